"""Mutation testing of the modules where a silent bug is dangerous (mutmut 3).

Each module is mutated on its own, in a private copy of the project under
``build/mutation/NAME/`` (mutmut keeps its state there, so a second run only
tests what changed), and only its own tests run against each mutant. A
mutant is *killed* when a test fails or hangs (mutmut's timeout) with it in
place; the score is killed / mutants. The survivors are listed by name
(``mutmut show NAME`` in that directory prints the change); docs/testing.md
lists those judged equivalent, with the reason.

    python benchmarks/mutation.py                      # every module
    python benchmarks/mutation.py --only interlocks ekf --children 1

prints ``{"modules": {PATH: {"mutants", "killed", "score", "survived"}}, "seconds"}``.
Needs the ``mutation`` extra (``pip install -e '.[test,mutation]'``) and the
plant FMU (``make fmu``) for the tests that run a scenario. It takes tens of
minutes: it is not part of ``make test``.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
WORK = ROOT / "build" / "mutation"
#: What a private copy holds: the packages (mutmut copies them into mutants/), the tests and what they read.
COPIED = ("cosim", "cosim_plugins", "tests", "examples", "pyproject.toml", "README.md")
#: Files copied if present (the plant FMU the scenario tests run).
OPTIONAL = ("build/swimmer_plant.fmu",)


@dataclass(frozen=True)
class Target:
    """One module to mutate and the tests that must catch its mutants (pytest arguments)."""

    name: str
    path: str
    tests: tuple[str, ...]
    #: in a run without --only (False: its mutants can stall mutmut, see docs/testing.md)
    by_default: bool = True


COIL_TESTS = ("tests/coil_driver/test_coil_interlocks.py", "tests/coil_driver/test_coil_boundaries.py",
              "tests/coil_driver/test_coil_properties.py", "tests/controllers/test_controllers_nan_safety.py",
              "-k", "not stops_the_run and not recorded_trace and not readme and not cosim_validate")
EKF_TESTS = ("tests/estimators/test_kf_filter.py", "tests/estimators/test_ekf_jacobian.py",
             "tests/estimators/test_ekf_parts.py", "tests/estimators/test_kf_noise.py",
             "tests/estimators/test_kf_noise_parts.py")
# the loop in one process, delays 0 to 3 on each edge once (each run starts a zenoh session: a second)
DELAY_TESTS = ("tests/core/test_delays.py", "-k", "reference or one_process and (1-0 or 2-1 or 3-2 or 1-3)")
TARGETS = (  # cheap and most dangerous first: a run cut short still has their figures
    Target("interlocks", "cosim_plugins/coil_driver/interlocks.py", COIL_TESTS),
    Target("wiring", "cosim/runtime/wiring.py", ("tests/core/test_wiring.py",)),
    Target("ekf", "cosim_plugins/estimators/ekf.py", EKF_TESTS),
    Target("noise", "cosim_plugins/estimators/noise.py", EKF_TESTS),
    Target("stepper", "cosim/runtime/stepper.py", DELAY_TESTS, by_default=False),
    Target("portcache", "cosim/runtime/portcache.py", DELAY_TESTS, by_default=False),
    Target("raw_log", "cosim_plugins/raw_log.py",
           ("tests/identify/test_identify_data.py", "tests/identify/test_raw_log_outliers.py")),
    Target("convert", "cosim_plugins/identify/convert.py", ("tests/identify/test_convert.py",)),
    Target("inverse", "cosim_plugins/coil_driver/inverse.py",
           ("tests/coil_driver/test_coil_visa.py", "tests/coil_driver/test_coil_daq.py", *COIL_TESTS)),
    Target("kalman", "cosim_plugins/estimators/kalman.py",
           ("tests/estimators/test_kf_component.py", "tests/estimators/test_kf_plant.py")),
)

#: mutmut's statuses that count as caught (a failing test, or one that no longer finishes).
CAUGHT = {"killed", "timeout"}
RESULT_LINE = re.compile(r"^\s+(\S+): (.+)$")


def prepare(target: Target) -> Path:
    """A private copy of the project for ``target``, its pyproject naming what to mutate and which tests run."""
    work = WORK / target.name
    work.mkdir(parents=True, exist_ok=True)
    for item in (*COPIED, *OPTIONAL):
        src, dst = ROOT / item, work / item
        if not src.exists():
            continue
        if src.is_dir():
            shutil.copytree(src, dst, dirs_exist_ok=True,
                            ignore=shutil.ignore_patterns("__pycache__", "*.pyc", ".hypothesis", "build"))
        else:
            dst.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dst)
    config = "\n".join([
        "", "[tool.mutmut]",
        'source_paths = ["cosim", "cosim_plugins"]',  # whole packages in mutants/, so every import resolves there
        f"only_mutate = [{json.dumps(target.path)}]",
        f"pytest_add_cli_args_test_selection = {json.dumps(list(target.tests))}",
        'pytest_add_cli_args = ["-p", "no:cacheprovider"]',
        # a mutant whose tests take 10x their clean time plus 10 s hangs (caught); generous, as the machine is shared
        "timeout_multiplier = 10.0", "timeout_constant = 10.0",
        'also_copy = ["examples", "README.md", "build"]',
        "",
    ])
    pyproject = work / "pyproject.toml"
    text = (ROOT / "pyproject.toml").read_text()
    pyproject.write_text(text.split("\n[tool.mutmut]")[0] + config)
    return work


def results(work: Path) -> dict[str, str]:
    """{mutant name: status} of the last run in ``work``."""
    out = subprocess.run([sys.executable, "-m", "mutmut", "results", "--all", "true"], cwd=work,
                         capture_output=True, text=True, check=True).stdout
    return {m.group(1): m.group(2).strip() for line in out.splitlines() if (m := RESULT_LINE.match(line))}


def mutate(target: Target, children: int) -> dict:
    """Run mutmut on ``target``; its figures: mutants, killed, score, and the survivors' names."""
    work = prepare(target)
    log_path = WORK / f"{target.name}.log"
    with open(log_path, "w") as log:
        proc = subprocess.run([sys.executable, "-m", "mutmut", "run", "--max-children", str(children)], cwd=work,
                              stdout=log, stderr=subprocess.STDOUT)
    if proc.returncode != 0:
        raise RuntimeError(f"mutmut run for {target.path} exited {proc.returncode}; see {log_path}")
    status = results(work)
    killed = sum(s in CAUGHT for s in status.values())
    return {"mutants": len(status), "killed": killed, "score": round(killed / len(status), 3) if status else None,
            "survived": sorted(name for name, s in status.items() if s not in CAUGHT)}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", nargs="+", metavar="NAME", choices=[t.name for t in TARGETS],
                        help="these modules only (names: " + ", ".join(t.name for t in TARGETS) + "; without "
                             "--only, all but " + ", ".join(t.name for t in TARGETS if not t.by_default) + ")")
    parser.add_argument("--children", type=int, default=2, help="mutants tested at once (default 2)")
    args = parser.parse_args(argv)
    targets = [t for t in TARGETS if (t.name in args.only if args.only else t.by_default)]
    WORK.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    modules = {}
    for target in targets:  # mutmut's own output: build/mutation/NAME.log
        modules[target.path] = mutate(target, args.children)
        print(f"{target.path}: {modules[target.path]['killed']} of {modules[target.path]['mutants']} killed",
              file=sys.stderr, flush=True)
    print(json.dumps({"modules": modules, "seconds": round(time.perf_counter() - t0, 1)}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
