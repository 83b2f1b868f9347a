"""The wheel, as a user gets it: built from the tracked files, installed into a venv outside the
tree, it runs a shipped scenario and a diagnosis of its log from another folder, and imports
nothing from the source tree.

Offline and fast: the wheel goes in with ``--no-deps`` and the new venv sees the dependencies
of the interpreter running this script (its site-packages on the new venv's path, without
running its ``.pth`` files, so the editable install of the tree stays out). Usage, from
anywhere (``.ci/run`` calls it after ``make test``)::

    .venv/bin/python .ci/check_wheel.py [--keep DIR]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import sysconfig
import tempfile
import textwrap
import zipfile
from pathlib import Path

SRC = Path(__file__).resolve().parents[1]

#: What the wheel must carry besides the modules: the lab's data, read as package resources.
DATA = ("cosim_plugins/scenarios/racetrack.yaml", "cosim_plugins/scenarios/paper/training.yaml",
        "cosim_plugins/scenarios/diagnose/excitation.py", "cosim_plugins/plant/swimmer_plant/plant.c",
        "cosim_plugins/plant/swimmer_plant/modelDescription.xml", "cosim_plugins/camera/acA800_pair.yaml")

#: Run in the new venv: the command, then every imported module's file checked against the tree
#: (but the dependencies' folder, which a project venv inside the tree puts there).
PROBE = textwrap.dedent('''
    import sys
    from pathlib import Path

    src, deps, args = Path(sys.argv[1]), Path(sys.argv[2]), sys.argv[3:]
    from cosim.cli.main import main

    try:
        code = main(args)
    except SystemExit as exc:
        code = exc.code
    files = {name: Path(getattr(module, "__file__", None) or "/").resolve()
             for name, module in list(sys.modules.items())}
    inside = sorted(name for name, file in files.items() if file.is_relative_to(src) and not file.is_relative_to(deps))
    if inside:
        sys.exit(f"imported from the source tree {src}: {', '.join(inside)}")
    sys.exit(code)
''')


def sh(*cmd, cwd: Path | None = None) -> str:
    """Run ``cmd`` (printed first); its stdout, or exit naming the failure and its output."""
    print("$ " + " ".join(map(str, cmd)), flush=True)
    done = subprocess.run(list(map(str, cmd)), cwd=cwd, capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"failed (exit status {done.returncode}):\n{done.stdout}\n{done.stderr}")
    return done.stdout


def tracked_copy(dest: Path) -> Path:
    """The files a clone has (tracked, and new ones not ignored) copied to ``dest``: the wheel is built
    from them, not from whatever build/ or *.egg-info a working tree holds."""
    listing = sh("git", "-C", SRC, "ls-files", "--cached", "--others", "--exclude-standard")
    for rel in listing.splitlines():
        file = SRC / rel
        if file.is_file():
            (dest / rel).parent.mkdir(parents=True, exist_ok=True)
            (dest / rel).write_bytes(file.read_bytes())
    return dest


def check_contents(wheel: Path, tree: Path) -> None:
    """Exit unless ``wheel`` holds every module of the tree's two packages and the lab's data (:data:`DATA`)."""
    names = set(zipfile.ZipFile(wheel).namelist())
    modules = {p.relative_to(tree).as_posix() for pkg in ("cosim", "cosim_plugins")
               for p in (tree / pkg).rglob("*.py")}
    missing = sorted((modules | set(DATA)) - names)
    if missing:
        sys.exit(f"{wheel.name} lacks {len(missing)} files: {', '.join(missing[:12])}")
    print(f"{wheel.name}: {len(names)} files, every module of cosim and cosim_plugins and the lab's data")


def main() -> int:
    """Build, install and exercise the wheel outside the tree; 0 when everything held."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--keep", type=Path, default=None, help="work in this folder and keep it")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="cosim-wheel-") as tmp:
        work = (args.keep or Path(tmp)).resolve()
        tree = tracked_copy(work / "src")
        sh(sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "--no-build-isolation", "-w", work / "dist", tree)
        wheel = next((work / "dist").glob("cosim_swimmer-*.whl"))
        check_contents(wheel, tree)
        venv = work / "venv"
        sh(sys.executable, "-m", "venv", "--without-pip", venv)
        python = venv / "bin" / "python"
        site = Path(sh(python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])").strip())
        deps = sysconfig.get_paths()["purelib"]
        (site / "_project_deps.pth").write_text(deps + "\n")
        sh(sys.executable, "-m", "pip", "--python", python, "install", "-q", "--no-deps", "--no-index", wheel)
        elsewhere = work / "elsewhere"
        elsewhere.mkdir()
        (work / "probe.py").write_text(PROBE)
        print(sh(venv / "bin" / "cosim", "scenarios", cwd=elsewhere).splitlines()[0])
        # diagnose's held-out windows need more than one short log: a second seed validates
        for seed, out in ((1, "run"), (2, "held_out")):
            sh(python, work / "probe.py", SRC, deps, "run", "racetrack", "--set", "duration_s=10",
               "--set", f"seed={seed}",
               "--out", out, "--quiet", cwd=elsewhere)
        report = sh(python, work / "probe.py", SRC, deps, "diagnose", "run/log.csv", "--validate", "held_out/log.csv",
                    "--effects", "gradient_force", "--out", "diagnosis", cwd=elsewhere)
        if not (elsewhere / "diagnosis" / "diagnosis.json").is_file():
            sys.exit(f"cosim diagnose wrote no diagnosis.json:\n{report}")
        print(next(line for line in report.splitlines() if line.startswith("verdict:"))[:100] + " ...")
    print("the wheel runs a shipped scenario and a diagnosis outside the tree, importing nothing from it")
    return 0


if __name__ == "__main__":
    sys.exit(main())
