"""The paper's dataset: 12 training, 12 test and 1 validation log, generated on demand and cached.

The shipped scenario ``paper/training`` (a 12-run sweep: circle and racetrack at six
angles) makes the training logs; the same sweep with another seed and 60 s
per case makes the test logs (unseen noise and trajectories of the same
paths, our analog of the paper's 80/20 test split); and
``paper/validation`` (the rotating circle) the validation log.
They are run once and their ``log.csv`` files kept under ``<cache>/paper_dataset``. The
cache is reused while the scenario files, the plant FMU and the length
(full or ``quick``) are unchanged; otherwise it is regenerated.
The cache folder is ``$COSIM_CACHE`` or ``./cache``.

A ``profile`` (``ideal``, the default, or one a plugin registers, e.g.
``lab``; see :func:`cosim.scenario.schema.apply_profile`) runs the scenarios with
that profile's values, as the paper's logs came from its own rig: its
dataset lives in ``paper_dataset[_quick]_<profile>`` and its fingerprint
includes the profile's name and values, so the models trained on it
(:mod:`cosim_plugins.identify.cache`) are cached apart and retrained when a value
changes.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

from cosim import api
from cosim_plugins.resources import SCENARIOS_DIR

PAPER_SCENARIOS = SCENARIOS_DIR / "paper"
#: Simulated seconds per case with ``quick`` (the full cases last 290 s, 14,500 rows).
QUICK_DURATION_S = 40.0
#: Simulated seconds per test case (full / quick) and the test set's seed.
TEST_DURATION_S = (60.0, 20.0)
TEST_SEED = 300


@dataclass
class PaperDataset:
    """The dataset's log files by split, and the folder holding them."""
    training: list[Path]
    test: list[Path]
    validation: list[Path]
    folder: Path


def _fingerprint(quick: bool, profile: str = "ideal") -> str:
    """Hash of what the data depend on: the scenarios, the plant FMU, the source of the
    components and paths the scenarios use (with the plugin modules those import), the
    length and the profile (its name and values; ``ideal`` adds nothing, so its cache
    keys are those of the data made before profiles existed)."""
    from cosim_plugins.plant.build import ensure_fmu

    h = hashlib.sha256()
    sources: set[str] = set()
    for name in ("training.yaml", "validation.yaml"):
        h.update((PAPER_SCENARIOS / name).read_bytes())
        scenario = api.load_scenario(PAPER_SCENARIOS / name, profile_overrides(profile))
        used = [*api.component_classes(scenario).values(), type(api.make_path(scenario.path.plugin))]
        sources.update(f for cls in used for f in api.class_sources(cls, ("cosim_plugins.",)))
    for source in sorted(sources):
        h.update(Path(source).read_bytes())
    h.update(Path(ensure_fmu()).read_bytes())
    h.update(b"quick" if quick else b"full")
    if profile != "ideal":
        values = api.profile_values(profile, "the paper dataset")
        h.update(json.dumps({"profile": profile, "values": values}, sort_keys=True, default=str).encode())
    return h.hexdigest()[:16]


def profile_overrides(profile: str) -> list[str]:
    """The scenario overrides that run the dataset's scenarios on ``profile``."""
    return [] if profile == "ideal" else [f"profile={profile}"]


def dataset_folder(quick: bool, profile: str = "ideal") -> Path:
    """The cache folder of the (quick) dataset on ``profile``."""
    name = "paper_dataset_quick" if quick else "paper_dataset"
    return api.cache_dir() / (name if profile == "ideal" else f"{name}_{profile}")


def ensure_dataset(quick: bool = False, folder: Path | None = None, force: bool = False,
                   progress: bool = True, jobs: int = 1, workers=None, profile: str = "ideal") -> PaperDataset:
    """The cached dataset on ``profile``; splits that are missing or stale are generated first (progress
    on stderr), ``jobs`` runs at a time on open ``workers`` or its own (see :mod:`cosim.scale.sweep`)."""
    folder = Path(folder) if folder else dataset_folder(quick, profile)
    with api.CacheLock(folder.parent / f".{folder.name}.lock"):
        return _ensure(folder, quick, force, progress, jobs, workers, profile)


def _ensure(folder: Path, quick: bool, force: bool, progress: bool, jobs: int, workers,
            profile: str = "ideal") -> PaperDataset:
    manifest = folder / "manifest.json"
    stamp = _fingerprint(quick, profile)
    data = json.loads(manifest.read_text()) if manifest.is_file() and not force else {}
    if data.get("fingerprint") != stamp:
        if folder.exists():
            shutil.rmtree(folder)
        data = {"fingerprint": stamp}
    duration = [f"duration_s={QUICK_DURATION_S}"] if quick else []
    on = profile_overrides(profile)
    plans = {
        "training": (PAPER_SCENARIOS / "training.yaml", duration + on),
        "test": (PAPER_SCENARIOS / "training.yaml",
                 [f"duration_s={TEST_DURATION_S[quick]}", f"seed={TEST_SEED}"] + on),
        "validation": (PAPER_SCENARIOS / "validation.yaml", duration + on),
    }
    missing = [s for s in plans if not (data.get(s) and all((folder / f).is_file() for f in data[s]))]
    if not missing:
        return PaperDataset(*[[folder / f for f in data[s]] for s in plans], folder)
    with contextlib.ExitStack() as stack:
        if workers is None:  # one set of workers for every split
            workers = stack.enter_context(api.workers(jobs))
        for split in missing:
            _generate(folder, split, *plans[split], progress, jobs, workers, data, manifest)
    return PaperDataset(*[[folder / f for f in data[s]] for s in plans], folder)


def _generate(folder: Path, split: str, scenario: Path, overrides: list[str], progress: bool, jobs: int,
              workers, data: dict, manifest: Path) -> None:
    """Run one split's scenario into the cache and note its logs in the manifest."""
    print(f"generating the paper dataset's {split} logs in {folder}", file=sys.stderr)
    out = folder / "runs" / split
    api.run(api.RunRequest(scenario, out, overrides, False, progress), api.SweepOptions(jobs=jobs, workers=workers))
    logs = sorted(out.glob("runs/*/log.csv")) or [out / "log.csv"]
    data[split] = [str(f.relative_to(folder)) for f in logs]
    manifest.write_text(json.dumps(data, indent=2))
