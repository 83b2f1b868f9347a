"""Build the plant FMU (``swimmer_plant.fmu``) from the C sources the package ships
(``cosim_plugins/plant/swimmer_plant``).

``build_fmu(out)`` compiles the sources with gcc into
``binaries/<platform>/swimmer_plant.so`` and zips it with ``modelDescription.xml``.
``ensure_fmu()`` returns the FMU the plant runs: ``$COSIM_FMU`` if set, else the one
built from these sources into the user cache dir (``~/.cache/cosim-swimmer/``, one file
per content of the sources, so checkouts and installs of different versions never
rebuild each other's), built on first use. Command line (what ``make fmu`` runs)::

    python -m cosim_plugins.plant.build              # the cached FMU (built if missing); prints its path
    python -m cosim_plugins.plant.build --out X.fmu  # (re)build into X.fmu

The FMI 2.0 headers are the ones shipped with fmpy (``fmpy/c-code``).
"""

from __future__ import annotations

import argparse
import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

from cosim.contract.errors import UserError
from cosim_plugins.resources import package_path, user_cache_dir

MODEL_IDENTIFIER = "swimmer_plant"
SOURCE_DIR = package_path("plant", MODEL_IDENTIFIER)
ENV_FMU = "COSIM_FMU"
CFLAGS = ["-O2", "-shared", "-fPIC", "-fvisibility=hidden", "-std=c99", "-D_DEFAULT_SOURCE"]


class FmuBuildError(UserError):
    """The plant FMU could not be built (no C compiler, or the compile failed)."""


def source_files() -> list[Path]:
    """Every file the FMU is built from (C sources, headers, modelDescription.xml)."""
    return sorted(
        p for p in SOURCE_DIR.iterdir() if p.suffix in {".c", ".h", ".xml"} and p.is_file()
    )


def sources_digest() -> str:
    """A short hash of the sources' names and contents (what the cached FMU is keyed by)."""
    h = hashlib.sha256()
    for src in source_files():
        h.update(src.name.encode() + b"\0" + src.read_bytes())
    return h.hexdigest()[:12]


def default_fmu() -> Path:
    """The cached FMU of these sources: ``<user cache>/fmu/swimmer_plant-<digest>.fmu``."""
    return user_cache_dir() / "fmu" / f"{MODEL_IDENTIFIER}-{sources_digest()}.fmu"


def find_compiler() -> str:
    """Path of gcc (or cc); raises :class:`FmuBuildError` saying what to install."""
    for name in ("gcc", "cc"):
        found = shutil.which(name)
        if found:
            return found
    raise FmuBuildError(
        "cannot build the plant FMU: no C compiler found (looked for 'gcc' and 'cc' on PATH); "
        "install one, e.g. 'apt-get install gcc', or point COSIM_FMU at a prebuilt swimmer_plant.fmu"
    )


def _fmi_headers() -> Path:
    import fmpy

    return Path(fmpy.__file__).resolve().parent / "c-code"


def _platform() -> tuple[str, str]:
    import fmpy

    return fmpy.platform, fmpy.sharedLibraryExtension


def build_fmu(out_path: str | os.PathLike) -> Path:
    """Compile the C sources and write the FMU to ``out_path``; returns its path.

    The archive is written to a temporary file and moved into place, so a
    concurrent reader never sees a half-written FMU.
    """
    out = Path(out_path).resolve()
    compiler = find_compiler()
    platform, ext = _platform()
    c_files = [str(p) for p in source_files() if p.suffix == ".c"]
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="swimmer_fmu_") as tmp:
        lib = Path(tmp) / f"{MODEL_IDENTIFIER}{ext}"
        cmd = [compiler, *CFLAGS, f"-I{SOURCE_DIR}", f"-I{_fmi_headers()}", *c_files, "-lm", "-o", str(lib)]
        result = subprocess.run(cmd, capture_output=True, text=True)
        if result.returncode != 0:
            raise FmuBuildError(
                f"compiling the plant FMU failed ({Path(compiler).name} exit status {result.returncode}); "
                f"make sure a working C compiler is installed ('apt-get install gcc'). "
                f"Compiler output:\n{result.stderr.strip()}"
            )
        staging = out.with_name(f".{out.name}.{os.getpid()}.tmp")
        with zipfile.ZipFile(staging, "w", zipfile.ZIP_DEFLATED) as zf:
            zf.write(SOURCE_DIR / "modelDescription.xml", "modelDescription.xml")
            zf.write(lib, f"binaries/{platform}/{MODEL_IDENTIFIER}{ext}")
        os.replace(staging, out)
    return out


def _is_stale(fmu: Path) -> bool:
    if not fmu.exists():
        return True
    built = fmu.stat().st_mtime
    return any(src.stat().st_mtime > built for src in source_files())


def cached_fmu() -> Path:
    """:func:`default_fmu`, built first if missing."""
    fmu = default_fmu()
    if not fmu.is_file():
        build_fmu(fmu)
    return fmu.resolve()


def ensure_fmu(path: str | os.PathLike | None = None) -> Path:
    """An up-to-date plant FMU.

    With ``path=None``: the FMU named by the environment variable ``COSIM_FMU``
    if set (used as is, never rebuilt), else :func:`default_fmu`, built if missing.
    A given ``path`` is (re)built when missing or older than any source file.
    """
    if path is None:
        env = os.environ.get(ENV_FMU)
        if env:
            fmu = Path(env)
            if not fmu.is_file():
                raise FmuBuildError(f"{ENV_FMU}={env} does not name an existing FMU file")
            return fmu.resolve()
        return cached_fmu()
    fmu = Path(path)
    if _is_stale(fmu):
        build_fmu(fmu)
    return fmu.resolve()


def main(argv: list[str] | None = None) -> int:
    """The command line: build the FMU (``--out``) or ensure the cached one; prints its path."""
    parser = argparse.ArgumentParser(description="Build the swimmer plant FMU.")
    parser.add_argument("--out", default=None,
                        help="build into this .fmu file (default: the user cache's, built only if missing)")
    args = parser.parse_args(argv)
    try:
        print(build_fmu(args.out) if args.out else cached_fmu())
    except FmuBuildError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
