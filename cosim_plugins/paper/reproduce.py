"""``cosim reproduce``: every table and figure of the paper, in simulation, next to the paper's.

Steps: generate the paper dataset (12 training, 12 test, 1 validation logs),
train the four models (Table II), compare them with the measurements
(Table III), real-time prediction on the rotating circle (Table IV), the
feedback-interval sweep (Fig. 6), and path following with PI, MRAC and MPC on
the racetrack and the helix + racetrack (Fig. 3, Fig. 7, Sec. III-E).
``--quick`` shortens every experiment (a few minutes in all).

Writes ``DIR/report.md``, ``DIR/report.html``, ``DIR/report.json``, the plots,
and every run's folder (with its ``recording.rrd``) under ``DIR/runs``.
"""

from __future__ import annotations

import json
import os
import platform
import sys
import time
from pathlib import Path
from typing import Any

import yaml

from cosim import api
from cosim_plugins.paper import report_format
from cosim_plugins.paper.dataset import ensure_dataset
from cosim_plugins.resources import SCENARIOS_DIR as SCENARIOS

MODELS = ("physical", "sindy-nonlinear", "sindy-linear", "mlp")

#: The paper's figures (Zhao et al.), by table / figure.
PAPER: dict[str, Any] = {
    "table2": {"physical": (1696, 6), "sindy-nonlinear": (20.64, 330), "sindy-linear": (2.10, 60), "mlp": (2760, 276)},
    "table3": {  # split -> model -> (x, y, z, norm) [mm]
        "training": {"physical": (0.30, 0.30, 0.17, 0.54), "sindy-nonlinear": (0.20, 0.25, 0.18, 0.45),
                     "sindy-linear": (0.46, 0.46, 0.29, 0.83), "mlp": (0.32, 0.36, 0.19, 0.52)},
        "test": {"physical": (0.40, 0.40, 0.17, 0.68), "sindy-nonlinear": (0.20, 0.25, 0.18, 0.45),
                 "sindy-linear": (0.47, 0.48, 0.29, 0.86), "mlp": (0.35, 0.39, 0.19, 0.56)},
        "validation": {"physical": (0.21, 0.23, 0.19, 0.45), "sindy-nonlinear": (0.34, 0.35, 0.33, 0.70),
                       "sindy-linear": (0.57, 0.65, 0.34, 1.03), "mlp": (0.34, 0.46, 0.25, 0.63)},
    },
    "table4": {"physical": (0.24, 0.34, 0.31, 0.62), "sindy-nonlinear": (0.42, 0.46, 0.52, 0.94),
               "sindy-linear": (0.48, 0.54, 0.40, 0.95), "mlp": (0.69, 0.55, 0.42, 1.02)},
    "fig6": {"none": (0.180, 9.0), "kf": (0.420, 4.6)},  # largest interval [s], tracking error [mm]
    "paths": {"racetrack": {"pi": (2.68, 1.98), "mpc": (2.7, 2.2)}, "helix": {"mpc": (3.3, 1.9)}},
    "mpc_solve_ms": (10.7, 5.3),
}

#: Quick mode: simulated seconds per run and the intervals of the feedback sweep.
QUICK = {"duration_s": 20.0, "intervals": [0.02, 0.18, 0.42, 1.0]}


def _say(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


#: The seeds every point of the feedback sweep is repeated over (full run; quick: the scenario's one).
SWEEP_SEEDS = [7, 8, 9]
#: The profiles every closed-loop experiment runs on (``--set profile=...``).
PROFILES = ("ideal", "lab")


def _scenario_copy(name: str, out_dir: Path, quick: bool, profile: str = "ideal") -> Path:
    """The scenario as run: on ``profile``, shortened in quick mode, the interval sweep repeated over
    :data:`SWEEP_SEEDS` in a full run, written next to the results."""
    data, _ = api.load_document(SCENARIOS / name)  # the framework's reading of numbers (5e-8)
    data["profile"] = profile
    key = "components.camera.params.interval_s"
    if quick:
        data["duration_s"] = min(float(data["duration_s"]), QUICK["duration_s"])
        if key in data.get("sweep", {}):
            data["sweep"][key] = QUICK["intervals"]
    elif key in data.get("sweep", {}):
        data["sweep"]["seed"] = SWEEP_SEEDS
    stem = Path(name).stem + report_format.profile_suffix(profile)
    path = out_dir / "scenarios" / f"{stem}.yaml"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _run_scenario(name: str, out_dir: Path, quick: bool, jobs: int = 1, workers=None,
                  profile: str = "ideal") -> dict:
    scenario = _scenario_copy(name, out_dir, quick, profile)
    return api.run(api.RunRequest(scenario, out_dir / "runs" / scenario.stem, [], False, progress=True),
                   api.SweepOptions(jobs=jobs, workers=workers))


def _dataset_info(dataset) -> dict:
    """A dataset's log files per split (for report.json)."""
    return {s: [str(p) for p in getattr(dataset, s)] for s in ("training", "test", "validation")}


def _train(dataset, out_dir: Path, quick: bool) -> dict:
    """Fit the four models (timed: Table II) and put them where scenarios look for them."""
    from cosim_plugins.identify.cache import model_path
    from cosim_plugins.identify.dataset import Dataset
    from cosim_plugins.identify.fit import fit_models, save_models, summarise

    data = Dataset.from_paths(dataset.training)
    models = fit_models(data, list(MODELS), seed=0, progress=lambda m: _say(f"  {m}"))
    summary = summarise(models, data, seed=0)
    save_models(models, summary, out_dir / "models")
    for name, model in models.items():
        path = model_path(name, quick)
        path.parent.mkdir(parents=True, exist_ok=True)
        model.save(path)
    return summary


def _compare(dataset, out_dir: Path) -> dict:
    """Table III on each split; plots (and a rerun overlay) of predictions on the validation log."""
    from cosim_plugins.identify.compare import compare
    from cosim_plugins.identify.dataset import Dataset
    from cosim_plugins.identify.fit import load_models
    from cosim_plugins.identify.plots import write_plots

    models = load_models(out_dir / "models")
    result = {}
    for split in ("training", "test", "validation"):
        data = Dataset.from_paths(getattr(dataset, split))
        result[split] = compare(models, data)
    files = write_plots(models, data, result["validation"], out_dir / "plots" / "table3")
    result["plots"] = [str(f.relative_to(out_dir)) for f in files if f.suffix == ".png"]
    return result


def _trajectory_plots(key: str, out_dir: Path) -> list[str]:
    """Fig. 3 / Fig. 7 analogs: each controller's true path over the reference, top and side views."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    scenario, _ = api.load_document(out_dir / "scenarios" / f"controllers_{key}.yaml")
    path = api.make_path(scenario["path"]["plugin"], scenario["path"].get("params", {})).points(0.0) * 1e3
    runs = sorted((out_dir / "runs" / f"controllers_{key}" / "runs").glob("*"))
    fig, axes = plt.subplots(2, len(runs), figsize=(4 * len(runs), 7), squeeze=False)
    for col, run_dir in enumerate(runs):
        truth = np.load(run_dir / "trace.npz")["plant.position"] * 1e3
        for row, (i, j) in enumerate(((0, 1), (0, 2))):
            ax = axes[row][col]
            ax.plot(path[:, i], path[:, j], "k--", lw=1, label="path")
            ax.plot(truth[:, i], truth[:, j], lw=0.8, label="swimmer (true position)")
            if row == 0:
                ax.set_aspect("equal", adjustable="datalim")
            else:  # a flat path would squash a side view drawn to scale: show at least +-15 mm of height
                mid = 0.5 * (truth[:, j].min() + truth[:, j].max())
                half = max(15.0, 0.6 * (truth[:, j].max() - truth[:, j].min()))
                ax.set_ylim(mid - half, mid + half)
            ax.set_xlabel(f"{'xyz'[i]} [mm]")
            ax.set_ylabel(f"{'xyz'[j]} [mm]")
            ax.tick_params(labelsize=8)
        axes[0][col].set_title(f"{run_dir.name.split('_', 1)[-1]}: top view (x-y)", fontsize=9)
        axes[1][col].set_title("side view (x-z)", fontsize=9)
    axes[0][0].legend(fontsize=8)
    fig.suptitle(f"{key}: each controller's path (simulation, the paper's Fig. 3/7 analog)", fontsize=10)
    fig.tight_layout()
    target = out_dir / "plots" / f"paths_{key}.png"
    target.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(target, dpi=100)
    plt.close(fig)
    return [str(target.relative_to(out_dir))]


def reproduce(out_dir: Path, quick: bool = False, jobs: int = 1) -> dict:
    """Run everything, the runs of each sweep ``jobs`` at a time; returns the report dict (also
    written to ``out_dir``)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    if quick:
        os.environ["COSIM_DATASET"] = "quick"  # on-demand models in the scenarios use the quick data
    wall0 = time.perf_counter()
    timings: dict[str, float] = {}
    results: dict[str, Any] = {}
    with api.workers(jobs) as pool:  # one set of worker processes for every sweep
        steps = [
            ("dataset", lambda: ensure_dataset(quick=quick, jobs=jobs, workers=pool)),
            ("table2", lambda: _train(results["dataset"], out_dir, quick)),
            ("table3", lambda: _compare(results["dataset"], out_dir)),
            ("table4", lambda: _run_scenario("realtime_prediction.yaml", out_dir, quick, jobs, pool)),
        ]
        for profile in PROFILES:
            sfx = report_format.profile_suffix(profile)
            if profile != "ideal":  # the profile's own logs, for the models its scenarios train on demand
                steps.append((f"dataset{sfx}", lambda p=profile: _dataset_info(
                    ensure_dataset(quick=quick, jobs=jobs, workers=pool, profile=p))))
            steps += [
                (f"fig6{sfx}", lambda p=profile: _run_scenario("feedback_sweep.yaml", out_dir, quick, jobs, pool, p)),
                (f"racetrack{sfx}", lambda p=profile, x=sfx: {
                    **_run_scenario("controllers_racetrack.yaml", out_dir, quick, jobs, pool, p),
                    "plots": _trajectory_plots("racetrack" + x, out_dir)}),
                (f"helix{sfx}", lambda p=profile, x=sfx: {
                    **_run_scenario("controllers_helix.yaml", out_dir, quick, jobs, pool, p),
                    "plots": _trajectory_plots("helix" + x, out_dir)}),
            ]
        for i, (key, step) in enumerate(steps, 1):
            _say(f"[{i}/{len(steps)}] {key} ...")
            t0 = time.perf_counter()
            results[key] = step()
            timings[key] = round(time.perf_counter() - t0, 2)
    results["dataset"] = _dataset_info(results["dataset"])
    report = {"quick": quick, "jobs": jobs, "wall_time_s": round(time.perf_counter() - wall0, 1),
              "step_time_s": timings,
              "machine": {"cpus": os.cpu_count(), "platform": platform.platform()}, "paper": PAPER, "ours": results}
    (out_dir / "report.json").write_text(json.dumps(report, indent=2, default=str) + "\n")
    markdown = report_format.markdown(report)
    (out_dir / "report.md").write_text(markdown)
    (out_dir / "report.html").write_text(report_format.html(markdown, title="Reproduction report"))
    return report


README_START, README_END = "<!-- results:start -->", "<!-- results:end -->"


def results_stamp(digest: str, quick: bool, wall_s: float) -> str:
    """The comment opening a page's results block: the digest of the code the results were made from
    (:func:`cosim_plugins.paper.code_digest.results_digest`, which ``tests/docs`` compares with the
    code as it is), whether the run was ``--quick``, and its wall time [s]."""
    run = f"quick run (--quick): {wall_s:.0f} s" if quick else f"full run: {wall_s:.0f} s"
    return f"<!-- generated by `cosim reproduce --docs` digest={digest}; {run} -->"


def update_results(report_dir: Path, readme: Path, assets: Path, digest: str | None = None) -> None:
    """Put the report's tables into the page ``readme`` (``docs/results.md``) between the results markers.

    The report's title and run details are dropped (the page's own heading
    introduces it); plots are copied into ``assets`` and linked from there (a plot
    whose name an earlier one took gets its folder's name in front: the lab
    profile's ``feedback_sweep_lab/sweep_interval_s.png``). The block opens with
    :func:`results_stamp`: ``digest`` is that of the code the report was made from
    (taken before the run; default: the code as it is now).
    """
    import re
    import shutil

    from cosim_plugins.paper.code_digest import results_digest

    report_dir, readme, assets = Path(report_dir), Path(readme), Path(assets)
    body = (report_dir / "report.md").read_text().split("\n## ", 1)[1]
    assets.mkdir(parents=True, exist_ok=True)

    used: dict[str, Path] = {}  # asset name -> the plot copied there (two profiles' plots share names)

    def relink(match: re.Match) -> str:
        source = report_dir / match[2]
        name = source.name
        if used.get(name, source) != source:
            name = f"{source.parent.name}_{name}"
        used[name] = source
        target = assets / name
        shutil.copyfile(source, target)
        return f"![{match[1]}]({target.relative_to(readme.parent)})"

    body = re.sub(r"!\[(.*?)\]\((.*?)\)", relink, "## " + body)  # the report's levels: the page's title is #
    text = readme.read_text()
    if README_START not in text or README_END not in text:
        raise ValueError(f"{readme} has no {README_START} ... {README_END} block")
    head, rest = text.split(README_START, 1)
    tail = rest.split(README_END, 1)[1]
    report = json.loads((report_dir / "report.json").read_text())
    stamp = results_stamp(digest or results_digest(), bool(report.get("quick")), report["wall_time_s"])
    readme.write_text(f"{head}{README_START}\n{stamp}\n\n{body.strip()}\n\n{README_END}{tail}")
