"""The README's first commands, run as written on the built environment.

The lines of the README's opening ``make`` block (but ``make test``, which is
this suite) and of its "First steps" block run in bash, in a folder that
links to this checkout's files (its own ``runs/``), with no display: each
must succeed, except ``cosim replay``, which must say how to look without one.
"""

from __future__ import annotations

import os
import re
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _blocks(text: str) -> list[list[str]]:
    """The command lines (comments stripped) of each ```sh block."""
    out = []
    for body in re.findall(r"```sh\n(.*?)```", text, flags=re.S):
        lines = [re.sub(r"\s+#.*$", "", line).strip() for line in body.splitlines()]
        out.append([line for line in lines if line and not line.startswith("#")])
    return out


def test_first_commands_work_as_typed(tmp_path):
    readme = (ROOT / "README.md").read_text()
    blocks = _blocks(readme)
    assert blocks[0] == ["make demo", "make test"]
    first_steps = _blocks(readme.split("### First steps", 1)[1])[0]
    for item in ROOT.iterdir():  # a checkout of its own, sharing the built venv and FMU
        if item.name not in ("runs", ".git"):
            (tmp_path / item.name).symlink_to(item)
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY", "VIRTUAL_ENV")}
    env["PATH"] = "/usr/bin:/bin"  # nothing of this interpreter's venv: the lines must set it up themselves
    lines = ["make demo", *first_steps]
    script = "\n".join(f"{line}\necho \"== {i} exit $?\"" for i, line in enumerate(lines))
    done = subprocess.run(["bash", "-c", script], cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=600)
    out = done.stdout + done.stderr
    codes = {int(i): int(c) for i, c in re.findall(r"== (\d+) exit (\d+)", done.stdout)}
    assert len(codes) == len(lines), out
    for i, line in enumerate(lines):
        if line.startswith("cosim replay"):
            assert codes[i] == 2 and "--web" in out and "rerun rrd stats" in out, out
        else:
            assert codes[i] == 0, f"{line!r} failed:\n{out}"
    assert "recording:" in out and (tmp_path / "runs" / "demo" / "recording.rrd").is_file()
    assert (tmp_path / "runs" / "frames_100ms" / "summary.json").is_file()
