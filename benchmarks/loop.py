"""Real-time factor of the racetrack PI loop over zenoh: one process, and one process per component.

Prints JSON: {"one_process": {"realtime_factor": median, "runs": [...],
"cpu_steal_pct": ...}, "processes": {...}, "processes_os_placement": {...},
"sim_s": ..., "budgets": {...}}. ``processes`` places the nodes as ``cosim run
--processes`` does by default (all on one CPU, see cosim.runtime.placement);
``processes_os_placement`` leaves that to the operating system
(``--node-cpus none``), for comparison. The
factor is simulated time over the wall time of the stepping loop (set-up and
file writing excluded). ``cpu_steal_pct`` is the share of CPU time the
hypervisor took from this machine while the runs went (Linux /proc/stat; None
elsewhere): on a shared VM a high share explains a low factor.

    .venv/bin/python benchmarks/loop.py [--sim-s 60] [--repeats 3]

``--against DIR`` compares this checkout with another (a ``git worktree`` of the
commit before, say): each run in a fresh process, the two alternated run by run
(A B B A A B ...), so a machine whose load changes meanwhile weighs on both
alike. It prints ``{"layouts": {"processes": {"this": {...}, "against": {...},
"ratio": median this / median against}, ...}, "sim_s": ..., "loadavg": ...}``.

    .venv/bin/python benchmarks/loop.py --against ../before --repeats 7 --sim-s 30 --layouts processes one_process
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from cosim.api import RunRequest, run
from cosim_plugins.resources import SCENARIOS_DIR

SCENARIO = SCENARIOS_DIR / "racetrack.yaml"


def cpu_times() -> list[int] | None:
    """The machine's aggregate CPU times (jiffies: user nice system idle iowait irq softirq steal)."""
    try:
        return [int(x) for x in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:9]]
    except (OSError, ValueError):
        return None


def measure(processes: bool, sim_s: float, repeats: int, node_cpus: str = "auto") -> dict:
    factors = []
    before = cpu_times()
    for _ in range(repeats):
        with tempfile.TemporaryDirectory() as out:
            summary = run(RunRequest(SCENARIO, Path(out), [f"duration_s={sim_s}"], processes, False, node_cpus))
        factors.append(round(summary["realtime_factor"], 2))
    after = cpu_times()
    steal = None
    if before and after and sum(after) > sum(before):
        steal = round(100 * (after[7] - before[7]) / (sum(after) - sum(before)), 1)
    return {"realtime_factor": statistics.median(factors), "runs": factors, "cpu_steal_pct": steal}


def one_run(tree: Path, processes: bool, sim_s: float) -> float:
    """The real-time factor of one run of the code in ``tree`` (its own ``cosim``), in a fresh process."""
    code = ("import sys, tempfile; from pathlib import Path\n"
            "try:\n    from cosim.api import RunRequest, run\n"
            "except ImportError:  # a checkout from before cosim.api\n"
            "    from cosim.runtime.runner import RunRequest, run\n"
            "from cosim_plugins.resources import SCENARIOS_DIR\n"
            "with tempfile.TemporaryDirectory() as out:\n"
            f"    s = run(RunRequest(SCENARIOS_DIR / 'racetrack.yaml', Path(out), ['duration_s={sim_s}'], {processes}, "
            "False))\n"
            "print(s['realtime_factor'])")
    env = {**os.environ, "PYTHONPATH": str(tree)}
    done = subprocess.run([sys.executable, "-c", code], cwd=tree, env=env, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"a run of {tree} failed:\n{done.stderr[-2000:]}")
    return round(float(done.stdout.strip().splitlines()[-1]), 2)


def compare(against: Path, layouts: list[str], sim_s: float, repeats: int) -> dict:
    """This checkout against ``against``, run by run alternately (A B B A ...), per layout."""
    this = Path(__file__).resolve().parents[1]
    result = {}
    for layout in layouts:
        runs: dict[str, list[float]] = {"this": [], "against": []}
        for i in range(repeats):
            for who in (("this", "against") if i % 2 == 0 else ("against", "this")):
                runs[who].append(one_run(this if who == "this" else against, layout == "processes", sim_s))
        medians = {who: statistics.median(v) for who, v in runs.items()}
        result[layout] = {who: {"realtime_factor": medians[who], "runs": runs[who]} for who in runs}
        result[layout]["ratio"] = round(medians["this"] / medians["against"], 3)
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sim-s", type=float, default=60.0, help="simulated seconds per run")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--against", type=Path, default=None, metavar="DIR",
                        help="another checkout to compare with, run by run alternately")
    parser.add_argument("--layouts", nargs="+", choices=["processes", "one_process"],
                        default=["processes", "one_process"], help="with --against: which layouts")
    args = parser.parse_args()
    if args.against is not None:
        if not (args.against / "cosim").is_dir():
            parser.error(f"--against {args.against}: no cosim/ there (expected a checkout of this project)")
        print(json.dumps({"sim_s": args.sim_s, "layouts": compare(args.against.resolve(), args.layouts, args.sim_s,
                                                                  args.repeats),
                          "loadavg": os.getloadavg()}, indent=2))
        return
    result = {
        "sim_s": args.sim_s,
        "one_process": measure(False, args.sim_s, args.repeats),
        "processes": measure(True, args.sim_s, args.repeats),
        "processes_os_placement": measure(True, args.sim_s, args.repeats, node_cpus="none"),
        "budgets": {"one_process": 100, "processes": 25},
    }
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
