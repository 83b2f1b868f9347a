"""`cosim convert`: a lab's command and detection recordings onto the raw log's control grid."""

from __future__ import annotations

import numpy as np
import pytest

from cosim.cli import main
from cosim_plugins.raw_log import read_log


def _write(path, header, rows):
    path.write_text(header + "\n" + "\n".join(",".join("" if np.isnan(v) else f"{v:.9g}" for v in r) for r in rows)
                    + "\n")
    return path


def test_commands_are_held_and_each_row_takes_the_nearest_frame(tmp_path, capsys):
    """Commands at 25 Hz (axis + frequency), detections at 30 frames/s in mm with frames lost: a 20 ms log whose
    omega is the last command before each row and whose position is the frame within 10 ms of it."""
    rng = np.random.default_rng(4)
    cmd_t = np.arange(0.0, 4.0 + 1e-9, 0.04)
    axis = rng.normal(size=(len(cmd_t), 3))
    freq = rng.uniform(2.0, 12.0, len(cmd_t))
    cmd = _write(tmp_path / "cmd.csv", "t_s,axis_x,axis_y,axis_z,freq_hz", np.column_stack([cmd_t, axis, freq]))
    frame_t = 0.005 + np.arange(0.0, 4.0, 1 / 30)
    truth_mm = np.column_stack([10 * np.sin(frame_t), 5 * np.cos(frame_t), frame_t])
    lost = rng.random(len(frame_t)) < 0.1
    pos_rows = np.column_stack([frame_t * 1e3, np.where(lost[:, None], np.nan, truth_mm)])
    pos = _write(tmp_path / "pos.csv", "t_ms,x,y,z", pos_rows)
    out = tmp_path / "log.csv"
    assert main(["convert", "--commands", str(cmd), "--positions", str(pos), "--out", str(out)]) == 0
    log = read_log(out)
    assert log.n == 201 and np.allclose(np.diff(log.t_s), 0.02)
    grid = np.arange(201) * 0.02
    held = np.searchsorted(cmd_t, grid + 1e-12, side="right") - 1
    expected_hz = freq[held, None] * axis[held] / np.linalg.norm(axis[held], axis=1, keepdims=True)
    np.testing.assert_allclose(log.omega_hz, expected_hz, rtol=1e-7)
    kept_t, kept_mm = frame_t[~lost], truth_mm[~lost]
    for i, t in enumerate(grid):
        k = int(np.argmin(np.abs(kept_t - t)))
        if abs(kept_t[k] - t) > 0.01:
            assert np.isnan(log.p_mm[i]).all(), i
        else:
            np.testing.assert_allclose(log.p_mm[i], kept_mm[k], atol=1e-6)
    printed = capsys.readouterr().out
    assert f"wrote {out}: 201 rows of 20 ms" in printed


@pytest.mark.parametrize("header, rows, message", [
    ("time,omega_x,omega_y,omega_z", [[0, 1, 2, 3]], "no time column: name it t_s or t_ms"),
    ("t_s,omega_x,omega_y,omega_z", [[0, 1, 2, 3], [0, 1, 2, 3]], "line 3: time 0 s does not increase"),
    ("t_s,omega_x,omega_y,omega_z", [[0, 1, 2, 3], [0.1, 1, 2]], "line 3: 3 fields, the header has 4"),
    ("t_s,wx,wy,wz", [[0, 1, 2, 3]], "commands need omega_x,omega_y,omega_z"),
    ("t_s,axis_x,axis_y,axis_z,freq_hz", [[0, 0, 0, 0, 5]], "line 2: a spin frequency with a zero rotation axis"),
])
def test_bad_command_files_are_named_with_the_line(tmp_path, capsys, header, rows, message):
    cmd = tmp_path / "cmd.csv"
    cmd.write_text(header + "\n" + "\n".join(",".join(map(str, r)) for r in rows) + "\n")
    pos = _write(tmp_path / "pos.csv", "t_s,x,y,z", [[0.0, 1.0, 2.0, 3.0]])
    assert main(["convert", "--commands", str(cmd), "--positions", str(pos), "--out", str(tmp_path / "o.csv")]) == 2
    err = capsys.readouterr().err
    assert str(cmd) in err and message in err, err
