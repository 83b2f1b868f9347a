"""Plant logs recorded once per session, and the diagnoses run on them.

Each variant runs ``scenarios/diagnose/plain.yaml`` (four paths, spin rate
stepped 4-16 Hz, every switchable plant effect off) for 40 s per path with
one effect switched on in the plant FMU (or none). Diagnoses are cached per
variant so each runs once.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from cosim import plugins

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = ROOT / "scenarios" / "diagnose" / "plain.yaml"
DATA = Path(__file__).parent / "data"
PLANT = "components.plant.params"
DURATION_S = 40

VARIANTS = {
    "plain": [],
    "background_flow": [f"{PLANT}.background_flow_on=true", f"{PLANT}.flow_x=0.003"],
    "wall_drag": [f"{PLANT}.wall_drag_on=true", f"{PLANT}.wall_drag_length=0.008", f"{PLANT}.wall_drag_gain=3"],
    "gradient_force": [f"{PLANT}.gradient_force_on=true", f"{PLANT}.gradient_force_scale=3"],
    "quadratic_drag": [f"{PLANT}.quadratic_drag_on=true"],
}


@pytest.fixture(scope="session")
def plant_logs(tmp_path_factory):
    """``get(variant) -> [log paths]``: records a variant's four logs on first use."""
    from cosim.runner import RunRequest, run

    root = tmp_path_factory.mktemp("diagnose_plant")
    cache: dict[str, list[Path]] = {}

    def get(variant: str) -> list[Path]:
        if variant not in cache:
            out = root / variant
            run(RunRequest(SCENARIO, out, [f"duration_s={DURATION_S}", *VARIANTS[variant]], progress=False))
            cache[variant] = sorted(out.glob("runs/*/log.csv"))
        return cache[variant]

    return get


@pytest.fixture(scope="session")
def diagnosed(plant_logs):
    """``get(variant) -> result dict``: the default diagnosis (every library effect) of a variant, cached."""
    from cosim.identify.diagnose import run

    cache: dict[str, dict] = {}

    def get(variant: str) -> dict:
        if variant not in cache:
            cache[variant] = run(plant_logs(variant)).result
        return cache[variant]

    return get


@pytest.fixture
def fresh_plugins():
    """Forget effect files loaded by a test (the plugin manager is process-wide)."""
    plugins.reset()
    yield
    plugins.reset()
