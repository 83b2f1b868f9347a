"""What the domain's commands (``cosim fit``, ``compare``, ``diagnose``, ``twin calibrate``) share: progress
lines on stderr and the output folder, checked before any work."""

from __future__ import annotations

import sys
from pathlib import Path

from cosim.contract.errors import UserError


def progress(message: str) -> None:
    """One progress line on stderr (the results go to stdout)."""
    print(f"  .. {message}", file=sys.stderr, flush=True)


def output_folder(path: str | Path) -> Path:
    """``path`` as the ``--out`` folder; a :class:`UserError` when it exists and is not a folder."""
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise UserError(f"--out {out} exists and is not a directory")
    return out
