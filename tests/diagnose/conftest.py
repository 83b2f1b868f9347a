"""Plant logs recorded once per session, and the diagnoses run on them.

Each variant runs ``scenarios/diagnose/plain.yaml`` (four paths, spin rate
stepped 4-16 Hz, every switchable plant effect off) for 40 s per path with
one effect switched on in the plant FMU (or none). Every variant is
recorded and diagnosed once per session, two at a time: under xdist the
first worker to ask makes them, under a file lock, and the others read its
results (each worker building them took ~400 s of CPU again).
"""

from __future__ import annotations

import fcntl
import json
import multiprocessing
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import pytest
from plant_variants import VARIANTS, record_and_diagnose

from cosim.contract import plugins
from cosim_plugins.identify.fit import json_default

DATA = Path(__file__).parent / "data"


@pytest.fixture(scope="session")
def plant_variants(tmp_path_factory, worker_id):
    """{variant: (log paths, default diagnosis)} for every variant, made two at a time on first use.

    Spawned workers (one core each): the runner opens zenoh sessions, which a forked child must not inherit.
    Under xdist the workers share one set, made by the first of them in the session's shared temporary folder.
    """
    if worker_id == "master":
        return _make_variants(tmp_path_factory.mktemp("diagnose_plant"))
    shared = tmp_path_factory.getbasetemp().parent / "diagnose_plant"
    with open(shared.with_suffix(".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        made = shared / "variants.json"
        if not made.exists():
            variants = _make_variants(shared)
            made.write_text(json.dumps({v: [[str(p) for p in logs], r] for v, (logs, r) in variants.items()},
                                       default=json_default))
        return {v: ([Path(p) for p in logs], r) for v, (logs, r) in json.loads(made.read_text()).items()}


def _make_variants(root: Path) -> dict:
    root.mkdir(parents=True, exist_ok=True)
    with ProcessPoolExecutor(max_workers=2, mp_context=multiprocessing.get_context("spawn")) as pool:
        done = pool.map(record_and_diagnose, [(v, str(root)) for v in VARIANTS])
        return {variant: (logs, result) for variant, logs, result in done}


@pytest.fixture(scope="session")
def plant_logs(plant_variants):
    """``get(variant) -> [log paths]``: a variant's four logs."""
    return lambda variant: plant_variants[variant][0]


@pytest.fixture(scope="session")
def diagnosed(plant_variants):
    """``get(variant) -> result dict``: the default diagnosis (every library effect) of a variant."""
    return lambda variant: plant_variants[variant][1]


@pytest.fixture
def fresh_plugins():
    """Forget effect files loaded by a test (the plugin manager is process-wide)."""
    plugins.reset()
    yield
    plugins.reset()
