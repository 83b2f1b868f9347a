"""Endpoints of a one-machine run that no other user of the machine can reach.

``cosim run --processes`` links its scheduler and nodes over unix sockets in a
folder of its own, created mode 0700 by the user who runs it (so no other user
can even look up a socket in it; the sockets themselves are not writable by
others either) and removed when the run ends. There is no TCP listener at all: a
process of another user can neither connect nor read nor publish a sample.
Processes of the same user are trusted as the user is (they could read the run's
files and attach a debugger anyway).

zenoh names such an endpoint ``unixsock-stream/PATH``; PATH must stay under the
operating system's limit for a socket path (108 bytes on Linux), so the folder
lies in the system's temporary folder, with a short name.
"""

from __future__ import annotations

import os
import shutil
import stat
import tempfile
from pathlib import Path

from cosim.contract.errors import UserError

SCHEME = "unixsock-stream/"
#: The longest socket path Linux accepts (sun_path is 108 bytes with its terminating NUL).
MAX_SOCKET_PATH = 107


class PrivateEndpoints:
    """A 0700 folder of unix-socket endpoints, one per :meth:`endpoint` call; use as a context
    manager (the folder and its sockets are removed on exit)."""

    def __init__(self, parent: str | Path | None = None):
        self.folder = Path(tempfile.mkdtemp(prefix="cosim-bus-", dir=parent))  # mkdtemp: mode 0700
        mode = stat.S_IMODE(os.stat(self.folder).st_mode)
        if mode != 0o700:
            raise UserError(f"the run's bus folder {self.folder} has mode {mode:o}, not 700")
        self._count = 0

    def endpoint(self, name: str | None = None) -> str:
        """A new ``unixsock-stream/…`` endpoint in the folder (``name``: a label for the socket file)."""
        self._count += 1
        label = "".join(c for c in (name or "node") if c.isalnum() or c in "-_")[:24] or "node"
        path = self.folder / f"{self._count}-{label}.sock"
        if len(str(path)) > MAX_SOCKET_PATH:
            raise UserError(f"the socket path {path} is longer than {MAX_SOCKET_PATH} bytes: set TMPDIR to a "
                            "shorter folder")
        return f"{SCHEME}{path}"

    def close(self) -> None:
        shutil.rmtree(self.folder, ignore_errors=True)

    def __enter__(self) -> "PrivateEndpoints":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def is_private(endpoint: str) -> bool:
    """Whether ``endpoint`` is a unix socket (reachable only through the file system's permissions)."""
    return endpoint.startswith(SCHEME)
