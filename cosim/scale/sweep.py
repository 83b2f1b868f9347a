"""A sweep: one run per combination of the scenario's sweep axes, one after another or in parallel.

Every combination becomes a :class:`~cosim.scale.jobs.Job` with its run folder
``DIR/runs/NNN_label``. With ``jobs == 1`` and no executor the jobs run in
this process one after another; otherwise an executor (see
:mod:`cosim.scale.executors`) runs them in worker processes, at most as many at a
time as it has workers, and a progress line counts the runs done, failed
and running. Either way:

* the caches the runs need (a model trained on demand, a dataset,
  a plant's FMU) are made first, here, once (``Component.prepare``);
* a run that fails, hangs past ``timeout_s`` or crashes its process is one
  failed row, and the others go on;
* rows are in combination order, each with the host that ran it, the
  fingerprint of the code and files that made it (``code``, ``artifacts``)
  and every numeric figure of its run's summary (the components' own last);
* ``DIR/summary.json`` lists the rows done so far while the sweep goes
  (``"status": "running"``), then the table, the plot and the figures.
"""

from __future__ import annotations

import json
import shutil
import sys
import time
from collections import deque
from concurrent.futures import FIRST_COMPLETED, Future, wait
from pathlib import Path
from typing import Any, Iterable, Sequence

from cosim.contract.errors import UserError
from cosim.contract.plugins import lookup
from cosim.record.summary import TRACKING, metric_keys, other_figures, sweep_table
from cosim.record.sweep_report import (
    figure_label,
    figure_missing,
    largest_below_lines,
    pooled_table,
    report,
    report_figure,
    sweep_plot,
)
from cosim.runtime.fingerprint import host_name
from cosim.runtime.request import RunRequest
from cosim.runtime.runner import write_json
from cosim.runtime.scheduler import StopRequest
from cosim.scale.executors import open_executor
from cosim.scale.jobs import Job, client_env, failed_summary, run_job, scenario_sources, unpack
from cosim.scale.options import SweepOptions
from cosim.scenario.schema import Scenario, load_scenario, sweep_overrides

#: How long past its own timeout a job may take to stop and write its outputs before it is given up.
GIVE_UP_GRACE_S = 30.0


def run_sweep(scenario: Scenario, request: RunRequest, options: SweepOptions, stop: StopRequest) -> dict[str, Any]:
    """Run every combination of ``scenario``'s sweep, each with ``request``'s run options, where and how
    ``options`` say; returns the sweep's summary, also written to ``request.out_dir``."""
    out = Path(request.out_dir).resolve()
    combos = sweep_overrides(scenario)
    clear_earlier_sweep(out / "runs")
    record = SweepRecord(scenario, out, len(combos))
    executor, own = options.workers, False
    if executor is None and (options.jobs > 1 or options.executor is not None):
        executor, own = open_executor(options.executor, options.jobs,
                                      place=request.processes and request.node_cpus == "auto",
                                      tls=options.executor_tls), True
    try:
        jobs = _jobs(combos, request, options, out, ships=bool(executor and executor.ships),
                     stop_event=getattr(executor, "stop_name", None))
        claim_run_folders(job.run_dir for job in jobs)
        prepare_caches((job.scenario_file, job.overrides) for job in jobs)
        if executor is None:
            _serial(jobs, record, stop, request.progress)
        else:
            _parallel(jobs, record, stop, executor, request.progress)
    finally:
        if own:
            executor.close()
    return record.finish(stop.event.is_set(), request.progress)


def _jobs(combos, request: RunRequest, options: SweepOptions, out: Path, ships: bool,
          stop_event: str | None = None) -> list[Job]:
    scenario_file = Path(request.scenario_file).resolve()
    sources, scenario_rel = (), ""
    if ships:
        base = load_scenario(scenario_file, request.overrides)
        sources, scenario_rel = scenario_sources(scenario_file, [scenario_file.parent / p for p in base.plugins])
    serial = options.serial()
    jobs = []
    for i, (labels, extra) in enumerate(combos):
        tag = "_".join(f"{k}={v}" for k, v in labels.items())
        jobs.append(Job(index=i, labels=labels, scenario_file=str(scenario_file),
                        overrides=(*request.overrides, *extra, "sweep={}"),
                        run_dir=str(out / "runs" / f"{i:03d}_{_safe(tag)}"), processes=request.processes,
                        node_cpus=request.node_cpus, realtime=request.realtime,
                        hosts=str(Path(request.hosts).resolve()) if request.hosts else None,
                        progress=request.progress and serial, timeout_s=options.run_timeout_s,
                        env=client_env(), ship=ships, sources=sources, scenario_rel=scenario_rel,
                        stop_event=stop_event))
    return jobs


def prepare_caches(runs: Iterable[tuple[str | Path, Sequence[str]]]) -> None:
    """Let every component of every run ``(scenario file, overrides)`` make what the runs would
    otherwise each make (``Component.prepare``), once per distinct plugin and parameters. A run
    that fails here is left to fail when it runs, where its row says why."""
    seen: set[str] = set()
    for scenario_file, overrides in runs:
        try:
            scenario = load_scenario(scenario_file, list(overrides))
        except Exception:
            continue
        for spec in scenario.components.values():
            key = json.dumps([spec.plugin, spec.params], sort_keys=True, default=str)
            if key in seen:
                continue
            seen.add(key)
            try:
                lookup("component", spec.plugin).prepare({"dt": scenario.dt_s, **spec.params})
            except Exception:
                continue


def _serial(jobs: list[Job], record: "SweepRecord", stop, progress: bool) -> None:
    for job in jobs:
        if stop.event.is_set():
            break
        if progress:
            print(f"[{job.index + 1}/{len(jobs)}] {_tag(job)}", file=sys.stderr)
        row = record.add(job, run_job(job))
        if row["status"] != "ok" and progress:
            print(f"  {row.get('error')}", file=sys.stderr)
        if row["status"] == "interrupted":  # a signal stopped the run: the sweep stops with it
            stop.request(row.get("error") or "stopped")


def _parallel(jobs: list[Job], record: "SweepRecord", stop, executor, progress: bool) -> None:
    bar = _ProgressLine(len(jobs), progress)
    if progress:
        bar.write(f"cosim: {len(jobs)} runs on {executor.describe()}")
    pending = deque(jobs)
    running: dict[Future, tuple[Job, float]] = {}
    stopping = False
    try:
        while pending or running:
            if stop.event.is_set() and not stopping:
                stopping = True
                executor.stop_running(stop.reason or "stopped")
            while pending and not stop.event.is_set() and executor.free():
                job = pending.popleft()
                running[executor.submit(run_job, job)] = (job, time.monotonic())
            if not running:
                break
            done, _ = wait(running, timeout=0.25, return_when=FIRST_COMPLETED)
            for future in done:
                job, _ = running.pop(future)
                result = _result(future, job, executor)
                executor.release(future)
                bar.report(record.add(job, result), _tag(job))
            for future, (job, submitted) in list(running.items()):
                started = executor.started_at(future, submitted)  # None: its worker is still starting
                limit_s = (job.timeout_s or 0.0) + GIVE_UP_GRACE_S
                if job.timeout_s and started is not None and time.monotonic() - started > limit_s:
                    running.pop(future)
                    what = executor.abandon(future)
                    text = f"no result within {limit_s:g} s of its start (hung): {what}"
                    bar.report(record.add(job, _lost(job, text, ships=executor.ships)), _tag(job))
            bar.show(record.done, record.failed, executor.running())
    finally:
        bar.close()
    if pending and progress:
        print(f"cosim: sweep stopped: {len(pending)} of {len(jobs)} runs not started", file=sys.stderr)


def _result(future: Future, job: Job, executor) -> dict[str, Any]:
    """A finished job's result; its run folder unpacked under ``--out`` when it was shipped back."""
    exc = future.exception()
    if exc is None:
        result = future.result()
        if result.get("files") is not None:
            unpack(result["files"], Path(job.run_dir))
        return result
    return _lost(job, executor.crash_text(exc) or f"{type(exc).__name__}: {exc}", executor.ships)


def _lost(job: Job, text: str, ships: bool) -> dict[str, Any]:
    """The result of a job whose process gave none: a failed summary, also written into its run
    folder (which says ``running`` or does not exist)."""
    summary = failed_summary(text)
    written = Path(job.run_dir) / "summary.json"
    if not ships and written.is_file():  # what the run had written: keep its scenario name and pid
        summary = {**json.loads(written.read_text()), **summary}
        summary.pop("note", None)
    write_json(written, summary)
    return {"summary": summary, "host": None if ships else host_name(), "fingerprint": None}


class SweepRecord:
    """The rows of a sweep, in combination order, written to ``DIR/summary.json`` as they come."""

    def __init__(self, scenario: Scenario, out: Path, n_runs: int):
        self.scenario, self.out, self.n_runs = scenario, out, n_runs
        self.rows: dict[int, dict] = {}
        self.failed = 0

    @property
    def done(self) -> int:
        return len(self.rows)

    def ordered(self) -> list[dict]:
        return [self.rows[i] for i in sorted(self.rows)]

    def add(self, job: Job, result: dict[str, Any]) -> dict:
        summary, made_by = result["summary"], result.get("fingerprint") or {}
        mark_own(Path(job.run_dir))  # again: a run shipped back from a worker replaced the folder
        row = {**job.labels, **{k: summary[k] for k in metric_keys() if summary.get(k) is not None},
               "status": summary["status"], "dir": str(Path(job.run_dir).relative_to(self.out))}
        if summary["status"] != "ok":
            row["error"] = summary.get("error")
        row.update(host=result.get("host"), code=made_by.get("code"), artifacts=made_by.get("artifacts"))
        row.update(other_figures(summary))  # the components' own figures, after the bookkeeping
        self.rows[job.index] = row
        self.failed += row["status"] != "ok"
        write_json(self.out / "summary.json", {"scenario": self.scenario.name, "status": "running",
                                               "runs": self.n_runs, "sweep": self.ordered()})
        return row

    def finish(self, stopped: bool, progress: bool) -> dict[str, Any]:
        """The sweep's summary once its runs are done (or stopped): the rows, the table, and what
        the scenario's ``report`` asks of one figure (:mod:`cosim.record.sweep_report`), written to
        ``DIR/summary.json`` and ``DIR/summary.md``; the table printed when ``progress``."""
        rows = self.ordered()
        summary: dict[str, Any] = {"scenario": self.scenario.name, "sweep": rows}
        if stopped:
            summary["status"] = "interrupted"
        table = sweep_table(rows)
        spec = self.scenario.report
        figure = report_figure(spec.figure, spec.part, rows, default=TRACKING)
        missing = figure_missing(rows, figure) if spec.figure else None
        if missing:
            summary["report_error"] = missing
            print(f"cosim: {missing}", file=sys.stderr)
        summary.update(report(rows, figure, spec.threshold))
        if "pooled" in summary:
            table += "\nPooled over the seeds:\n\n" + pooled_table(summary["pooled"], figure)
        summary["plots"] = [] if figure is None else \
            [p.name for p in sweep_plot(rows, self.out, figure, spec.threshold, self.scenario.name)]
        write_json(self.out / "summary.json", summary)
        (self.out / "summary.md").write_text(table)
        if progress:
            print(table)
            if figure is not None and spec.threshold is not None:
                label = figure_label(rows, figure)
                for line in largest_below_lines(summary["largest_below_threshold"], label, figure, spec.threshold):
                    print(line)
        return summary


class _ProgressLine:
    """One line over the runs of a parallel sweep: done of all, failed, running."""

    def __init__(self, total: int, enabled: bool):
        self.bar = None
        if enabled:
            from tqdm import tqdm

            self.bar = tqdm(total=total, unit="run", file=sys.stderr, desc="sweep", dynamic_ncols=True)

    def write(self, text: str) -> None:
        if self.bar is not None:
            self.bar.write(text, file=sys.stderr)

    def report(self, row: dict, tag: str) -> None:
        if row["status"] != "ok":
            self.write(f"  {tag}: {row['status']}: {row.get('error')}")

    def show(self, done: int, failed: int, running: int) -> None:
        if self.bar is not None:
            self.bar.set_postfix_str(f"failed {failed}, running {running}", refresh=False)
            self.bar.update(done - self.bar.n)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


#: The file a sweep leaves in each run folder it makes: the only folders a later sweep removes.
SWEEP_MARK = ".cosim-sweep-run"


def mark_own(folder: Path) -> None:
    """Make ``folder`` (if need be) and mark it as a sweep's run folder."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / SWEEP_MARK).write_text("a run folder made by a cosim sweep; the next sweep here replaces it\n")


def claim_run_folders(folders) -> None:
    """Make and mark this sweep's run folders; one that exists without the mark (a folder the sweep did
    not make) is a UserError naming it, and nothing in it is touched."""
    for folder in map(Path, folders):
        if folder.exists() and not (folder / SWEEP_MARK).is_file():
            raise UserError(f"{folder} exists and was not made by a sweep: move it away (a sweep writes and "
                            "removes only folders it made)")
    for folder in map(Path, folders):
        mark_own(folder)


def clear_earlier_sweep(runs_dir: Path) -> None:
    """Remove the run folders an earlier sweep left in ``runs_dir``: those it marked as its own
    (:data:`SWEEP_MARK`), so none is mistaken for one of this sweep's; says how many went. A folder
    without the mark is left alone, whatever its name."""
    if not runs_dir.is_dir():
        return
    stale = sorted(d for d in runs_dir.iterdir()
                   if d.is_dir() and not d.is_symlink() and (d / SWEEP_MARK).is_file())
    for d in stale:
        shutil.rmtree(d)
    if stale:
        print(f"cosim: cleared {len(stale)} run folder(s) of an earlier sweep in {runs_dir}", file=sys.stderr)


def _tag(job: Job) -> str:
    return "_".join(f"{k}={v}" for k, v in job.labels.items())


def _safe(text: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "=._-" else "_" for ch in text)[:80]
