"""`cosim replay` from the command line, up to the viewer: what it refuses and what it tells instead.

(`--web` starts rerun's web server; its address and port handling are tested where they are made.)
"""

from __future__ import annotations

import pytest

from cosim.cli import main


def test_replay_without_a_display_points_to_the_web_viewer(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    (tmp_path / "recording.rrd").write_bytes(b"")
    assert main(["replay", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "no display to open the viewer on" in err and f"cosim replay {tmp_path} --web" in err


@pytest.mark.parametrize("web", [False, True])
def test_replay_of_a_folder_without_a_recording_is_named(tmp_path, capsys, web):
    assert main(["replay", str(tmp_path), *(["--web"] if web else [])]) == 2
    assert f"no recording at {tmp_path / 'recording.rrd'}" in capsys.readouterr().err
