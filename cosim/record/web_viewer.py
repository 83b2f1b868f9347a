"""``cosim replay --web``: rerun's web viewer serving a run's recording, on loopback unless told otherwise.

The viewer listens on two ports, its page (HTTP) and the data the page reads
(gRPC), both on ``bind`` (127.0.0.1 by default: only this machine; a browser on
another machine reaches it through an SSH tunnel, or ``--bind`` widens it) and
free ports unless one is given for the page. rerun's usage statistics are
turned off for this viewer (a configuration folder of its own, removed
afterwards). The one address to open is printed; the viewer stops with this
command: Ctrl-C, SIGTERM, or the viewer ending by itself.
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

from cosim.contract.errors import UserError

#: How long the viewer has to print where it listens [s].
START_TIMEOUT_S = 60.0
_ADDRESS = re.compile(r"connect at (http://\S+)")
_ANSI = re.compile(r"\x1b\[[0-9;]*m")


def private_config(viewer: str, folder: Path) -> dict[str, str]:
    """The environment for a viewer whose configuration and data folders lie in ``folder``, with its
    usage statistics disabled there (``rerun analytics disable``; the user's own settings untouched)."""
    env = {**os.environ, "XDG_CONFIG_HOME": str(folder / "config"), "XDG_DATA_HOME": str(folder / "data")}
    done = subprocess.run([viewer, "analytics", "disable"], env=env, capture_output=True, text=True, timeout=60)
    if done.returncode != 0:
        raise UserError(f"could not turn rerun's usage statistics off: {done.stderr.strip() or done.stdout.strip()}")
    return env


def serve_web(viewer: str, files: list[str], bind: str = "127.0.0.1", port: int = 0, out=sys.stdout) -> int:
    """Serve ``files`` (.rrd) in the web viewer on ``bind``; print the address to open; return the exit
    status once the viewer has stopped (0 when this command stopped it)."""
    folder = Path(tempfile.mkdtemp(prefix="cosim-viewer-"))
    proc = None
    stopping = threading.Event()
    previous = {}

    def stop(signum, frame):
        stopping.set()
        if proc is not None and proc.poll() is None:
            os.killpg(proc.pid, signal.SIGTERM)

    try:
        env = private_config(viewer, folder)
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGTERM, signal.SIGINT):
                previous[sig] = signal.signal(sig, stop)
        proc = subprocess.Popen([viewer, "--serve-web", "--bind", bind, "--web-viewer-port", str(port), "--port", "0",
                                 *files], env=env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, text=True, start_new_session=True)
        address, said = _wait_for_address(proc)
        if address is None:
            if stopping.is_set():
                return 0
            proc.wait(timeout=10)
            raise UserError("the rerun web viewer did not start: " + (" | ".join(said[-5:]) or "no output"))
        print(f"open {address} in a browser (the viewer listens on {bind}; Ctrl-C stops it)", file=out,
              flush=True)
        threading.Thread(target=lambda: [None for _ in proc.stdout], daemon=True).start()  # drain its log
        code = proc.wait()
        return 0 if stopping.is_set() else code
    finally:
        if proc is not None and proc.poll() is None:
            os.killpg(proc.pid, signal.SIGTERM)
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        shutil.rmtree(folder, ignore_errors=True)


def _wait_for_address(proc: subprocess.Popen) -> tuple[str | None, list[str]]:
    """(the page's address, as the viewer printed it; the lines it printed meanwhile)."""
    said: list[str] = []
    found: list[str] = []

    def read():
        for line in proc.stdout:
            line = _ANSI.sub("", line).strip()
            said.append(line)
            match = _ADDRESS.search(line)
            if match:
                found.append(match[1])
                return

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    reader.join(START_TIMEOUT_S)
    return (found[0] if found else None), said
