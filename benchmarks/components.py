"""Per-step cost of each component of a scenario, replayed on its own recorded inputs.

Runs the scenario once (one process) to record every port's value at every
tick (``trace.npz``), or reads ``--trace``; then, for each component, sets it
up as a run does (same params, path and seeded RNG) and calls its ``step()``
tick by tick with the inputs the run gave it (a delayed edge reads the
source's previous tick, or its initial outputs at tick 0), timing each call.
No bus, no scheduler: only the component's own cost. Each replayed output is
checked against the recording (diagnostic ports such as ``solve_time``
excepted), so a figure is never that of a component computing something else.

Prints JSON: {"scenario": ..., "ticks": ..., "repeats": ...,
"step_us": {component: {"median": ..., "p90": ...}}, "mismatches": {...}}.
Medians over every step of every repeat, in microseconds.

    .venv/bin/python benchmarks/components.py [--scenario scenarios/racetrack.yaml]
        [--components camera,estimator,controller,coil_driver] [--repeats 5] [--trace trace.npz]
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from cosim.api import RunRequest, run
from cosim.runtime.stepper import setup_component
from cosim.runtime.wiring import build_wiring
from cosim.scenario.schema import load_scenario
from cosim_plugins.resources import SCENARIOS_DIR

ROOT = Path(__file__).resolve().parents[1]
#: outputs that report timings rather than results: never compared
DIAGNOSTIC_PORTS = ("solve_time",)


def record(scenario_file: Path, overrides: list[str]) -> dict[str, np.ndarray]:
    """Every port's value at every tick of one run of the scenario."""
    with tempfile.TemporaryDirectory() as out:
        run(RunRequest(scenario_file, Path(out), list(overrides), progress=False))
        with np.load(Path(out) / "trace.npz") as z:
            return {k: z[k] for k in z.files}


def input_sequence(scenario, wiring, name: str, trace: dict[str, np.ndarray]) -> list[dict[str, np.ndarray]]:
    """The inputs component ``name`` received at each tick, as (fresh, contiguous) float arrays."""
    ticks = len(trace["t_s"])
    initial: dict[str, dict] = {}
    columns = []
    for dst, spec in scenario.components[name].inputs.items():
        src, port, delay = spec.component, spec.port, spec.delay
        if delay and src not in initial:
            initial[src] = setup_component(scenario, wiring, src).initial_outputs()
        first = np.asarray(initial[src][port], dtype=float) if delay else None
        values = [first if k < delay else np.array(trace[f"{src}.{port}"][k - delay]) for k in range(ticks)]
        columns.append((dst, values))
    return [{dst: values[k] for dst, values in columns} for k in range(ticks)]


def replay(scenario, wiring, name: str, inputs: list[dict], trace: dict[str, np.ndarray]) -> tuple[list[int], int]:
    """Step a freshly set-up ``name`` over ``inputs``: (per-step ns, outputs differing from the recording)."""
    component = setup_component(scenario, wiring, name)
    times = trace["t_s"].tolist()
    clock = time.perf_counter_ns
    elapsed, outputs = [], []
    try:
        for t, given in zip(times, inputs):
            t0 = clock()
            out = component.step(t, given)
            elapsed.append(clock() - t0)
            outputs.append(out)
    finally:
        component.close()
    mismatches = 0
    for k, out in enumerate(outputs):
        for port, value in out.items():
            if port in DIAGNOSTIC_PORTS:
                continue
            if not np.array_equal(np.asarray(value, dtype=float), trace[f"{name}.{port}"][k], equal_nan=True):
                mismatches += 1
    return elapsed, mismatches


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", type=Path, default=SCENARIOS_DIR / "racetrack.yaml")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--components", default="", help="comma-separated names (default: all but the plant)")
    parser.add_argument("--repeats", type=int, default=5, help="replays per component (each a fresh set-up)")
    parser.add_argument("--trace", type=Path, help="a run's trace.npz to replay instead of recording one")
    args = parser.parse_args()
    if args.trace:
        with np.load(args.trace) as z:
            trace = {k: z[k] for k in z.files}
    else:
        trace = record(args.scenario, args.overrides)
    scenario = load_scenario(args.scenario, args.overrides)
    wiring = build_wiring(scenario)
    names = args.components.split(",") if args.components else [n for n in scenario.components if n != "plant"]
    step_us, mismatches = {}, {}
    for name in names:
        if scenario.components[name].period != 1:
            raise SystemExit(f"{name}: period {scenario.components[name].period}; only period-1 components replay")
        inputs = input_sequence(scenario, wiring, name, trace)
        samples: list[int] = []
        for _ in range(args.repeats):
            elapsed, mismatches[name] = replay(scenario, wiring, name, inputs, trace)
            samples += elapsed
        samples.sort()
        step_us[name] = {"median": round(statistics.median(samples) / 1e3, 2),
                         "p90": round(samples[int(0.9 * (len(samples) - 1))] / 1e3, 2)}
    print(json.dumps({"scenario": str(args.scenario), "overrides": args.overrides, "ticks": len(trace["t_s"]),
                      "repeats": args.repeats, "step_us": step_us, "mismatches": mismatches}, indent=1))


if __name__ == "__main__":
    main()
