"""Caches of what runs make on demand (a dataset, a trained model, a built FMU): where they live and
their lock.

A cache entry is named by a fingerprint of what made it (see
:func:`cosim.runtime.fingerprint.class_sources` for the code of a plugin
class), so a change of any input makes a new entry rather than reusing a
stale one. Concurrent runs (a sweep's workers) that make the same entry hold
:class:`CacheLock` while they check and write it.
"""

from __future__ import annotations

import fcntl
import os
from pathlib import Path

#: The environment variable naming the cache folder (a sweep's workers inherit the client's).
CACHE_ENV = "COSIM_CACHE"


def cache_dir() -> Path:
    """The cache folder: ``$COSIM_CACHE``, else ``./cache``, as an absolute path."""
    return Path(os.environ.get(CACHE_ENV, "cache")).resolve()


class CacheLock:
    """An exclusive lock on the file ``path`` (made with its folder if need be), held inside a
    ``with`` block, so concurrent processes never delete or half-write each other's cache entry."""

    def __init__(self, path: Path):
        self.path = Path(path)

    def __enter__(self) -> "CacheLock":
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.fh = open(self.path, "w")
        fcntl.flock(self.fh, fcntl.LOCK_EX)
        return self

    def __exit__(self, *exc) -> None:
        fcntl.flock(self.fh, fcntl.LOCK_UN)
        self.fh.close()
