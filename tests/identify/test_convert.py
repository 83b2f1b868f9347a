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


# ---------------------------------------------------------------- units and period, against hand-computed values


def _convert(tmp_path, capsys, positions_rows, *args, header="t_s,x,y,z"):
    """Commands at 0, 0.05, 0.1 s (1, 2, 3 Hz about z); the given detections; ``cosim convert`` with ``args``."""
    cmd = _write(tmp_path / "cmd.csv", "t_s,axis_x,axis_y,axis_z,freq_hz",
                 [[0.0, 0, 0, 1, 1.0], [0.05, 0, 0, 1, 2.0], [0.1, 0, 0, 1, 3.0]])
    pos = _write(tmp_path / "pos.csv", header, positions_rows)
    out = tmp_path / "log.csv"
    code = main(["convert", "--commands", str(cmd), "--positions", str(pos), "--out", str(out), *args])
    return code, out, capsys.readouterr()


@pytest.mark.parametrize("args, written_m", [
    (["--unit", "mm"], (0.1, 0.2, -0.3)),  # 100 mm = 0.1 m
    (["--unit", "m"], (100.0, 200.0, -300.0)),  # but no swimmer is 100 m away: see the next test
    (["--unit", "px", "--pixel-mm", "0.19"], (0.019, 0.038, -0.057)),  # 100 px x 0.19 mm = 19 mm
    (["--unit", "px", "--pixel-mm", "2.5"], (0.25, 0.5, -0.75)),
], ids=["mm", "m", "px 0.19", "px 2.5"])
def test_position_units_give_metres_in_the_raw_log(tmp_path, capsys, args, written_m):
    code, out, _ = _convert(tmp_path, capsys, [[0.0, 100.0, 200.0, -300.0]], *args)
    assert code == 0
    row = out.read_text().splitlines()[1].split(",")
    np.testing.assert_allclose([float(v) for v in row[4:7]], written_m, rtol=1e-9)


def test_pixels_read_back_in_mm(tmp_path, capsys):
    """40 px of 0.19 mm: 7.6 mm in the cleaned log, on every axis's own scale."""
    rows = [[0.02 * i, 40.0 + i, -20.0, 10.0 * i] for i in range(6)]
    code, out, _ = _convert(tmp_path, capsys, rows, "--unit", "px", "--pixel-mm", "0.19")
    assert code == 0
    log = read_log(out)
    expected = np.array([[0.19 * (40.0 + i), 0.19 * -20.0, 0.19 * 10.0 * i] for i in range(6)])
    np.testing.assert_allclose(log.p_mm, expected, rtol=1e-9)


def test_the_period_sets_the_grid_and_the_held_commands(tmp_path, capsys):
    """--dt 0.03 over commands at 0, 0.05, 0.1 s: rows at 0, 30, 60, 90 ms holding 1, 1, 2, 2 Hz;
    a detection at 31 ms is within half a period (15 ms) of the 30 ms row only."""
    code, out, printed = _convert(tmp_path, capsys, [[0.031, 1.0, 2.0, 3.0]], "--dt", "0.03")
    assert code == 0
    log = read_log(out)
    np.testing.assert_allclose(log.t_s, [0.0, 0.03, 0.06, 0.09], atol=1e-12)
    np.testing.assert_allclose(log.omega_hz[:, 2], [1.0, 1.0, 2.0, 2.0], rtol=1e-8)  # as written: 10 digits
    np.testing.assert_allclose(log.omega_hz[:, :2], 0.0, atol=1e-12)
    assert np.isnan(log.p_mm[[0, 2, 3]]).all()
    np.testing.assert_allclose(log.p_mm[1], [1.0, 2.0, 3.0], rtol=1e-9)
    assert "4 rows of 30 ms" in printed.out


def test_the_default_period_is_20_ms(tmp_path, capsys):
    code, out, printed = _convert(tmp_path, capsys, [[0.0, 1.0, 2.0, 3.0]])
    assert code == 0 and read_log(out).n == 6  # 0..100 ms
    assert "6 rows of 20 ms" in printed.out


@pytest.mark.parametrize("args, message", [
    (["--unit", "px"], "positions in px need --pixel-mm"),
    (["--unit", "px", "--pixel-mm", "0"], "positions in px need --pixel-mm"),
    (["--unit", "px", "--pixel-mm", "-0.19"], "positions in px need --pixel-mm"),
    (["--dt", "0"], "--dt 0: the control period must be positive"),
    (["--dt", "-0.02"], "--dt -0.02: the control period must be positive"),
])
def test_bad_units_and_periods_are_named(tmp_path, capsys, args, message):
    code, out, printed = _convert(tmp_path, capsys, [[0.0, 1.0, 2.0, 3.0]], *args)
    assert code == 2 and message in printed.err, printed.err
    assert not out.exists()


def _files(tmp_path, cmd_rows, pos_rows, cmd_header="t_s,omega_x,omega_y,omega_z", pos_header="t_s,x,y,z"):
    return (_write(tmp_path / "c.csv", cmd_header, cmd_rows), _write(tmp_path / "p.csv", pos_header, pos_rows))


def test_a_recording_that_starts_late_gives_a_log_from_zero(tmp_path, capsys):
    """Commands from t = 100 s: the log's time starts at 0 and spans the commands (100..100.1 s: 6 rows)."""
    cmd, pos = _files(tmp_path, [[100.0, 0, 0, 6.0], [100.06, 0, 0, 12.0], [100.1, 0, 0, 18.0]],
                      [[100.04, 1.0, 2.0, 3.0]])
    out = tmp_path / "log.csv"
    assert main(["convert", "--commands", str(cmd), "--positions", str(pos), "--out", str(out)]) == 0
    log = read_log(out)
    np.testing.assert_allclose(log.t_s, [0.0, 0.02, 0.04, 0.06, 0.08, 0.1], atol=1e-12)
    np.testing.assert_allclose(log.omega_hz[:, 2] * 2 * np.pi, [6.0, 6.0, 6.0, 12.0, 12.0, 18.0], rtol=1e-8)
    np.testing.assert_allclose(log.p_mm[2], [1.0, 2.0, 3.0], rtol=1e-9)


def test_a_command_just_after_a_row_is_not_yet_held(tmp_path, capsys):
    cmd, pos = _files(tmp_path, [[0.0, 0, 0, 6.0], [0.04 + 1e-8, 0, 0, 12.0], [0.1, 0, 0, 18.0]],
                      [[0.0, 1.0, 2.0, 3.0]])
    out = tmp_path / "log.csv"
    assert main(["convert", "--commands", str(cmd), "--positions", str(pos), "--out", str(out)]) == 0
    np.testing.assert_allclose(read_log(out).omega_hz[:4, 2] * 2 * np.pi, [6.0, 6.0, 6.0, 12.0], rtol=1e-8)


def test_of_two_detections_equally_near_the_earlier_is_taken_and_half_a_period_is_near(tmp_path, capsys):
    """dt = 0.25 s (exact in binary), detections at 0.125 and 0.375 s: each is exactly half a period from
    two rows."""
    cmd, pos = _files(tmp_path, [[0.0, 0, 0, 6.0], [0.5, 0, 0, 6.0]],
                      [[0.125, 1.0, 0.0, 0.0], [0.375, 2.0, 0.0, 0.0]])
    out = tmp_path / "log.csv"
    assert main(["convert", "--commands", str(cmd), "--positions", str(pos), "--out", str(out), "--dt", "0.25"]) == 0
    rows = [line.split(",") for line in out.read_text().splitlines()[1:]]  # as written (read_log would
    p_x_mm = [float(r[4]) * 1e3 for r in rows]  # drop the repeated row as a lost detection)
    assert p_x_mm == pytest.approx([1.0, 1.0, 2.0])  # 0 s: exactly half a period away, kept; 0.25 s: a tie,
    # the earlier detection; 0.5 s: the later one


@pytest.mark.parametrize("which, header, rows, message", [
    ("positions", "t_s,x,y,z", [[0.0, 1, 2, 3], [np.nan, 1, 2, 3], [np.nan, 1, 2, 3]],
     "line 3: empty or non-numeric time"),
    ("positions", "t_s,x,y", [[0.0, 1, 2]], "positions need columns x,y,z (header: t_s,x,y)"),
    ("positions", "time,x,y,z", [[0.0, 1, 2, 3]], "no time column: name it t_s or t_ms (header: time,x,y,z)"),
])
def test_bad_position_files_are_named_with_the_line(tmp_path, capsys, which, header, rows, message):
    cmd, pos = _files(tmp_path, [[0.0, 0, 0, 6.0], [0.1, 0, 0, 6.0]], rows, pos_header=header)
    assert main(["convert", "--commands", str(cmd), "--positions", str(pos), "--out", str(tmp_path / "o.csv")]) == 2
    err = capsys.readouterr().err
    assert f"{pos}: " in err or f"{pos} line" in err, err
    assert message in err, err


def test_the_summary_counts_rows_measured_detections_and_those_outside(tmp_path, capsys):
    """Commands over 1..1.1 s (t0 = 1 s); detections at 0.5 s and 1.2 s lie outside [0.99, 1.11] s, the one
    at 0.995 s and 1.04 s are inside and each gives a row its position."""
    cmd, pos = _files(tmp_path, [[1.0, 0, 0, 6.0], [1.05, 0, 0, 6.0], [1.1, 0, 0, 6.0]],
                      [[0.5, 1, 0, 0], [0.995, 2, 0, 0], [1.04, 3, 0, 0], [1.2, 4, 0, 0]])
    out = tmp_path / "sub" / "dir" / "log.csv"  # folders made as needed
    assert main(["convert", "--commands", str(cmd), "--positions", str(pos), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert printed.strip() == (f"wrote {out}: 6 rows of 20 ms (0.1 s), 2 with a position from 4 detections; "
                               "2 detections lie outside the commands' time span and were left out")


# ---------------------------------------------------------------- each refusal's words in full


def _refused(tmp_path, capsys, cmd_text=None, pos_text="t_s,x,y,z\n0,1,2,3\n", *args):
    """The message `cosim convert` ends with (exit 2) on these files' texts; a None command text: no file."""
    cmd, pos = tmp_path / "c.csv", tmp_path / "p.csv"
    if cmd_text is not None:
        cmd.write_text(cmd_text)
    pos.write_text(pos_text)
    code = main(["convert", "--commands", str(cmd), "--positions", str(pos), "--out", str(tmp_path / "o.csv"), *args])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and err, err
    return err[-1].replace(str(tmp_path), "DIR")


@pytest.mark.parametrize("cmd_text, message", [
    (None, "DIR/c.csv: no such file"),
    ("", "DIR/c.csv: empty file"),
    ("t_s,omega_x,omega_y,omega_z\n", "DIR/c.csv: no data rows"),
    ("t_s,omega_x,omega_y,omega_z\n\n  \n", "DIR/c.csv: no data rows"),  # blank lines are no rows
    ("t_s,omega_x,omega_y,omega_z\n0,1,2,3\n0.1,1,two,3\n", "DIR/c.csv line 3: not a number in '0.1,1,two,3'"),
    # the third row goes back: its line (4) and its time are named, not its neighbour's
    ("t_s,omega_x,omega_y,omega_z\n0,1,2,3\n0.2,1,2,3\n0.1,1,2,3\n0.3,1,2,3\n",
     "DIR/c.csv line 4: time 0.1 s does not increase"),
])
def test_each_refusal_of_a_commands_file_in_full(tmp_path, capsys, cmd_text, message):
    assert _refused(tmp_path, capsys, cmd_text).endswith(message)


def test_blank_lines_between_rows_are_skipped_not_the_end(tmp_path, capsys):
    """A blank line after the first row: the rows after it are still read (the log spans 0..0.1 s)."""
    cmd = tmp_path / "c.csv"
    cmd.write_text("t_s,omega_x,omega_y,omega_z\n0,0,0,6\n\n0.1,0,0,6\n")
    pos = _write(tmp_path / "p.csv", "t_s,x,y,z", [[0.0, 1.0, 2.0, 3.0]])
    assert main(["convert", "--commands", str(cmd), "--positions", str(pos), "--out", str(tmp_path / "o.csv")]) == 0
    assert read_log(tmp_path / "o.csv").n == 6


def test_the_pixel_size_and_unit_refusals_in_full(tmp_path, capsys):
    from cosim.contract.errors import UserError
    from cosim_plugins.identify.convert import read_positions

    cmd_text = "t_s,omega_x,omega_y,omega_z\n0,0,0,6\n0.1,0,0,6\n"
    assert _refused(tmp_path, capsys, cmd_text, "t_s,x,y,z\n0,1,2,3\n", "--unit", "px").endswith(
        "positions in px need --pixel-mm (the size of one pixel in the tank, e.g. 0.19)")
    with pytest.raises(UserError) as err:
        read_positions(_write(tmp_path / "p2.csv", "t_s,x,y,z", [[0.0, 1.0, 2.0, 3.0]]), "inch")
    assert str(err.value) == "position unit 'inch': use mm, m or px"


def test_a_command_at_a_row_within_the_rounding_slack_is_held_from_that_row():
    """The grid's rows are compared with the commands' times 1e-9 periods late, so a command that rounding put a
    hair after a row (exactly that slack here) is held from that row, not from the next."""
    from cosim_plugins.identify.convert import to_raw_log

    dt = 0.02
    late = 0.04 + 1e-9 * dt  # the third row's time and the slack, as the grid computes them
    cmd_t = np.array([0.0, late, 0.1])
    omega = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 2.0], [0.0, 0.0, 3.0]])
    _, held, _ = to_raw_log(cmd_t, omega, np.array([0.0]), np.zeros((1, 3)), dt)
    np.testing.assert_array_equal(held[:, 2], [1.0, 1.0, 2.0, 2.0, 2.0, 3.0])


@pytest.mark.parametrize("cmd_text, message", [
    # a zero axis with a spin frequency of exactly 1 Hz is refused like any other frequency
    ("t_s,axis_x,axis_y,axis_z,freq_hz\n0,0,0,1,2\n0.1,0,0,0,1\n",
     "DIR/c.csv line 3: a spin frequency with a zero rotation axis"),
    ("t_s,wx,wy,wz\n0,1,2,3\n", "DIR/c.csv: commands need omega_x,omega_y,omega_z [rad/s] or axis_x,axis_y,axis_z,"
                                "freq_hz (header: t_s,wx,wy,wz)"),
    # the first command with a missing field is named by its own line
    ("t_s,omega_x,omega_y,omega_z\n0,1,2,3\n0.1,1,2,3\n0.2,1,,3\n0.3,1,2,\n",
     "DIR/c.csv line 4: a command must be given in full (empty or NaN field)"),
])
def test_each_refusal_of_a_commands_content_in_full(tmp_path, capsys, cmd_text, message):
    assert _refused(tmp_path, capsys, cmd_text).endswith(message)


def test_a_zero_axis_at_zero_frequency_is_no_spin_and_the_axis_sets_the_direction(tmp_path):
    from cosim_plugins.identify.convert import read_commands

    cmd = tmp_path / "c.csv"
    cmd.write_text("t_s,axis_x,axis_y,axis_z,freq_hz\n0,0,0,0,0\n0.1,0,3,4,2\n")
    t, omega = read_commands(cmd)
    np.testing.assert_array_equal(t, [0.0, 0.1])
    np.testing.assert_allclose(omega, [[0.0, 0.0, 0.0], [0.0, 4 * np.pi * 0.6, 4 * np.pi * 0.8]], rtol=1e-12)


def test_convert_reads_millimetres_unless_told(tmp_path):
    from cosim_plugins.identify.convert import convert

    cmd, pos = _files(tmp_path, [[0.0, 0, 0, 6.0], [0.1, 0, 0, 6.0]], [[0.0, 100.0, 200.0, -300.0]])
    convert(cmd, pos, tmp_path / "log.csv", 0.02)
    np.testing.assert_allclose(read_log(tmp_path / "log.csv").p_mm[0], [100.0, 200.0, -300.0], rtol=1e-9)


@pytest.mark.parametrize("dt, t_ms", [
    ("0.0125", ["0", "12.5", "25", "37.5"]),  # a period of a fraction of a millisecond: written as it is
    ("0.0250001", ["0", "25.0001", "50.0002", "75.0003"]),  # 0.1 us a row off whole milliseconds: kept
    ("0.0200000001", ["0", "20", "40", "60"]),  # 0.1 ns a row: whole milliseconds (within 1 ns)
])
def test_times_off_whole_milliseconds_are_written_as_they_are(tmp_path, capsys, dt, t_ms):
    code, out, _ = _convert(tmp_path, capsys, [[0.0, 1.0, 2.0, 3.0]], "--dt", dt)
    assert code == 0
    assert [line.split(",")[0] for line in out.read_text().splitlines()[1:5]] == t_ms


def test_detections_outside_the_commands_span_are_counted_to_half_a_period(tmp_path):
    """Commands at 1, 1.5 and 2 s, dt = 0.25 s (exact in binary): the span with half a period either side is
    [0.875, 2.125] s. Of detections at 0.6, 0.875, 0.9, 1.9, 2.125 and 2.3 s, the first and the last lie outside;
    the edges themselves are inside. Rows at 1 and 2 s have one within half a period (0.9 and 1.9 s)."""
    from cosim_plugins.identify.convert import convert

    cmd, pos = _files(tmp_path, [[1.0, 0, 0, 6.0], [1.5, 0, 0, 6.0], [2.0, 0, 0, 6.0]],
                      [[t, 1.0, 0.0, 0.0] for t in (0.6, 0.875, 0.9, 1.9, 2.125, 2.3)])
    counts = convert(cmd, pos, tmp_path / "log.csv", 0.25)
    assert counts == {"rows": 5, "measured": 2, "detections": 6, "outside": 2, "duration_s": 1.0}
