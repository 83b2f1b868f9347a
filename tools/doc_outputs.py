"""Regenerate every command output the docs show, and check that none is stale.

A page shows a command's output between markers::

    <!-- output: NAME -->
    ```text
    $ cosim scenarios
    ...
    ```
    <!-- /output -->

and :data:`BLOCKS` says how to make output ``NAME``: the shell lines to run (in a fresh folder,
with the ``cosim`` of the Python running this script first on the PATH), which of them to
show, and what of their output to keep. ``python tools/doc_outputs.py [NAME...]`` runs them
and rewrites every marked block of the README and of ``docs/`` (all when no name is given).

Quick blocks (a few seconds) are re-run by the test ``tests/docs/test_doc_outputs.py``,
which fails when a page differs from a fresh run (wall-clock figures masked). Slow blocks
(a minute or more: the diagnose walkthrough) carry the digest of the code they depend on
in their marker (``<!-- output: NAME digest=... -->``); the test recomputes it and fails
when that code changed since the block was made, naming the command that remakes it.
The paper's results (``docs/results.md``, between ``<!-- results:start -->`` and
``<!-- results:end -->``) are ``cosim reproduce --docs``'s: that command writes the digest of the
code the results depend on (``cosim_plugins.paper.code_digest.RESULTS_CODE``) into the block, and
:func:`results_problem` (run by the test) says when it is missing, from a ``--quick`` run, or stale.
The measured tables of the benchmark and diagnose pages are ``tools/bench_tables.py``'s.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # the checkout's package, whatever the current folder
from cosim_plugins.paper.code_digest import code_digest, results_digest  # noqa: E402

PAGES = ("README.md", "docs")
MARK = re.compile(r"<!-- output: (?P<name>[\w-]+)(?: digest=(?P<digest>\w+))? -->\n(?P<body>.*?)<!-- /output -->",
                  re.S)


@dataclass(frozen=True)
class Block:
    """How to make one output: ``commands`` run in order in one folder; those in ``show`` (indexes;
    default all) appear as ``$ command`` and their output; ``keep`` trims a shown command's output."""

    commands: tuple[str, ...]
    show: tuple[int, ...] | None = None
    #: one trim for every shown command, or a tuple of them: one a shown command, in order
    keep: Callable[[str], str] | tuple[Callable[[str], str], ...] = lambda text: text
    #: slow blocks are not re-run by the test; the code they depend on is (modules and files, by digest)
    slow: bool = False
    depends: tuple[str, ...] = ()
    #: blocks made in the same folder as this one, first (their commands, not shown)
    after: str | None = None
    extra_env: dict = field(default_factory=dict)
    #: the exit statuses a command may end with (an error message the docs show exits non-zero)
    exit_codes: tuple[int, ...] = (0,)
    #: show what the shown commands print on stderr too (after their stdout)
    stderr: bool = False


def lines_between(first: str, last: str | None = None) -> Callable[[str], str]:
    """Keep the output from the line starting with ``first`` to the one starting with ``last`` (included)."""
    def keep(text: str) -> str:
        lines = text.splitlines()
        i = next(i for i, line in enumerate(lines) if line.startswith(first))
        j = next((j for j in range(i, len(lines)) if last and lines[j].startswith(last)), len(lines) - 1)
        return "\n".join(lines[i:j + 1])
    return keep


def ranking_and_short_verdict(text: str) -> str:
    """A diagnosis as the effects page shows it: the ranking (to its first blank line) and the verdict cut to
    its first clause and its fitted values (``verdict: X explains the error: ... Fitted: ...``)."""
    lines = text.splitlines()
    i = next(i for i, line in enumerate(lines) if line.startswith("rank effect"))
    j = next((j for j in range(i, len(lines)) if not lines[j].strip()), len(lines))
    verdict = next(line for line in lines if line.startswith("verdict:"))
    head = re.match(r"verdict: [^:]*:", verdict)
    fitted = re.search(r"Fitted: .*?\.(?=\s|$)", verdict)
    if head and fitted:
        verdict = f"{head[0]} ... {fitted[0]}"
    return "\n".join(lines[i:j]) + "\n\n" + verdict


def sweep_rows(column: str, values: tuple[str, ...], drop: tuple[str, ...]) -> Callable[[str], str]:
    """Keep a sweep's printed Markdown table (the last one with a ``column``: its runs may print tables of their
    own before it) with only the rows whose ``column`` is one of ``values`` and without the columns ``drop``, and
    the lines after it saying the largest values below the threshold."""
    def cells(line: str) -> list[str]:
        return [c.strip() for c in line.strip().strip("|").split("|")]

    def keep(text: str) -> str:
        lines = text.splitlines()
        heads = [i for i, line in enumerate(lines) if line.startswith("| ") and column in cells(line)]
        if not heads:
            raise SystemExit(f"the sweep printed no table with a column {column!r}:\n{text[-3000:]}")
        first = heads[-1]
        end = next((j for j in range(first, len(lines)) if not lines[j].startswith("|")), len(lines))
        header = cells(lines[first])
        cols = [k for k, name in enumerate(header) if name not in drop]
        at = header.index(column)
        rows = [cells(line) for line in lines[first + 2:end]]
        kept = [header, ["---"] * len(header), *(r for r in rows if r[at] in values)]
        table = ["| " + " | ".join(r[k] for k in cols) + " |" for r in kept]
        return "\n".join([*table, "", *(line for line in lines[end:] if line.startswith("largest "))])
    return keep


def pooled_columns(keep_columns: tuple[str, ...]) -> Callable[[str], str]:
    """Keep a sweep's table pooled over its seeds (after ``Pooled over the seeds:``) with only ``keep_columns``."""
    def keep(text: str) -> str:
        lines = text.splitlines()
        at = next((i for i, line in enumerate(lines) if line.startswith("Pooled over the seeds")), None)
        if at is None:
            raise SystemExit(f"the sweep printed no table pooled over its seeds:\n{text[-3000:]}")
        first = next(i for i in range(at, len(lines)) if lines[i].startswith("|"))
        end = next((j for j in range(first, len(lines)) if not lines[j].startswith("|")), len(lines))
        rows = [[c.strip() for c in line.strip().strip("|").split("|")] for line in lines[first:end]]
        missing = [c for c in keep_columns if c not in rows[0]]
        if missing:
            raise SystemExit(f"the pooled table has no column {', '.join(missing)} (it has {', '.join(rows[0])})")
        cols = [rows[0].index(c) for c in keep_columns]
        rows[1] = ["---"] * len(rows[0])
        return "\n".join("| " + " | ".join(r[k] for k in cols) + " |" for r in rows)
    return keep


def without_progress(text: str) -> str:
    """The output without the progress bar's redrawn lines (``1530step [00:02, ...]``, ended by carriage
    returns) and the blanks that clear it."""
    pieces = (piece for line in text.splitlines() for piece in line.split("\r"))
    return "\n".join(p for p in pieces if p.strip() and not re.match(r"\s*\d+step \[", p))


def lines_starting(*starts: str) -> Callable[[str], str]:
    """Keep only the output's lines that start with one of ``starts``."""
    return lambda text: "\n".join(line for line in text.splitlines() if line.startswith(starts))


def verdict_to_first_clue(text: str) -> str:
    """A diagnosis's verdict line, cut after its first clue (``... Clues: WHERE: ...; ...``)."""
    verdict = next(line for line in text.splitlines() if line.startswith("verdict:"))
    at = verdict.find("Clues: ")
    end = verdict.find("; ", at) if at >= 0 else -1
    return verdict[:end] + "; ..." if end >= 0 else verdict


def table_from(heading: str) -> Callable[[str], str]:
    """Keep the output from the line holding ``heading`` to the line before the next blank or ``wrote`` one."""
    def keep(text: str) -> str:
        lines = text.splitlines()
        i = next(i for i, line in enumerate(lines) if heading in line)
        j = next((j for j in range(i + 1, len(lines)) if not lines[j].strip() or lines[j].startswith("wrote")),
                 len(lines))
        return "\n".join(lines[i:j])
    return keep


def diagnose_table_and_verdict(text: str) -> str:
    """A diagnosis as the walkthrough shows it: the error table, the ranking, the legend and the verdict."""
    return lines_between("held-out error [mm]", "verdict:")(text)


HIDDEN_FLOW = ("--set components.plant.params.background_flow_on=true "
               "--set components.plant.params.flow_x=0.003")
DIAGNOSE_CODE = ("cosim_plugins.identify", "cosim_plugins.diagnose", "cosim_plugins.effects", "cosim_plugins.models",
                 "cosim_plugins.plant", "cosim_plugins/scenarios/diagnose")
#: What the flow-KF sweep runs besides the diagnosis: the components of its loop, its scenario, the sweep's table.
FLOW_KF_CODE = (*DIAGNOSE_CODE, "cosim_plugins.estimators", "cosim_plugins.controllers", "cosim_plugins.camera",
                "cosim_plugins.coil_driver", "cosim_plugins.paths", "cosim/record/summary.py",
                "cosim/record/sweep_report.py", "cosim_plugins/scenarios/flow_kf_sweep.yaml")
#: The sweep table's columns the effects page leaves out.
SWEEP_DROP = ("max [mm]", "prediction x / y / z / RMSE [mm]", "solve median / p99 [ms]", "status")

#: What the twin's calibration runs besides the diagnosis: the twin, the lab's loop it writes and runs.
TWIN_CODE = (*DIAGNOSE_CODE, "cosim_plugins.twin", "cosim_plugins.coil_driver", "cosim_plugins.camera",
             "cosim_plugins.controllers", "cosim_plugins.estimators", "cosim_plugins.paths", "cosim/record/summary.py",
             "cosim_plugins/scenarios/racetrack.yaml")


def calibration_table(text: str) -> str:
    """``cosim twin calibrate``'s printout from its error table to its list of held parameters."""
    return lines_between("held-out error [mm]", "held at the FMU's values")(text)


BLOCKS: dict[str, Block] = {
    "first-steps": Block(("cosim run racetrack --set components.camera.params.interval_s=0.1 "
                          "--out runs/frames_100ms",)),
    "scenarios": Block(("cosim scenarios",)),
    "validate": Block(("cosim validate racetrack",)),
    "swap-controller": Block(("cosim run racetrack --set components.controller.plugin=controller.mrac "
                              "--out runs/mrac",)),
    "profiles": Block(("cosim plugins",), keep=lambda text: lines_between("profiles:")(text).split("\nviews:")[0]),
    "diagnose-walkthrough": Block(
        (f"cosim run diagnose/plain --out runs/diag_flow --quiet {HIDDEN_FLOW}",
         "cosim diagnose runs/diag_flow/runs/*/log.csv --out runs/diag_flow/diagnosis"),
        show=(1,), keep=diagnose_table_and_verdict, slow=True, depends=DIAGNOSE_CODE),
    "diagnose-added": Block(
        ("cosim diagnose runs/diag_flow/runs/*/log.csv --add background_flow --out runs/diag_flow/added",),
        keep=lines_between("held-out error [mm]", "noise floor"), slow=True, depends=DIAGNOSE_CODE,
        after="diagnose-walkthrough"),
    "twin-calibrate": Block(
        ("cosim twin calibrate runs/diag_flow/runs/*/log.csv --effects background_flow --out runs/diag_flow/twin",
         "cosim run runs/diag_flow/twin/twin.yaml --out runs/diag_flow/twin_run"),
        keep=(calibration_table, lambda text: text), slow=True, depends=TWIN_CODE, after="diagnose-walkthrough"),
    "until-stopped": Block(("timeout -s INT 20 cosim run racetrack --until-stopped --out runs/rig",),
                           keep=without_progress, exit_codes=(124,), stderr=True, slow=True,
                           depends=("cosim/runtime", "cosim/cli", "cosim_plugins/scenarios/racetrack.yaml")),
    "rotate": Block(("cosim run racetrack --set duration_s=120 --rotate 0.01 --out runs/rotated",)),
    "rotate-parts": Block(
        ("python -c 'from cosim.api import load_trace; print(load_trace(\"runs/rotated\")[\"t_s\"].shape)'",
         "python -c 'from cosim.api import iter_trace; "
         "print([len(p[\"t_s\"]) for p in iter_trace(\"runs/rotated\", [\"plant.position\"])])'"),
        after="rotate"),
    "hosts-plain-tcp": Block(
        ("printf 'scheduler: {host: one, listen: tcp/0.0.0.0:7447}\\nhosts:\\n  one: {address: 0.0.0.0}\\n' "
         "> hosts.yaml",
         "cat hosts.yaml", "cosim run racetrack --processes --hosts hosts.yaml"),
        show=(1, 2), exit_codes=(0, 2), stderr=True),
    "dask-refused": Block(("cosim run feedback_sweep --executor dask://tls://127.0.0.1:8786",
                           "cosim run feedback_sweep --executor dask://10.0.0.5:8786"), exit_codes=(2,), stderr=True),
    "lab-logs": Block(
        ('ln -sfn "$DOCS_ROOT/examples" examples',
         "cosim run diagnose/plain --out runs/lab/rig --quiet",
         "for case in helix wide vertical tilted; do\n"
         "  python examples/lab_recording.py runs/lab/rig/runs/*_case=$case --out runs/lab/recordings/$case\n"
         "  cosim convert --commands runs/lab/recordings/$case/commands.csv \\\n"
         "      --positions runs/lab/recordings/$case/detections.csv --out runs/lab/logs/$case.csv\n"
         "done",
         "cosim fit runs/lab/logs/{helix,wide,vertical}.csv --model physical,sindy-linear --out runs/lab/models",
         "cosim compare runs/lab/logs/tilted.csv --models runs/lab/models --split test \\\n"
         "    --json runs/lab/compare.json --plots runs/lab/plots",
         "cosim diagnose runs/lab/logs/*.csv --out runs/lab/diagnosis"),
        show=(2, 3, 4, 5),
        keep=(lines_starting("wrote runs/lab/logs/"), lines_between("model ", "physical"),
              table_from("one-step error"), verdict_to_first_clue),
        slow=True, depends=(*DIAGNOSE_CODE, "examples/lab_recording.py", "cosim_plugins/raw_log.py")),
    "lab-sensitivity": Block(
        ("cosim run lab_sensitivity --jobs 2 --out runs/lab_sensitivity",),
        keep=pooled_columns(("change", "mean tracking error [mm]", "min / max of the seeds' means [mm]")),
        slow=True,
        depends=("cosim_plugins.profiles", "cosim_plugins.camera", "cosim_plugins.controllers",
                 "cosim_plugins.estimators", "cosim_plugins.coil_driver", "cosim_plugins.plant", "cosim_plugins.paths",
                 "cosim/record/summary.py", "cosim/record/sweep_report.py",
                 "cosim_plugins/scenarios/lab_sensitivity.yaml")),
    "flow-kf-sweep": Block(
        (f"cosim run diagnose/plain --set duration_s=40 --out runs/flow/logs --quiet {HIDDEN_FLOW}",
         "cosim fit runs/flow/logs/runs/*/log.csv --model physical --out runs/flow/plain",
         "cosim diagnose runs/flow/logs/runs/*/log.csv --add background_flow --save-model runs/flow/with_flow.npz "
         "--out runs/flow/diagnosis",
         "cosim run flow_kf_sweep --out runs/flow/sweep"),
        show=(3,), keep=sweep_rows("interval_s", ("0.42", "1.0", "1.5", "2.0"), SWEEP_DROP), slow=True,
        depends=FLOW_KF_CODE),
    "diagnose-own-effect": Block(
        ('ln -sfn "$DOCS_ROOT/examples" examples',
         "cosim run diagnose/plain --out runs/diag_wall --quiet --set components.plant.params.wall_drag_on=true "
         "--set components.plant.params.wall_drag_length=0.008 --set components.plant.params.wall_drag_gain=3",
         "cosim diagnose runs/diag_wall/runs/*/log.csv --effects-file examples/my_effect.py "
         "--effects wall_drag,wall_drag_exp --out runs/diag_wall/mine"),
        show=(2,), keep=ranking_and_short_verdict, slow=True, depends=(*DIAGNOSE_CODE, "examples/my_effect.py")),
}

#: Wall-clock figures, masked when a page is compared with a fresh run.
WALL_CLOCK = (re.compile(r"simulated in [\d.]+ s \(\d+x real time\)"), re.compile(r"\d+(\.\d+)? s wall"))


def mask(text: str) -> str:
    """``text`` with its wall-clock figures replaced, for comparing two runs' outputs."""
    for pattern in WALL_CLOCK:
        text = pattern.sub("<wall clock>", text)
    return text


def pages() -> list[Path]:
    """The Markdown pages that may mark outputs: the README and every page under ``docs/``."""
    out = []
    for item in PAGES:
        path = ROOT / item
        out += sorted(path.rglob("*.md")) if path.is_dir() else [path]
    return out


def used_blocks() -> dict[str, list[Path]]:
    """Every marked output's name and the pages showing it."""
    found: dict[str, list[Path]] = {}
    for page in pages():
        for match in MARK.finditer(page.read_text()):
            found.setdefault(match["name"], []).append(page)
    return found


def digest(block: Block) -> str:
    """Hash of the code a slow block depends on: each module's syntax tree without docstrings and imports
    (so import order and docstrings, which change no output, leave it), each data file's bytes
    (:func:`cosim_plugins.paper.code_digest.code_digest`, which the results page's digest uses too)."""
    try:
        return code_digest(block.depends, " ".join(block.commands).encode(), ROOT)
    except FileNotFoundError as err:
        raise SystemExit(f"{err}: update BLOCKS in {__file__}") from None


#: The paper's results block of ``docs/results.md`` and the digest ``cosim reproduce --docs`` writes into it.
RESULTS_PAGE = ROOT / "docs" / "results.md"
RESULTS_BLOCK = re.compile(r"<!-- results:start -->\n<!-- generated by `cosim reproduce --docs` "
                           r"digest=(?P<digest>\w+); (?P<run>full|quick) run")
RESULTS_REMAKE = "nice .venv/bin/cosim reproduce --out runs/reproduce --docs docs/results.md"


def results_stamp(page: Path = RESULTS_PAGE) -> tuple[str, str] | None:
    """The results block's ``(digest, "full" or "quick")``, or None when the block carries no digest."""
    match = RESULTS_BLOCK.search(page.read_text())
    return (match["digest"], match["run"]) if match else None


def results_problem(page: Path = RESULTS_PAGE) -> str | None:
    """Why the page's results block is not current (no digest, a quick run, code changed since), or None."""
    stamp = results_stamp(page)
    where = page.relative_to(ROOT) if page.is_relative_to(ROOT) else page
    if stamp is None:
        return f"{where}: the results block carries no code digest; remake it: {RESULTS_REMAKE}"
    if stamp[1] != "full":
        return f"{where}: the results block was made by a --quick run; remake it: {RESULTS_REMAKE}"
    now = results_digest(ROOT)
    if stamp[0] != now:
        return (f"{where}: the results are stale (the code they depend on changed since they were made: "
                f"digest {stamp[0]}, now {now}); remake them: {RESULTS_REMAKE}")
    return None


def environment(extra: dict[str, str] | None = None) -> dict[str, str]:
    """This Python's scripts first on the PATH; no display; the package as installed; ``DOCS_ROOT`` the
    checkout (for a command that needs one of its files, without its path in the command's digest)."""
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env["DOCS_ROOT"] = str(ROOT)
    env.update(extra or {})
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    env["COLUMNS"] = "110"
    return env


def run_block(name: str, folder: Path, done: set[str] | None = None) -> str:
    """Run block ``name`` (and the one it comes after) in ``folder``; the text its marker holds."""
    done = set() if done is None else done
    block = BLOCKS[name]
    if block.after and block.after not in done:
        run_block(block.after, folder, done)
    shown = []
    for i, command in enumerate(block.commands):
        print(f"[{name}] $ {command}", file=sys.stderr, flush=True)
        result = subprocess.run(["bash", "-c", command], cwd=folder, env=environment(block.extra_env),
                                capture_output=True, text=True)
        if result.returncode not in block.exit_codes:
            raise SystemExit(f"[{name}] `{command}` failed (exit {result.returncode}):\n{result.stderr}")
        if block.show is None or i in block.show:
            printed = result.stdout.rstrip() + (f"\n{result.stderr.rstrip()}" if block.stderr else "")
            keep = block.keep[len(shown)] if isinstance(block.keep, tuple) else block.keep
            out = keep(printed.strip("\n"))
            shown.append(f"$ {command}\n{out}")
    done.add(name)
    return "```text\n" + "\n\n".join(shown).replace(str(ROOT), ".") + "\n```\n"


def marker(name: str) -> str:
    """The opening marker of output ``name`` (with its code digest when it is slow)."""
    block = BLOCKS[name]
    return f"<!-- output: {name}{f' digest={digest(block)}' if block.slow else ''} -->\n"


def write(outputs: dict[str, str]) -> list[Path]:
    """Put the made outputs into every page marking them; returns the pages changed."""
    changed = []
    for page in pages():
        text = page.read_text()
        new = MARK.sub(lambda m: (marker(m["name"]) + outputs[m["name"]] + "<!-- /output -->")
                       if m["name"] in outputs else m[0], text)
        if new != text:
            page.write_text(new)
            changed.append(page)
    return changed


def make(names: list[str]) -> dict[str, str]:
    """Make the outputs ``names`` in one fresh folder; ``{name: the text its marker holds}``."""
    outputs: dict[str, str] = {}
    with tempfile.TemporaryDirectory(prefix="cosim-docs-") as tmp:
        done: set[str] = set()
        for name in names:
            outputs[name] = run_block(name, Path(tmp), done)
    return outputs


def main(argv: list[str] | None = None) -> int:
    """The command line: make the named outputs (or all, or the quick ones) and write them into the pages."""
    parser = argparse.ArgumentParser(description="Regenerate the command outputs the docs show.")
    parser.add_argument("names", nargs="*", help=f"outputs to make (default: all): {', '.join(BLOCKS)}")
    parser.add_argument("--quick", action="store_true", help="only the quick ones (what the test re-runs)")
    args = parser.parse_args(argv)
    unknown = [n for n in args.names if n not in BLOCKS]
    if unknown:
        parser.error(f"unknown output(s) {', '.join(unknown)}; known: {', '.join(BLOCKS)}")
    names = args.names or [n for n, b in BLOCKS.items() if not (args.quick and b.slow)]
    for page in write(make(names)):
        print(f"updated {page.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
