"""Helpers of the scale-out tests: the core tests' toy scenarios, sweeps over them, what they wrote."""

from __future__ import annotations

import json
from pathlib import Path

CORE_DATA = Path(__file__).parents[1] / "core" / "data"
TOY = CORE_DATA / "toy.yaml"
FAULTY = CORE_DATA / "faulty.yaml"
#: measured computation times: they differ between any two runs, wherever they run
TIMINGS = ("solve_ms",)


def sweep_arg(axes: dict) -> str:
    return f"sweep={json.dumps(axes)}"


def rows_of(out: Path) -> list[dict]:
    return json.loads((out / "summary.json").read_text())["sweep"]


def without_timings(rows: list[dict]) -> list[dict]:
    return [{k: v for k, v in row.items() if k not in TIMINGS} for row in rows]


def logs_of(out: Path) -> dict[str, bytes]:
    return {d.name: (d / "log.csv").read_bytes() for d in sorted((out / "runs").iterdir())}
