"""The paper's dataset: 12 training logs + 1 validation log, generated on demand and cached.

``scenarios/paper/training.yaml`` (a 12-run sweep: circle and racetrack at six
angles) and ``scenarios/paper/validation.yaml`` (the rotating circle) are run
once and their ``log.csv`` files kept under ``<cache>/paper_dataset``. The
cache is reused while the scenario files, the plant FMU and the length
(full or ``quick``) are unchanged; otherwise it is regenerated.
The cache folder is ``$COSIM_CACHE`` or ``./cache``.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PAPER_SCENARIOS = REPO / "scenarios" / "paper"
#: Simulated seconds per case with ``quick`` (the full cases last 290 s, 14,500 rows).
QUICK_DURATION_S = 40.0


def cache_dir() -> Path:
    return Path(os.environ.get("COSIM_CACHE", "cache")).resolve()


@dataclass
class PaperDataset:
    training: list[Path]
    validation: list[Path]
    folder: Path

    @property
    def all(self) -> list[Path]:
        return [*self.training, *self.validation]


def _fingerprint(quick: bool) -> str:
    from cosim_plugins.plant.build import ensure_fmu  # the plant the data comes from

    h = hashlib.sha256()
    for name in ("training.yaml", "validation.yaml"):
        h.update((PAPER_SCENARIOS / name).read_bytes())
    h.update(Path(ensure_fmu()).read_bytes())
    h.update(b"quick" if quick else b"full")
    return h.hexdigest()[:16]


def ensure_dataset(quick: bool = False, folder: Path | None = None, force: bool = False,
                   progress: bool = True) -> PaperDataset:
    """The cached dataset, generated first if missing or stale (with progress on stderr)."""
    folder = Path(folder) if folder else cache_dir() / ("paper_dataset_quick" if quick else "paper_dataset")
    manifest = folder / "manifest.json"
    stamp = _fingerprint(quick)
    if not force and manifest.is_file():
        data = json.loads(manifest.read_text())
        files = [folder / f for f in data.get("training", []) + data.get("validation", [])]
        if data.get("fingerprint") == stamp and all(f.is_file() for f in files):
            return PaperDataset([folder / f for f in data["training"]], [folder / f for f in data["validation"]],
                                folder)
    from cosim.runner import RunRequest, run

    print(f"generating the paper dataset in {folder} (12 training + 1 validation runs)", file=sys.stderr)
    if folder.exists():
        shutil.rmtree(folder)
    extra = [f"duration_s={QUICK_DURATION_S}"] if quick else []
    runs = folder / "runs"
    run(RunRequest(PAPER_SCENARIOS / "training.yaml", runs / "training", extra, False, progress))
    run(RunRequest(PAPER_SCENARIOS / "validation.yaml", runs / "validation", extra, False, progress))
    training = sorted(p.relative_to(folder) for p in (runs / "training" / "runs").glob("*/log.csv"))
    validation = [(runs / "validation" / "log.csv").relative_to(folder)]
    manifest.write_text(json.dumps({"fingerprint": stamp, "training": [str(p) for p in training],
                                    "validation": [str(p) for p in validation]}, indent=2))
    return PaperDataset([folder / p for p in training], [folder / p for p in validation], folder)
