"""The raw log reader and writer (cosim_plugins.raw_log)."""

from __future__ import annotations

import numpy as np
import pytest

from cosim.contract.errors import UserError
from cosim_plugins.raw_log import HEADER, read_log, write_log


def _rows(n=10, p_scale=1e-3):
    """n clean rows: 20 ms steps, 1 Hz command, a slow ramp in metres."""
    lines = [HEADER]
    for i in range(n):
        lines.append(f"{20 * i},6.283185307,0,0,{(10 + i) * p_scale},{2 * p_scale},{-3 * p_scale}")
    return lines


def _write(tmp_path, lines, name="log.csv"):
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n")
    return path


def test_reads_and_converts_units(tmp_path):
    log = read_log(_write(tmp_path, _rows()))
    assert log.n == 10
    np.testing.assert_allclose(log.t_s[:3], [0.0, 0.02, 0.04])
    np.testing.assert_allclose(log.omega_hz[0], [1.0, 0.0, 0.0], rtol=1e-9)
    np.testing.assert_allclose(log.p_mm[0], [10.0, 2.0, -3.0])
    assert log.dt_s == pytest.approx(0.02)
    assert log.quality() == {"file": str(tmp_path / "log.csv"), "rows": 10, "gaps": 0, "outliers": 0,
                             "repeats": 0, "duration_s": 0.18}


@pytest.mark.parametrize(
    "mutate, message",
    [
        (lambda L: ["time,wx,wy,wz,x,y,z"] + L[1:], "wrong header 'time,wx,wy,wz,x,y,z'"),
        (lambda L: L[:3], "too few rows (2); need at least 3"),
        (lambda L: [L[0]] + _rows(10, p_scale=1.0)[1:], "positions look like mm (max |p| = 19"),
        (lambda L: L[:5] + ["80,6.28,0,0,0.01,abc,0.0"] + L[6:], "line 6: non-numeric value 'abc' in column p_y"),
        (lambda L: L[:4] + ["60,6.28,0,0,0.01"] + L[5:], "line 5: expected 7 comma-separated fields, got 5"),
        (lambda L: [L[0]] + [",".join(r.split(",")[:4] + ["", "", ""]) for r in L[1:]],
         "column p_x has no values (all empty/NaN)"),
        (lambda L: L[:3] + [L[2]] + L[4:], "line 4: time is not strictly increasing"),
        (lambda L: [""], "empty file"),
    ],
    ids=["header", "few-rows", "mm-in-m", "garbage", "fields", "all-nan", "time", "empty"],
)
def test_bad_input_names_file_and_problem(tmp_path, mutate, message):
    path = _write(tmp_path, mutate(_rows()))
    with pytest.raises(UserError) as exc:
        read_log(path)
    assert str(path) in str(exc.value)
    assert message in str(exc.value)


def test_missing_file(tmp_path):
    with pytest.raises(UserError, match="no such file"):
        read_log(tmp_path / "nope.csv")


def test_time_in_seconds_is_rejected(tmp_path):
    lines = [HEADER] + [f"{0.02 * i},0,0,0,0.01,0,0" for i in range(5)]
    with pytest.raises(UserError, match="look like seconds"):
        read_log(_write(tmp_path, lines))


def test_gaps_outliers_repeats_are_counted_and_removed(tmp_path):
    rng = np.random.default_rng(0)
    n = 60
    t = 20.0 * np.arange(n)
    p = np.column_stack([np.linspace(0, 0.02, n), np.full(n, 0.005), np.zeros(n)])
    p += 1e-5 * rng.standard_normal(p.shape)  # 0.01 mm noise: no accidental repeats
    p[[10, 30]] = np.nan  # gaps
    p[20, 0] += 0.008  # 8 mm reflection
    p[40] = p[39]  # lost detection: exact repeat
    p[45, 1] = np.nan  # one empty field is a gap too
    path = tmp_path / "defects.csv"
    write_log(path, t, np.ones((n, 3)), p)
    log = read_log(path)
    q = log.quality()
    assert (q["gaps"], q["outliers"], q["repeats"]) == (3, 1, 1)
    assert log.outlier[20] and log.repeat[40] and log.gap[[10, 30, 45]].all()
    assert np.isnan(log.p_mm[[10, 20, 30, 40, 45]]).all()
    assert np.isfinite(log.p_mm[~(log.gap | log.outlier | log.repeat)]).all()


def test_writer_format_and_round_trip(tmp_path):
    t = np.array([0.0, 20.0, 40.0])
    w = np.array([[1.0, -2.5, 3.14159265358979], [0, 0, 0], [1e-7, 2e5, -1]])
    p = np.array([[0.0123456789012, -0.02, 0.0], [np.nan, np.nan, np.nan], [0.001, np.nan, 0.002]])
    path = tmp_path / "w.csv"
    write_log(path, t, w, p)
    lines = path.read_text().splitlines()
    assert lines[0] == HEADER
    assert lines[1] == "0,1,-2.5,3.14159265,0.0123456789,-0.02,0"
    assert lines[2] == "20,0,0,0,,,"
    assert lines[3] == "40,1e-07,200000,-1,0.001,,0.002"
    w2 = np.array([[0.3, 0.1, 0.2]] * 3)
    p2 = np.array([[0.01234567891, 0.0, -0.03]] * 3) + np.arange(3)[:, None] * 1e-3
    write_log(path, [0, 20, 40], w2, p2)
    log = read_log(path)
    np.testing.assert_allclose(log.p_mm * 1e-3, p2, rtol=1e-8)
    np.testing.assert_allclose(log.omega_hz * 2 * np.pi, w2, rtol=1e-8)


def test_writer_non_integer_times(tmp_path):
    path = tmp_path / "t.csv"
    write_log(path, [0.5, 20.25, 1234567.125], np.zeros((3, 3)), np.zeros((3, 3)))
    assert [ln.split(",")[0] for ln in path.read_text().splitlines()[1:]] == ["0.5", "20.25", "1234567.125"]
