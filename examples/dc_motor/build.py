"""Build the DC motor FMU from ``dc_motor_fmu.py`` with pythonfmu, cached by the hash of its sources.

``ensure_fmu()`` returns ``build/dc_motor-<hash>.fmu`` beside this file (git
ignores ``build/``), building it only when no FMU of the current sources is
there. The hash covers the model's source and the pythonfmu version that
exports it, so editing the model or upgrading pythonfmu rebuilds, and nothing
else does. pythonfmu runs in a child process (it imports the model and edits
``sys.path`` while it builds) and the FMU is moved into place whole, so a
concurrent reader never sees half an archive; older builds are removed.

pythonfmu is needed only to build: the FMU carries the model and pythonfmu's
Python part, and runs in the interpreter that loads it (its binary finds the
interpreter's ``libpython`` already loaded in the process).

    python examples/dc_motor/build.py      # prints the FMU's path (what `make example` runs first)
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import tempfile
from importlib import metadata
from pathlib import Path

HERE = Path(__file__).resolve().parent
SOURCE = HERE / "dc_motor_fmu.py"
BUILD_DIR = HERE / "build"
MODEL_IDENTIFIER = "DcMotor"  # the class name in SOURCE: pythonfmu names the FMU's binary after it
PREFIX = "dc_motor-"


class FmuBuildError(RuntimeError):
    """pythonfmu is missing or failed to export the model."""


def pythonfmu_version() -> str | None:
    """The installed pythonfmu's version, or None when it is not installed."""
    try:
        return metadata.version("pythonfmu")
    except metadata.PackageNotFoundError:
        return None


def source_hash() -> str:
    """First 16 hex digits of the SHA-256 of the model source and the pythonfmu version."""
    digest = hashlib.sha256(SOURCE.read_bytes())
    digest.update(f"\npythonfmu {pythonfmu_version()}".encode())
    return digest.hexdigest()[:16]


def fmu_path() -> Path:
    """Where the FMU of the current sources is (or will be) cached."""
    return BUILD_DIR / f"{PREFIX}{source_hash()}.fmu"


def build_fmu(out: Path) -> Path:
    """Export ``SOURCE`` with pythonfmu into ``out`` (written whole, then moved into place)."""
    if pythonfmu_version() is None:
        raise FmuBuildError("building the DC motor FMU needs pythonfmu: pip install pythonfmu==0.7.0 "
                            "(or pip install -e '.[test]')")
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="dc_motor_fmu_") as tmp:
        cmd = [sys.executable, "-m", "pythonfmu", "build", "--file", str(SOURCE), "--dest", tmp]
        done = subprocess.run(cmd, capture_output=True, text=True, cwd=tmp)
        built = Path(tmp) / f"{MODEL_IDENTIFIER}.fmu"
        if done.returncode != 0 or not built.is_file():
            raise FmuBuildError(f"pythonfmu failed to build {SOURCE.name} (exit status {done.returncode}):\n"
                                f"{(done.stderr or done.stdout).strip()}")
        staging = out.with_name(f".{out.name}.{os.getpid()}.tmp")
        staging.write_bytes(built.read_bytes())  # the temporary folder may be on another file system
        os.replace(staging, out)
    return out


def ensure_fmu() -> Path:
    """The FMU of the current sources, built on first use; older builds in ``BUILD_DIR`` are removed."""
    out = fmu_path()
    if not out.is_file():
        build_fmu(out)
        for old in BUILD_DIR.glob(f"{PREFIX}*.fmu"):
            if old != out:
                old.unlink(missing_ok=True)
    return out


if __name__ == "__main__":
    try:
        print(ensure_fmu())
    except FmuBuildError as exc:
        print(f"error: {exc}", file=sys.stderr)
        sys.exit(2)
