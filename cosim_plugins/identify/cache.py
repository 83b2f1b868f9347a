"""Models trained on demand from the paper dataset, cached beside it.

A scenario names a model either by file (``model: path/to/sindy-linear.npz``)
or by kind (``model: sindy-linear``); a kind is trained here on the paper's
12 training logs (generated first if missing, see :mod:`cosim_plugins.paper.dataset`) and
kept under ``<cache>/models[_quick]/<dataset fingerprint>/``, so a fresh
clone runs such scenarios with no manual step and later runs reuse the file.
``COSIM_DATASET=quick`` trains on the short (40 s per case) dataset instead.
A ``profile`` other than ``ideal`` trains on that profile's dataset (its own
fingerprint, so its own folder): a scenario on the lab profile gets models
identified on lab logs, as the paper's were on its rig's.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

from cosim import api
from cosim.contract.errors import UserError
from cosim.contract.plugins import lookup, registry
from cosim_plugins.paper.dataset import ensure_dataset


def _progress(message: str) -> None:
    print(f"  {message}", file=sys.stderr)


def quick_data() -> bool:
    """Whether on-demand models use the short dataset (``COSIM_DATASET=quick``; tests set it)."""
    return os.environ.get("COSIM_DATASET", "full") == "quick"


def ensure_model(kind: str, quick: bool | None = None, seed: int = 0, profile: str = "ideal") -> Path:
    """Path of a ``kind`` model trained on the paper dataset on ``profile`` (trained now if not cached)."""
    quick = quick_data() if quick is None else quick
    from cosim_plugins.identify.dataset import Dataset
    from cosim_plugins.identify.fit import fit_models, resolve_names

    resolve_names(kind)  # unknown kinds fail here, listing the known ones
    path = model_path(kind, quick, seed, profile)
    with api.CacheLock(path.parent.parent / f".{path.parent.name}-{path.stem}.lock"):
        if path.is_file():
            return path
        print(f"training the {kind} model on the paper dataset ({profile} profile; cached in {path.parent})",
              file=sys.stderr)
        dataset = Dataset.from_paths(ensure_dataset(quick=quick, profile=profile).training)
        model = fit_models(dataset, [kind], seed=seed, progress=_progress)[kind]
        path.parent.mkdir(parents=True, exist_ok=True)
        partial = path.with_name(path.stem + ".partial")
        model.save(partial)
        partial.replace(path)
    return path


def model_path(kind: str, quick: bool, seed: int = 0, profile: str = "ideal") -> Path:
    """Where the cached ``kind`` model lives: keyed on the fingerprint of the dataset on
    ``profile`` and the model's source code (generating the dataset if needed)."""
    dataset = ensure_dataset(quick=quick, profile=profile)
    stamp = json.loads((dataset.folder / "manifest.json").read_text())["fingerprint"]
    code = api.files_digest(api.class_sources(lookup("model", kind), ("cosim_plugins.",)))
    folder = api.cache_dir() / ("models_quick" if quick else "models") / f"{stamp}-seed{seed}"
    return folder / f"{kind}-{code[:12]}.npz"


def resolve_model(spec: str, base_dir: Path | None = None, quick: bool | None = None, profile: str = "ideal"):
    """A loaded model from a file path or a kind name (trained on demand on ``profile``'s dataset);
    clear errors for both."""
    from cosim_plugins.identify.model import load_model

    candidate = Path(spec)
    if base_dir is not None and not candidate.is_absolute():
        candidate = base_dir / candidate
    if candidate.suffix == ".npz" or candidate.is_file():
        return load_model(candidate)
    if spec not in registry("model"):
        raise UserError(f"model {spec!r} is neither a model file nor a known kind "
                        f"({', '.join(sorted(registry('model')))})")
    return load_model(ensure_model(spec, quick=quick, profile=profile))
