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


def stop_a_parallel_sweep(folder: Path, *executor: str, scratch: Path | None = None) -> tuple[int, list[dict]]:
    """Start a sweep of two paced 30 s runs (``executor``: more ``cosim run`` arguments), send SIGTERM
    to ``cosim run`` alone once both runs have recorded a second (under ``scratch``: where the
    workers write the run folders they ship back), return its exit status and rows."""
    import signal
    import subprocess
    import sys
    import time

    sweep = sweep_arg({"components.camera.params.interval_s": [0.02, 0.04]})
    started = time.time()
    proc = subprocess.Popen([sys.executable, "-m", "cosim.cli", "run", str(TOY), "--out", str(folder), "--quiet",
                             "--set", "duration_s=30", "--set", sweep, "--realtime", "1", *executor])
    deadline = time.monotonic() + 60

    def logs() -> list[Path]:
        if scratch is None:
            return [folder / "runs" / name / "log.csv" for name in ("000_interval_s=0.02", "001_interval_s=0.04")]
        return [f for f in scratch.glob("cosim-run-*/00[01]_interval_s=0.0[24]/log.csv") if f.stat().st_mtime > started]

    while not (len(logs()) == 2 and all(f.is_file() and f.read_text().count("\n") > 50 for f in logs())):
        assert time.monotonic() < deadline and proc.poll() is None, "the runs did not start"
        time.sleep(0.2)
    proc.send_signal(signal.SIGTERM)
    return proc.wait(timeout=60), rows_of(folder)
