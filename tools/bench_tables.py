"""Render the docs' measured tables from the benchmarks' kept JSON, and check that none was edited by hand.

Each benchmark's printed JSON is kept in ``docs/benchmarks/data/NAME.json``, wrapped in a header::

    {"command": "benchmarks/plant.py", "date": "2026-11-25", "commit": "010912a",
     "machine_load": "load average 3.1 / 2.5 / 2.2 (2 CPUs)", "source": "printed by the benchmark",
     "output": {... exactly what the benchmark printed ...}}

``source`` is ``printed by the benchmark`` or, for figures kept only on a page, ``transcribed from
the page of DATE`` (then ``output`` holds only the figures that page stated, in the benchmark's own
keys where it has them). A page marks a table with ``<!-- table: NAME -->`` ... ``<!-- /table -->``;
:data:`TABLES` says which data files table ``NAME`` renders and how. Commands::

    python tools/bench_tables.py                  # rewrite every marked table from its data
    python tools/bench_tables.py --check          # exit 1 naming each table that differs
    python tools/bench_tables.py record NAME [--load TEXT] -- benchmarks/plant.py --repeats 5
                                                  # run a benchmark, keep its JSON as data/NAME.json

``tests/docs/test_bench_tables.py`` fails when a page's table differs from what its data render.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "docs" / "benchmarks" / "data"
PAGES = ("docs",)
MARK = re.compile(r"<!-- table: (?P<name>[\w-]+) -->\n(?P<body>.*?)<!-- /table -->", re.S)
PRINTED = "printed by the benchmark"
HEADER = ("command", "date", "commit", "machine_load", "source", "output")


def load(name: str) -> dict:
    """The kept data ``docs/benchmarks/data/NAME.json``: its header and ``output``; a clear error if
    the file is missing or lacks a header field."""
    path = DATA / f"{name}.json"
    if not path.is_file():
        raise SystemExit(f"no data {path.relative_to(ROOT)}: record it (tools/bench_tables.py record {name} -- ...)")
    data = json.loads(path.read_text())
    missing = [k for k in HEADER if k not in data]
    if missing:
        raise SystemExit(f"{path.relative_to(ROOT)}: header lacks {', '.join(missing)}")
    return data


def table(header: list[str], rows: list[list[str]]) -> str:
    """A Markdown table (``header``, then ``rows``, each a list of cells), ending in a newline."""
    def line(cells: list[str]) -> str:
        return "|" + "|".join(f" {cell.replace('|', chr(92) + '|')} " if cell else " " for cell in cells) + "|"

    return "\n".join([line(header), line(["---"] * len(header)), *map(line, rows)]) + "\n"


def of(part: float | None, cases: int, bold_below: float | None = None) -> str:
    """A fraction of ``cases`` as "k of n" (``-`` when nothing was counted), bold when under ``bold_below``."""
    if part is None or not cases:
        return "-"
    text = f"{round(part * cases)} of {cases}"
    return f"**{text}**" if bold_below is not None and part < bold_below else text


def when(data: dict) -> str:
    """When and on what a figure was measured, from a data file's header; transcribed ones say so."""
    note = f"{data['date']}, {data['machine_load']}"
    return note if data["source"] == PRINTED else f"{note}; transcribed"


# ---------------------------------------------------------------- the benchmarks page, one row a script


def _plant(d: dict) -> str:
    return f"{d['output']['wall_s']:.2f} s for {d['output']['sim_s']:g} s"


def _loop_against(d: dict) -> str:
    layouts, parts, n = d["output"]["layouts"], [], d.get("alternations")
    for key, label in (("one_process", "one process"), ("processes", "`--processes`")):
        if key in layouts:
            lay = layouts[key]
            n = n or len(lay["this"].get("runs", ()))
            parts.append(f"{label} {lay['against']['realtime_factor']:g} -> {lay['this']['realtime_factor']:g}x "
                         f"({lay['ratio']:g}x)")
    return f"`--against` {d['against']}, {n} runs each, alternated: " + ", ".join(parts)


def _loop(d: dict) -> str:
    o = d["output"]
    return (f"one process {o['one_process']['realtime_factor']:g}x, "
            f"`--processes` {o['processes']['realtime_factor']:g}x "
            f"(`--node-cpus none` {o['processes_os_placement']['realtime_factor']:g}x), medians of "
            f"{len(o['processes']['runs'])} runs of {o['sim_s']:g} s")


def _components(d: dict) -> str:
    step = d["output"]["step_us"]
    return ", ".join(f"{name} {v['median']:g}" for name, v in step.items()) + \
        f" us (medians of {d['output']['repeats']} repeats)"


def _fit(d: dict) -> str:
    models = d["output"]["models"]
    names = ("physical", "sindy-nonlinear", "sindy-linear", "mlp")
    return " / ".join(f"{models[n]['train_time_s']:g}" for n in names) + " s"


def _kf(d: dict) -> str:
    rows = [r for r in d["output"] if "model" in r]
    pred = [r["predict_us"]["median"] for r in rows]
    gap = [r["gap_420ms_us"] / 1e3 for r in rows]
    each = ", ".join(f"{r['model']} {r['predict_us']['median']:g} us / {r['gap_420ms_us'] / 1e3:.2f} ms" for r in rows)
    return f"{min(pred):g}-{max(pred):g} us, {min(gap):.2f}-{max(gap):.2f} ms ({each})"


def _mpc(d: dict) -> str:
    o = d["output"]
    return f"{o['median_ms']:.2f} / {o['p99_ms']:.2f} ms over {o['solves']} solves ({o['backend']})"


def _camera(d: dict) -> str:
    o = d["output"]
    return (f"median {o['pair_ms']['median']:.2f} ms, p99 {o['pair_ms']['p99']:.2f} ms "
            f"({o['whole_frame_ms']:.2f} ms searching the whole frames)")


def _diagnose(d: dict) -> str:
    o = d["output"]
    text = f"{o['diagnose_wall_s']:g} s with `--jobs {o['jobs']}`, verdict {o['verdict']}"
    if "against" in d:  # alternated with another commit in one run
        text += f" ({d['ratio']:.3f}x commit {d['against']['commit']}'s {d['against']['median_s']:g} s, alternated)"
    return text


def _archive(d: dict) -> str:
    o = d["output"]
    runs = ", ".join(f"{r['logs']} logs {r['wall_s']:.1f} s / {r['peak_mb']:,.0f} MB" for r in o["runs"])
    return f"`--jobs {o['jobs']}`: {runs}; every size names " + \
        ", ".join(sorted({e for r in o["runs"] for e in r["effects"]}))


def _twin(d: dict) -> str:
    o = d["output"]
    lab, blind = o["lab"], o["blind"]["with_effect"]
    return (f"lab logs ({lab['logs']} x {lab['log_s']} s): {lab['calibration_s']:.0f} s, twin {lab['twin_mm']:.3f} mm "
            f"against uncalibrated {lab['uncalibrated_mm']:.3f} mm ({lab['twin_over_uncalibrated']:.2f}x) and host "
            f"{lab['host_mm']:.3f} mm; blind bench ({o['blind']['case']}): twin {blind['twin_mm']:.3f} mm, "
            f"{blind['twin_over_uncalibrated']:.2f}x uncalibrated, {blind['twin_over_host']:.2f}x the host model, "
            f"{o['blind']['without_effect']['twin_mm']:.3f} mm without the effect" + _twin_fresh(o))


def _twin_inject(d: dict) -> str:
    """The FMU's laws injected against native, fine camera: each case's mean over seeds, and the floor's."""
    o = d["output"]
    by: dict[str, list[float]] = {}
    for c in o["cases"]:
        if c["camera"] == "fine" and (c["name"].startswith(("fmu_background_flow/", "fmu_wall_drag/"))
                                      and "command_axis" not in c["name"] and "axis_at" not in c["name"]
                                      or c["name"].startswith("scatter")):
            by.setdefault(c["name"], []).append(c["log_mm"]["mean"])
    return ", ".join(f"{k} {sum(v) / len(v):.3f}" for k, v in by.items()) + " mm"


def _twin_fresh(o: dict) -> str:
    """The twin's blind figures on a fresh seed, when the run has one."""
    if "blind_fresh" not in o:
        return ""
    f = o["blind_fresh"]
    w = f["with_effect"]
    return (f"; fresh seed {f['seed']}: twin {w['twin_mm']:.3f} mm, {w['twin_over_uncalibrated']:.2f}x uncalibrated, "
            f"{w['twin_over_host']:.2f}x the host model, {f['without_effect']['twin_mm']:.3f} mm without the effect")


def _blind(d: dict) -> str:
    o = d["output"]
    lib, none, out = o["library"], o["no_effect"], o["outside"]
    seed = o["seed"] if "seed" in o else re.search(r"--seed (\d+)", d["command"]).group(1)  # later runs print none
    groups = (("library", lib), ("no-effect", none), ("outside", out))
    ran = [(name, g["cases"]) for name, g in groups if g.get("cases")]
    alone = len(ran) == 1  # one group of the draw only (--only GROUP)
    parts = []
    if lib["cases"]:
        parts += [f"top1 {lib['top1']:.3f} over all {lib['cases']} library cases, {lib['top1_detectable']:.3f} over "
                  f"the {lib['detectable']} detectable", f"ratio {lib['median_reduction_ratio']:.3f}"]
    if none["cases"]:
        parts.append(f"{none['false_alarms']} false alarms in {none['cases']}"
                     + (f", {none['discovered_alarms']} discovered alarms" if alone else ""))
    if out.get("cases", 1):  # the earliest runs did not count them
        parts.append(f"discovered_ok {out['discovered_ok']:.3f}"
                     + (f" ({out['time_varying']} varying in time not scored)" if alone else ""))
    head = f"seed {seed}, its {ran[0][1]} {ran[0][0]} cases only: " if alone else f"seed {seed}: "
    return head + "; ".join(parts) + f"; {o['seconds_per_case']:g} s per case"


def _sweep_jobs(d: dict) -> str:
    o = d["output"]
    same = "rows and logs identical" if o["rows_identical_but_timings"] and o["logs_identical"] else \
        "rows or logs differ"
    return f"{o['jobs_1_wall_s']['median']:g} / {o['jobs_2_wall_s']['median']:g} s, ratio {o['ratio']:.2f}, {same}"


def _hosts(d: dict) -> str:
    o = d["output"]
    same = "logs identical" if o["logs_identical"] else "logs differ"
    return f"{o['two_hosts_tls']['realtime_factor']:g}x / {o['loopback_tcp']['realtime_factor']:g}x real time, {same}"


def _mutation_runs(d: dict) -> list[dict]:
    """What each run of ``benchmarks/mutation.py`` kept in ``d`` printed, in order (the first tests every mutant,
    a later one the survivors again against the tests added since)."""
    return d["output"] if isinstance(d["output"], list) else [d["output"]]


def _mutation(d: dict) -> str:
    """A data file's modules, as the last run printed them; the time is every run's."""
    runs = _mutation_runs(d)
    times = " + ".join(f"{r['seconds']:.0f}" for r in runs if "seconds" in r)
    parts = []
    for path, m in runs[-1]["modules"].items():
        cut = f", {m['untested']} not reached" if m.get("untested") else ""
        parts.append(f"`{path.rsplit('/', 1)[-1]}` {m['score']:.3f} ({m['killed']} of "
                     f"{m['mutants'] - m['equivalent']}{cut})")
    return ", ".join(parts) + f"; {times or '-'} s"


#: the kept runs of benchmarks/mutation.py, one module (or two) each, in the benchmark's order of targets
MUTATION_DATA = ("mutation_interlocks", "mutation_wiring", "mutation_ekf", "mutation_noise", "mutation_stepper",
                 "mutation_portcache", "mutation_raw_log", "mutation_convert", "mutation_verdict", "mutation_inverse",
                 "mutation_kalman")


def _soak(d: dict) -> str:
    parts = []
    for r in d["output"]["runs"]:
        layout = "`--processes`" if r["layout"] == "processes" else "one process"
        nodes = f", largest node {r['nodes_peak_mb']:.1f} MB" if r.get("nodes_peak_mb") else ""
        parts.append(f"{layout} {r['hours']:g} h {r['peak_mb']:.1f} MB{nodes}")
    return ", ".join(parts)


def _realtime(d: dict) -> str:
    o = d["output"]
    layouts = [k for k in ("one", "processes") if k in o]
    missed = " / ".join(f"{o[k]['missed']}" for k in layouts)
    p99 = " / ".join(f"{o[k]['lateness_ms']['p99']:g}" for k in layouts)
    return f"{missed} missed of {o[layouts[0]]['ticks']} ticks; lateness p99 {p99} ms ({' / '.join(layouts)})"


@dataclass(frozen=True)
class Row:
    """One benchmark of the benchmarks page: its script, what it measures, its budget, and how each of its
    data files reads in the "last measured" cell."""

    script: str
    figure: str
    budget: str
    data: tuple[str, ...]
    cell: Callable[[dict], str]


ROWS = (
    Row("plant.py", "290 s of simulated time through fmpy at 20 ms steps", "`wall_s` <= 1.0", ("plant",), _plant),
    Row("loop.py", "real-time factor of the racetrack PI loop, one process / one process per component; "
        "`--against DIR`: this checkout against another, run by run alternately", ">= 100 / >= 25",
        ("loop", "loop_010912a", "loop_against_785565c", "loop_against_d12c65a", "loop_against_d12c65a_soak",
         "loop_against_34b820d", "loop_against_34b820d_r9", "loop_against_34b820d_quiet"),
        lambda d: (_loop_against if "layouts" in d["output"] else _loop)(d)),
    Row("components.py", "each racetrack component's `step()` alone, replayed on a run's recorded inputs "
        "(checked against the recorded outputs)", "-", ("components",), _components),
    Row("fit.py", "training time of each model on 174,000 samples (physical / SINDy nonlinear / SINDy linear / MLP)",
        "physical <= 15 s, SINDy nonlinear <= 5 s, SINDy linear <= 1 s, MLP <= 30 s", ("fit",), _fit),
    Row("kf.py", "Kalman filter predict step and a 420 ms gap, per model", "<= 50 us, <= 1 ms", ("kf",), _kf),
    Row("mpc.py", "MPC solve time over a racetrack run (median / p99)", "median <= 1.5 ms, p99 <= 5 ms",
        ("mpc",), _mpc),
    Row("camera.py", "detection and triangulation of one rendered frame pair at 800 x 600 (the frames made "
        "beforehand; each pair's minimum over 5 passes)", "`pair_ms` median <= 2 ms", ("camera",), _camera),
    Row("diagnose.py", "`cosim diagnose` on five 3,000-row logs",
        "<= 20 s (round 3); <= 60 s with the stepwise search (issue 33)",
        ("diagnose_jobs2_f3f23f8", "diagnose_jobs2_578846c", "diagnose_jobs2_aaa7302", "diagnose_jobs2_21cc104",
         "diagnose_jobs2_79af89a",
         "diagnose_jobs2_0940a22", "diagnose_jobs2_2bb3b17",
         "diagnose_jobs2_775c2b1", "diagnose_jobs2_222c636", "diagnose_jobs2_fa604e4", "diagnose_jobs2_010912a",
         "diagnose_jobs2", "diagnose_jobs1"), _diagnose),
    Row("archive.py", "`cosim diagnose` on 5, 20 and 120 logs of 60 s from the blind bench's simulator "
        "(a background flow hidden): wall time, peak memory, the named effects",
        "2 hours <= 3 min and <= 3 GB, the verdict of 20 logs", ("archive",), _archive),
    Row("twin.py", "`cosim twin calibrate`: five 60 s logs (a 3 mm/s flow hidden in the plant FMU) and a blind "
        "bench case; held-out open-loop error at 1.0 s of the calibrated twin, the uncalibrated FMU and diagnose's "
        "host model ([The twin](twin.md))", "calibration <= 3 min; twin <= 0.5x uncalibrated, <= 1.5x host",
        ("twin",), _twin),
    Row("twin_inject.py", "the plant FMU's wall drag and background flow injected through its force input "
        "against its own switches: racetrack tracking logs apart over 60 s, seeds 1-4, fine camera (the grid "
        "camera's and the loop's own scatter in [The twin](twin.md))", "<= 0.05 mm mean", ("twin_inject",),
        _twin_inject),
    Row("blind.py", "`cosim diagnose` on logs of an independent simulator, 60 random cases "
        "(see [How diagnose is validated](diagnose/validation.md))",
        "top1 >= 0.9, ratio >= 0.7, no false alarm, discovered_ok >= 0.75",
        ("blind_s3", "blind_s2", "blind_s43", "blind_s47", "blind_s49", "blind_s52", "blind_s54", "blind_s56",
         "blind_s58", "blind_s60", "blind_s62", "blind_s64", "blind_s66", "blind_s68", "blind_s72", "blind_s74",
         "blind_s76", "blind_s78", "blind_s81", "blind_s83", "blind_s86", "blind_outside_s93", "blind_none_s95",
         "blind_library_s96", "blind_library_s98", "blind_s107", "blind_s112", "blind_s113", "blind_s115",
         "blind_s116", "blind_s118", "blind_s120", "blind_s123", "blind_s125"),
        _blind),
    Row("sweep_jobs.py", "the Fig. 6 sweep's wall time with `--jobs 1` and `--jobs 2`, the rows and logs compared",
        "ratio <= 0.6", ("sweep_jobs",), _sweep_jobs),
    Row("hosts_loop.py", "the racetrack loop over mutual TLS between two loopback addresses (a run over two "
        "hosts, without the network) against loopback TCP", "-", ("hosts_loop",), _hosts),
    Row("mutation.py", "mutmut on the modules where a silent bug is dangerous, each with its own tests: score, "
        "killed of mutants less equivalent ([Testing](testing.md))", ">= 0.85 a module",
        MUTATION_DATA, _mutation),
    Row("soak.py", "the racetrack for hours of simulated time (1 h and 12 h in one process, 1 h and 12 h with "
        "`--processes`): peak memory", "12 h peak within 10 % of 1 h, both <= 400 MB",
        ("soak_processes_bounded", "soak_one_process", "soak_processes"), _soak),
    Row("realtime.py", "the racetrack paced at real time, one process / `--processes`: missed ticks, lateness",
        "missed <= 0.1 %, p99 <= 2 ms", ("realtime",), _realtime),
)


def benchmarks_table() -> str:
    """The benchmarks page's table: per script, what it measures, its budget and each kept measurement."""
    rows = []
    for row in ROWS:
        kept = [load(name) for name in row.data]
        cell = "; ".join(f"{row.cell(d)} ({when(d)}, [data](benchmarks/data/{name}.json))"
                         for name, d in zip(row.data, kept))
        rows.append([f"`benchmarks/{row.script}`", row.figure, row.budget, cell])
    return table(["script", "figure", "budget", "measured (newest last)"], rows)


# ---------------------------------------------------------------- the diagnose pages


def mutation_table() -> str:
    """docs/testing.md: each mutated module's figures as its last run printed them, and every run's time."""
    rows = []
    for name in MUTATION_DATA:
        d = load(name)
        runs = _mutation_runs(d)
        for path, m in runs[-1]["modules"].items():
            times = " + ".join(f"{r['modules'][path]['seconds']:.0f}" for r in runs
                               if "seconds" in r["modules"].get(path, {}))
            rows.append([f"`{path}`", str(m["mutants"]), f"{m['killed']} ({m['hung']})", str(m["equivalent"]),
                         f"{m['score']:.3f}", str(m.get("untested", 0)), str(len(m["survived"])), times or "-",
                         f"{when(d)}, {d['commit']}, [data](benchmarks/data/{name}.json)"])
    return table(["module", "mutants", "killed (hung)", "equivalent", "score", "not reached", "survived",
                  "seconds (each run)", "measured"], rows)


def archive_table() -> str:
    """docs/diagnose/drift.md: each archive size's wall time, peak memory and named effects."""
    runs = load("archive")["output"]["runs"]
    return table(["logs", "hours", "rows", "wall", "peak memory (the process and its largest worker)", "named"],
                 [[str(r["logs"]), str(r["hours"]), f"{r['rows']:,}", f"{r['wall_s']:.1f} s", f"{r['peak_mb']:,.0f} MB",
                   ", ".join(r["effects"]) or "(none)"] for r in runs])


DRIFT_SEEDS = (("blind_drift_s21", "seed 21 (first draw)"), ("blind_drift_s22", "seed 22 (stopped)"),
               ("blind_drift_s23", "seed 23 (fresh, size gates)"), ("blind_drift_s24", "seed 24 (fresh, trend fits)"),
               ("blind_drift_s42", "seed 42 (fresh, one case at a time)"))


def drift_table() -> str:
    """docs/diagnose/drift.md: the blind bench's drift and none groups, per seed (bold: a target missed)."""
    outs = [load(name)["output"] for name, _ in DRIFT_SEEDS]

    def flags(o: dict) -> str:
        checked, false = o["no_effect"].get("drift_checked", 0), o["no_effect"]["drift_false_flags"]
        text = f"{false} of {checked}"
        return f"**{text}**" if false else text

    def alarms(o: dict) -> str:
        n = o["no_effect"]["cases"]
        return f"{o['no_effect']['false_alarms']} of {n}" if n else "-"

    def seconds(o: dict) -> str:
        return f"{o['seconds_per_case']:.0f} s" if o.get("seconds_per_case") is not None else ""

    rows = [
        ["`drift.flagged`: a drift flagged", *[of(o["drift"]["flagged"], o["drift"]["cases"], 0.8) for o in outs],
         ">= 0.8"],
        ["`drift.right`: a quantity the drawn parameter moves, between or within as drawn",
         *[of(o["drift"]["right"], o["drift"]["cases"]) for o in outs], ""],
        ["`drift.named`: an effect named (nothing is hidden)", *[str(o["drift"]["named"]) for o in outs], ""],
        ["`no_effect.drift_false_flags` (steady controls and `none` cases)", *[flags(o) for o in outs], "0"],
        ["`no_effect.false_alarms` (`none` cases)", *[alarms(o) for o in outs], "0"],
        ["time per case (a busy machine)", *[seconds(o) for o in outs], ""],
    ]
    return table(["figure", *[label for _, label in DRIFT_SEEDS], "target"], rows)


SEVERAL_SEEDS = (("blind_groups_s8", "seed 8"), ("blind_lookalike_s10", "seed 10 (look-alikes, distance per log)"),
                 ("blind_groups_s45", "seed 45 (multi drawn visible, given discovered, sized experiment)"),
                 ("blind_groups_s46", "seed 46 (look-ahead, heading law, invisible pairs drawn anew)"),
                 ("blind_groups_s48", "seed 48 (look-alikes drawn visible, fit basins, stop-and-go and placed "
                                      "experiments)"),
                 ("blind_groups_s51", "seed 51 (a latency's start, a long log's separation)"),
                 ("blind_groups_s53", "seed 53 (starts off a degenerate baseline)"),
                 ("blind_groups_s55", "seed 55 (quadratic drag's starts, latency to 25 steps)"),
                 ("blind_groups_s57", "seed 57 (stand-ins dropped)"),
                 ("blind_groups_s59", "seed 59 (the full fit when no quick fit passes the screen)"),
                 ("blind_groups_s61", "seed 61 (trimmed t, candidates refitted after round 1)"),
                 ("blind_groups_s63", "seed 63 (full fit after a quick fit that changes nothing)"),
                 ("blind_groups_s65", "seed 65 (multi only: a flow's uniform part, the search on top of the form "
                                      "keeping it, a listed effect in place of its terms; 75f2e92)"),
                 ("blind_groups_s67", "seed 67 (a flow's uniform part only when it vanishes inside the tank)"),
                 ("blind_groups_s69", "seed 69 (a listed effect's start matched to the force of the terms it "
                                      "replaces)"),
                 ("blind_groups_s71", "seed 71 (step-out starts at the band's top, a borderline t on every "
                                      "fold)"),
                 ("blind_groups_s73", "seed 73 (the model's step taken twice: second order)"),
                 ("blind_groups_s79", "seed 79 (discovery judged on its refit and retried about other time "
                                      "constants, a group weighed again given the effects after it; cd50fed: "
                                      "1 case failed, mended in c1ae6fd)"),
                 ("blind_groups_s80", "seed 80 (retries only when discovery chose no term, a form of a chosen "
                                      "effect's own terms read as its law, the search on top of the form "
                                      "keeping the first search's effects; 233e6b0)"),
                 ("blind_groups_s82", "seed 82 (the noise floor's time constant from a passing candidate's "
                                      "shorter fit; 75df2a2)"),
                 ("blind_groups_s85", "seed 85 (the flow through the model's drag and lift on the velocity "
                                      "relative to the water; 76fac38)"),
                 ("blind_groups_s87", "seed 87 (multi only, the same code)"),
                 ("blind_groups_s88", "seed 88 (a step-out with the magnet's phase, 20f216e, reverted in 0d1e8f0)"),
                 ("blind_groups_s90", "seed 90 (multi only, 5a466d8: the diagnosis of 76fac38; 1 case failed, "
                                      "mended in afb971f)"),
                 ("blind_groups_s91", "seed 91 (fresh, e643ed0: the same diagnosis with that mend)"),
                 ("blind_groups_s92", "seed 92 (fresh, 9691f77: the swirl one term of the regression, a stand-in "
                                      "competing again on top of the form)"),
                 ("blind_groups_s94", "seed 94 (fresh, 0940a22: a look-ahead's next candidate tried when its "
                                      "first is dropped)"),
                 ("blind_groups_s97", "seed 97 (fresh, 91e2eb0: a look-alike group weighed again given the "
                                      "discovered form)"),
                 ("blind_groups_s99", "seed 99 (multi only, the same diagnosis; first run on an unlanded "
                                      "variant with a looser share gate)"),
                 ("blind_groups_s100", "seed 100 (fresh, 190d3e0: a group outside the lags' family weighed given "
                                       "the others, the effects left measured again once stand-ins are out)"),
                 ("blind_groups_s101", "seed 101 (fresh, multi only, the same diagnosis)"),
    ("blind_groups_s102", "seed 102 (fresh, 33f4167: the gradient force's cross terms tied to its pairs, the "
                          "first choices measured again given those on top of the form)"),
    ("blind_groups_s103", "seed 103 (fresh, multi only, 73eb11f: the same diagnosis)"),
    ("blind_groups_s105", "seed 105 (fresh, multi only, 06b83d9: a flow's form refitted as the water's velocity, "
                          "the thrust's factor one term per axis, further terms earning their place)"),
    ("blind_groups_s106", "seed 106 (fresh, multi only, 06b83d9: the same diagnosis)"),
    ("blind_groups_s108", "seed 108 (fresh, 55af7eb: a flow dropped as a swirl's uniform part comes back when the "
                          "form found without it holds no flow)"),
    ("blind_groups_s109", "seed 109 (fresh, multi only, 023d7ce: the same diagnosis)"),
    ("blind_groups_s110", "seed 110 (fresh, multi only, 07f9cb6: every drag through the water beside a flow)"),
    ("blind_s113", "seed 113 (fresh, multi beside the single-effect groups, 2d90968: every open-loop fit with the "
                   "evaluation's two passes)"),
    ("blind_s115", "seed 115 (fresh, multi beside the single-effect groups, 2b445de: the effects left once a "
                   "stand-in is out measured given the form, drags through a discovered flow)"),
    ("blind_s116", "seed 116 (fresh, multi beside the single-effect groups, 915e9da: discovery given a dropped "
                   "tentative effect)"),
    ("blind_lookalike_s117", "seed 117 (fresh, look-alikes only, 915e9da: discovery given a dropped tentative "
                             "effect)"),
    ("blind_s118", "seed 118 (fresh, multi beside the single-effect groups, 4acc1e7: the compiled kernels; one "
                   "case again on c325875, the residuals capped)"),
    ("blind_lookalike_s119", "seed 119 (fresh, look-alikes only, 578846c: the residuals capped)"),
    ("blind_s120", "seed 120 (fresh, multi beside the single-effect groups, d81d55b: a large drop asked on every "
                   "fold from t = 1)"),
    ("blind_lookalike_s121", "seed 121 (fresh, look-alikes only, d81d55b: a large drop asked on every fold from "
                             "t = 1)"),
    ("blind_s123", "seed 123 (fresh, multi beside the single-effect groups, cf23b9e: the floor lowered to a passing "
                   "refit, a better form from beside a tentative effect)"),
    ("blind_lookalike_s124", "seed 124 (fresh, look-alikes only, cf23b9e: the same diagnosis)"),
    ("blind_s125", "seed 125 (fresh, multi beside the single-effect groups, f3f23f8: the gradient force bending "
                   "with the field's strength, a step left after a backward drop measured again)"),
    ("blind_lookalike_s126", "seed 126 (fresh, look-alikes only, f3f23f8: the same diagnosis)"))


def several_effects_table() -> str:
    """docs/diagnose/several-effects.md: the blind bench's multi and lookalike groups, per seed."""
    outs = [load(name)["output"] for name, _ in SEVERAL_SEEDS]

    def multi(render: Callable[[dict], str]) -> list[str]:
        return [render(o["multi"]) if o["multi"]["cases"] else "-" for o in outs]

    def look(render: Callable[[dict], str]) -> list[str]:
        return [render(o["lookalike"]) if o["lookalike"]["cases"] else "-" for o in outs]

    def after(lk: dict) -> str:
        right_after = round((lk["resolved"] - lk["named_at_once"]) * lk["cases"])
        return f"{lk['declared']}, of which {right_after} named right after"

    rows = [
        ["`multi.all_named`: every hidden library effect named", *multi(lambda m: of(m["all_named"], m["cases"])),
         ">= 0.8"],
        ["`multi.visible_named`: every hidden library effect that its true form alone shows (>= 10 %) named",
         *multi(lambda m: of(m["visible_named"], m["cases"])), ""],
        ["`multi.all_named_drawn_visible`: the same over the cases whose both effects the simulator's own measure "
         "shows (drawn so from seed 45 on)",
         *multi(lambda m: of(m["all_named_drawn_visible"], m["drawn_visible"])
                if m.get("drawn_visible") else "-"), ""],
        ["`multi.all_named_detectable_jointly`: the same over the cases where each hidden library effect's true form "
         "lowers the error by >= 10 % once the other's is in (from seed 51 on)",
         *multi(lambda m: of(m["all_named_detectable_jointly"], m["detectable_jointly"])
                if m.get("detectable_jointly") else "-"), ""],
        ["`multi.extra_named`: a library effect named that is not hidden",
         *multi(lambda m: str(m["extra_named"])), "<= 1"],
        ["`multi.all_named_after_experiment`: the same at once or once a declared group's designed experiment is "
         "flown and its log added (from seed 46 on)",
         *multi(lambda m: f"{of(m['all_named_after_experiment'], m['cases'])} ({m['experiments']} flown; "
                          f"{m['extra_named_after_experiment']} extra)" if "experiments" in m else "-"), ""],
        ["`lookalike.wrong_named`: a wrong effect named without a group", *look(lambda lk: str(lk["wrong_named"])),
         "0"],
        ["`lookalike.resolved`: named right at once, or declared and named right after the experiment",
         *look(lambda lk: of(lk["resolved"], lk["cases"])), ">= 0.8"],
        ["... over the cases whose hidden effect the simulator's own measure shows (from seed 45 on)",
         *look(lambda lk: of(lk["resolved_visible"], lk["visible"]) if lk.get("visible") else "-"), ""],
        ["... named right at once", *look(lambda lk: of(lk["named_at_once"], lk["cases"])), ""],
        ["... declared as a group, the experiment flown", *look(after), ""],
        ["time per case (2 or 3 diagnoses, two cases at once, a busy machine)",
         *[f"{o['seconds_per_case']:.0f} s median" for o in outs], ""],
    ]
    return table(["figure", *[label for _, label in SEVERAL_SEEDS], "target"], rows)


def hidden_effects_table() -> str:
    """docs/diagnose/walkthrough.md: the diagnosis of the plant with each effect hidden."""
    cases = load("walkthrough_hidden_effects")["output"]["cases"]
    rows = []
    for c in cases:
        before, after = c["held_out_error_mm"]["before"], c["held_out_error_mm"].get("after")
        error = f"{before:.2f} -> {after:.2f} mm" if after is not None else \
            f"{before:.2f} mm, floor {c['noise_floor_mm']:.2f} mm"
        reduction = f"{c['reduction'] * 100:.0f} %" if c.get("ranked_first") else f"best {c['reduction'] * 100:.0f} %"
        rows.append([c["hidden"], c.get("ranked_first") or "(none named)", error, reduction, c.get("fitted", "")])
    return table(["hidden in the plant FMU", "ranked first", "held-out error at 1.0 s", "reduction", "fitted"], rows)


def blind_table() -> str:
    """docs/diagnose/validation.md: the blind bench's two full draws (seed 3, then seed 2)."""
    outs = [load(name)["output"] for name in ("blind_s3", "blind_s2")]

    def frac(part: float, n: int) -> str:
        return f"{of(part, n)} ({part:.3f})"

    rows = [
        [f"library effects ranked first, all {outs[0]['library']['cases']} cases",
         *[frac(o["library"]["top1"], o["library"]["cases"]) for o in outs], ">= 0.90"],
        [f"the same over the {outs[0]['library']['detectable']} cases a perfect diagnosis can see (true form >= 10 %)",
         *[frac(o["library"]["top1_detectable"], o["library"]["detectable"]) for o in outs], ""],
        ["detectable cases first or tied with the first (paired t < 3, the verdict says so)",
         *[of(o["library"]["top1_or_tied_detectable"], o["library"]["detectable"]) for o in outs], ""],
        ["median achieved / true-form reduction (detectable cases)",
         *[f"{o['library']['median_reduction_ratio']:.3f}" for o in outs], ">= 0.7"],
        [f"false alarms on the {outs[0]['no_effect']['cases']} cases with nothing hidden (a named effect; a discovered "
         "form with >= 10 % and t >= 3)",
         *[f"{o['no_effect']['false_alarms']} and {o['no_effect']['discovered_alarms']}" for o in outs], "0"],
        ["outside effects whose discovered form reaches half the true form's reduction",
         *[frac(o["outside"]["discovered_ok"], o["outside"]["discovered_ok_of"]) for o in outs], ">= 0.75"],
        ["time per case, median (max)",
         *[f"{o['seconds_per_case']:g} s ({o['seconds_per_case_max']:.0f} s)" for o in outs], ""],
    ]
    return table(["figure", "seed 3 (new)", "seed 2", "target"], rows)


# ---------------------------------------------------------------- the twin page


def twin_inject_table(name: str) -> Callable[[], str]:
    """docs/twin.md: ``benchmarks/twin_inject.py``'s runs kept in ``data/NAME.json``, one row a case and camera:
    the tracking logs apart (mean per seed, their mean, the worst max), the open-loop replays, the tracking
    errors; under it, the command that printed them."""
    def render() -> str:
        d = load(name)
        o = d["output"]
        target, rows = o["target_mean_mm"], []
        groups: dict[tuple[str, str], list[dict]] = {}
        for c in o["cases"]:
            groups.setdefault((c["name"], c["camera"]), []).append(c)
        for (case, camera), runs in groups.items():
            means = [r["log_mm"]["mean"] for r in runs]
            mean = sum(means) / len(means)
            loops = [r["open_loop_mm"] for r in runs if r["open_loop_mm"]]
            loop = (" / ".join(f"{sum(x[k]['mean'] for x in loops) / len(loops):.4f}" for k in ("linear", "held"))
                    if loops else "-")
            track = " / ".join(f"{sum(r['tracking_error_mean_mm'][k] for r in runs) / len(runs):.3f}"
                               for k in ("native", "injected"))
            ok = sum(m <= target for m in means)
            rows.append([f"`{case}`", runs[0]["form"], camera, " / ".join(f"{m:.4f}" for m in means),
                         f"**{mean:.4f}**" if mean <= target else f"{mean:.4f}",
                         f"{max(r['log_mm']['max'] for r in runs):.3f}", f"{ok} of {len(means)}", loop, track])
        seeds = ", ".join(str(s) for s in dict.fromkeys(c["seed"] for c in o["cases"]))
        head = table(["case", "forms", "camera", f"logs apart, mean, seeds {seeds} [mm]", "mean [mm]", "max [mm]",
                      f"seeds <= {target:g} mm", "open loop, linear / held, mean [mm]",
                      "tracking error, native / injected [mm]"], rows)
        return head + (f"\n(`PYTHONPATH=. .venv/bin/python {d['command']}`: {o['duration_s']:g} s a run, "
                       f"{o['wall_s']:.0f} s in all; commit {d['commit']}, {when(d)}; "
                       f"[data](benchmarks/data/{name}.json))\n")
    return render


# ---------------------------------------------------------------- the long-runs page


def soak_table(names: tuple[str, ...]) -> Callable[[], str]:
    """docs/long-runs.md: the soak runs kept in the data files ``names`` (in order), one row a run: hours,
    layout, wall time, peak memory (the scheduler's and the largest node's with ``--processes``), files, speed."""
    def render() -> str:
        rows = []
        for name in names:
            for r in load(name)["output"]["runs"]:
                processes = r["layout"] == "processes"
                peak = f"{r['peak_mb']:.1f}" + (f" (scheduler); largest node {r['nodes_peak_mb']:.1f}"
                                                if processes and r.get("nodes_peak_mb") else "")
                rows.append([f"{r['hours']:g}", "`--processes`" if processes else "one process", f"{r['wall_s']:.1f}",
                             peak, f"{r['files_mb']:.1f}", f"{r['realtime_factor']:.1f}x"])
        return table(["hours", "layout", "wall [s]", "peak memory [MB]", "files [MB]", "real-time factor"], rows)
    return render


def realtime_table() -> str:
    """docs/getting-started.md: the racetrack paced at real time, per layout: ticks, missed, lateness, SCHED_FIFO."""
    o = load("realtime")["output"]
    rows = []
    for key, label in (("one", "one process"), ("processes", "`--processes`")):
        if key in o:
            r, late = o[key], o[key]["lateness_ms"]
            rows.append([label, str(r["ticks"]), str(r["missed"]),
                         f"{late['p50']:.2f} / {late['p99']:.2f} / {late['max']:.2f}",
                         "granted" if r["sched_fifo"] is True else f"not granted ({r['sched_fifo']})"])
    return table(["layout", "ticks", "missed", "lateness p50 / p99 / max [ms]", "SCHED_FIFO"], rows)


def sweep_jobs_table() -> str:
    """docs/scaling-out.md: the Fig. 6 sweep and the reproduction with one worker and with two: wall times,
    ratio, and whether the rows, logs or tables came out the same."""
    fig6, quick, full = (load(n) for n in ("sweep_jobs", "sweep_jobs_reproduce_quick", "sweep_jobs_reproduce"))

    def wall(o: dict, key: str) -> str:
        w = o[key]
        return f"{w['median']:g} s" if "median" in w else f"{w['runs'][0]:g} s"

    o = fig6["output"]
    same = "identical (rows but for `solve_ms`; all 55 `log.csv`)" if o["rows_identical_but_timings"] and \
        o["logs_identical"] else "rows or logs differ"
    rows = [["Fig. 6 (`feedback_sweep`, 55 runs of 50 s)", wall(o, "jobs_1_wall_s"), wall(o, "jobs_2_wall_s"),
             f"{o['ratio']:.2f}", same]]
    for label, d in (("`cosim reproduce --quick` (fresh cache)", quick),
                     (f"`cosim reproduce` (fresh cache; one run each, {full['machine_load']})", full)):
        o = d["output"]
        rows.append([label, wall(o, "jobs_1_wall_s"), wall(o, "jobs_2_wall_s"), f"{o['ratio']:.2f}",
                     "tables identical but for the timings" if o["tables_identical_but_timings"] else "tables differ"])
    return table(["sweep", "`--jobs 1`", "`--jobs 2`", "ratio", "rows, logs"], rows)


#: The soak runs of the long-runs page's two tables: ``soak.py --hours 1 12`` (one process, then its
#: ``--processes`` hour), and ``soak.py --no-one-process --processes-hours 1 12``.
SOAK_TABLES = {"soak-hours-1-12": ("soak_one_process", "soak_processes_first"),
               "soak-processes-12h": ("soak_processes",)}


#: docs/twin.md's tables of ``benchmarks/twin_inject.py``'s runs: the FMU's laws and the scatter floor, and
#: (``--library``) the library's forms; table name -> data file.
TWIN_INJECT_TABLES = {"twin-inject": "twin_inject", "twin-inject-library": "twin_inject_library"}


#: Every table a page may mark, by name: what renders it (from the data files it loads).
TABLES: dict[str, Callable[[], str]] = {
    "benchmarks": benchmarks_table,
    "mutation": mutation_table,
    "diagnose-archive": archive_table,
    "diagnose-drift-bench": drift_table,
    "diagnose-several-effects-bench": several_effects_table,
    "diagnose-hidden-effects": hidden_effects_table,
    "diagnose-blind-bench": blind_table,
    **{name: soak_table(files) for name, files in SOAK_TABLES.items()},
    "realtime": realtime_table,
    "sweep-jobs": sweep_jobs_table,
    **{name: twin_inject_table(data) for name, data in TWIN_INJECT_TABLES.items()},
}


def pages() -> list[Path]:
    """The Markdown pages that may mark tables: every page under ``docs/``."""
    return sorted(p for item in PAGES for p in (ROOT / item).rglob("*.md"))


def marked() -> dict[str, list[tuple[Path, str]]]:
    """Every marked table's name and, per page showing it, what its marker holds."""
    found: dict[str, list[tuple[Path, str]]] = {}
    for page in pages():
        for match in MARK.finditer(page.read_text()):
            found.setdefault(match["name"], []).append((page, match["body"]))
    return found


def stale() -> list[str]:
    """One line per problem: a marked table that is unknown, never shown, or differs from its data."""
    found, problems = marked(), []
    for name in sorted(set(found) - set(TABLES)):
        problems.append(f"{found[name][0][0].relative_to(ROOT)}: unknown table {name} (known: {', '.join(TABLES)})")
    for name in sorted(set(TABLES) - set(found)):
        problems.append(f"table {name} is marked on no page")
    for name, shown in found.items():
        if name in TABLES:
            fresh = TABLES[name]()
            problems += [f"{page.relative_to(ROOT)}: table {name} differs from its data; remake it: "
                         f".venv/bin/python tools/bench_tables.py" for page, body in shown if body != fresh]
    return problems


def write() -> list[Path]:
    """Render every marked table into its pages; returns the pages changed."""
    changed = []
    for page in pages():
        text = page.read_text()
        new = MARK.sub(lambda m: f"<!-- table: {m['name']} -->\n{TABLES[m['name']]()}<!-- /table -->"
                       if m["name"] in TABLES else m[0], text)
        if new != text:
            page.write_text(new)
            changed.append(page)
    return changed


def record(name: str, command: list[str], load_note: str | None) -> Path:
    """Run ``command`` (a benchmark, from the checkout's root, with this Python) and keep what it printed on
    stdout as ``data/NAME.json``: one JSON value, or one a line (a list), under a header."""
    argv = [sys.executable, *command] if command[0].endswith(".py") else command
    before = os.getloadavg()
    done = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"`{' '.join(command)}` failed (exit {done.returncode}):\n{done.stderr[-2000:]}")
    text = done.stdout.strip()
    try:
        output = json.loads(text)
    except json.JSONDecodeError:
        try:
            output = [json.loads(line) for line in text.splitlines() if line.strip()]
        except json.JSONDecodeError as err:
            raise SystemExit(f"`{' '.join(command)}` printed no JSON ({err}):\n{text[:500]}") from None
    after = os.getloadavg()
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                            text=True).stdout.strip() or None
    data = {"command": " ".join(command), "date": datetime.date.today().isoformat(), "commit": commit,
            "machine_load": load_note or (f"load average {before[0]:.1f} before, {after[0]:.1f} after "
                                          f"({os.cpu_count()} CPUs)"),
            "source": PRINTED, "output": output}
    DATA.mkdir(parents=True, exist_ok=True)
    path = DATA / f"{name}.json"
    path.write_text(json.dumps(data, indent=1) + "\n")
    return path


def main(argv: list[str] | None = None) -> int:
    """The command line: rewrite the tables, check them, or record a benchmark's JSON."""
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["record"]:
        p = argparse.ArgumentParser(prog="bench_tables.py record", description="keep a benchmark's JSON")
        p.add_argument("name", help="the data file's name (docs/benchmarks/data/NAME.json)")
        p.add_argument("--load", default=None, help="the machine's load, as text (default: the load average)")
        rest = argv[1:]
        cut = rest.index("--") if "--" in rest else len(rest)  # options before --, the command after it
        args = p.parse_args(rest[:cut])
        command = rest[cut + 1:]
        if not command:
            p.error("no command given after --")
        print(f"kept {record(args.name, command, args.load).relative_to(ROOT)}")
        return 0
    p = argparse.ArgumentParser(description="Render the docs' measured tables from docs/benchmarks/data.")
    p.add_argument("--check", action="store_true", help="only say which tables differ from their data (exit 1)")
    args = p.parse_args(argv)
    if args.check:
        problems = stale()
        print("\n".join(problems) or "every table is current")
        return 1 if problems else 0
    for page in write():
        print(f"updated {page.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
