"""The raw log's outlier cleaning against hand-computed cases and an independent reference.

The rule (``cosim_plugins.raw_log``): a position is an outlier when it lies
further than ``max(outlier_mm, 6 x 1.4826 x MAD of the residuals)`` from the
per-axis median of the 5 valid samples centred on it (gaps skipped; fewer at
the ends). The reference here is that sentence as a plain loop over rows
with ``statistics.median``.
"""

from __future__ import annotations

import math
import statistics

import numpy as np
import pytest

from cosim_plugins.raw_log import OUTLIER_HALF_WINDOW, OUTLIER_MM, read_log, write_log


def reference_outliers(p_mm: np.ndarray, threshold_mm: float = OUTLIER_MM, h: int = OUTLIER_HALF_WINDOW):
    """(n,) bool: the documented rule, row by row (p_mm (n, 3) [mm], NaN rows are gaps)."""
    valid = [i for i in range(len(p_mm)) if all(math.isfinite(v) for v in p_mm[i])]
    out = np.zeros(len(p_mm), dtype=bool)
    if len(valid) < 2 * h + 1:
        return out
    residual = []
    for j, i in enumerate(valid):
        hood = valid[max(0, j - h): j + h + 1]
        centre = [statistics.median(p_mm[k][a] for k in hood) for a in range(3)]
        residual.append(math.dist(p_mm[i], centre))
    mid = statistics.median(residual)
    mad = statistics.median(abs(r - mid) for r in residual)
    limit = max(threshold_mm, 6 * 1.4826 * mad)
    for i, r in zip(valid, residual):
        out[i] = r > limit
    return out


def _log(tmp_path, p_mm: np.ndarray, name="log.csv", **kw):
    """Write positions (n, 3) [mm] as a raw log (20 ms rows) and read it back cleaned."""
    path = tmp_path / name
    write_log(path, 20.0 * np.arange(len(p_mm)), np.ones((len(p_mm), 3)), p_mm * 1e-3)
    return read_log(path, **kw)


def _line(n: int) -> np.ndarray:
    """A swimmer moving 0.1 mm per row along x, distinct values (no repeats): (n, 3) [mm]."""
    i = np.arange(n, dtype=float)
    return np.column_stack([0.1 * i, 5.0 + 0.01 * i, -3.0 + 0.02 * i])


def test_several_isolated_outliers_and_only_they_are_removed(tmp_path):
    p = _line(40)
    p[5, 0] += 30.0  # a large reflection: a mean of its neighbourhood would move 6 mm and drag its neighbours out
    p[17, 1] -= 4.0
    p[29, 2] += 8.0
    log = _log(tmp_path, p)
    assert np.flatnonzero(log.outlier).tolist() == [5, 17, 29]
    np.testing.assert_array_equal(log.outlier, reference_outliers(p))


def test_two_and_three_adjacent_outliers_are_all_found(tmp_path):
    """A cluster of two within 5 samples still leaves the median on the clean ones."""
    p = _line(40)
    p[[10, 11], 0] += 12.0  # two in a row, the same way
    p[25, 1] += 6.0
    p[26, 1] -= 6.0  # two in a row, opposite ways
    log = _log(tmp_path, p)
    assert np.flatnonzero(log.outlier).tolist() == [10, 11, 25, 26]
    np.testing.assert_array_equal(log.outlier, reference_outliers(p))


def test_the_neighbourhood_skips_gaps(tmp_path):
    """Gaps either side of an outlier: its neighbours are the nearest valid samples, not the NaN rows."""
    p = _line(30)
    p[[13, 14, 16, 17]] = np.nan
    p[15, 2] += 5.0
    log = _log(tmp_path, p)
    assert np.flatnonzero(log.outlier).tolist() == [15]
    assert np.flatnonzero(log.gap).tolist() == [13, 14, 16, 17]


def test_outliers_at_the_ends_are_found(tmp_path):
    p = _line(20)
    p[0, 0] += 9.0
    p[19, 1] -= 9.0
    log = _log(tmp_path, p)
    assert np.flatnonzero(log.outlier).tolist() == [0, 19]


def test_a_jump_just_within_the_threshold_stays(tmp_path):
    """3 mm is the default threshold: 2.9 mm away from the neighbourhood's median stays, 3.1 mm goes."""
    p = np.zeros((20, 3))
    p[:, 0] = 0.001 * np.arange(20)  # 1 um a row: residuals of clean rows are about 0
    p[6, 1] = 2.9
    p[14, 1] = 3.1
    log = _log(tmp_path, p)
    assert np.flatnonzero(log.outlier).tolist() == [14]


def test_a_noisy_log_raises_the_threshold_to_six_robust_sigmas(tmp_path):
    """Noise of 1 mm per axis: a 4 mm jump is within 6 robust sigmas of the residuals, a 25 mm one is not."""
    rng = np.random.default_rng(7)
    p = _line(200) + rng.normal(0.0, 1.0, (200, 3))
    p[50, 0] += 25.0
    expected = reference_outliers(p)
    log = _log(tmp_path, p)
    np.testing.assert_array_equal(log.outlier, expected)
    assert log.outlier[50] and expected.sum() <= 2  # the jump, and at most a noise tail


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_random_logs_with_clusters_match_the_reference(tmp_path, seed):
    rng = np.random.default_rng(seed)
    n = 150
    p = np.cumsum(rng.normal(0.0, 0.05, (n, 3)), axis=0) + rng.normal(0.0, 0.02, (n, 3))
    p[rng.random(n) < 0.05] = np.nan  # gaps
    for start in rng.choice(n - 3, 6, replace=False):  # clusters of 1 to 2 outliers
        width = int(rng.integers(1, 3))
        p[start:start + width, int(rng.integers(0, 3))] += rng.choice([-1, 1]) * rng.uniform(4.0, 20.0)
    log = _log(tmp_path, p, name=f"log{seed}.csv", outlier_mm=3.0)
    p_read = np.where(log.gap[:, None], np.nan, p)
    np.testing.assert_array_equal(log.outlier, reference_outliers(p_read))
    assert log.outlier.sum() >= 4


def _limit(p_mm: np.ndarray) -> float:
    """The rule's threshold [mm] for these positions: max(3 mm, 6 robust sigmas of the residuals)."""
    valid = [i for i in range(len(p_mm)) if all(math.isfinite(v) for v in p_mm[i])]
    residual = []
    for j, i in enumerate(valid):
        hood = valid[max(0, j - 2): j + 3]
        centre = [statistics.median(p_mm[k][a] for k in hood) for a in range(3)]
        residual.append(math.dist(p_mm[i], centre))
    mid = statistics.median(residual)
    return max(OUTLIER_MM, 6 * 1.4826 * statistics.median(abs(r - mid) for r in residual))


@pytest.mark.parametrize("factor, flagged", [(1.15, True), (0.85, False)])
def test_a_jump_just_above_or_below_six_robust_sigmas(tmp_path, factor, flagged):
    rng = np.random.default_rng(11)
    p = _line(300) + rng.normal(0.0, 1.5, (300, 3))
    near = np.sort(p[[148, 149, 151, 152]], axis=0)  # the four neighbours, sorted per axis
    p[150] = (near[1] + near[2]) / 2  # in the middle on every axis: the neighbourhood's median
    limit = _limit(p)
    for _ in range(3):  # residual = x - the neighbours' third x: factor x the threshold it leads to
        p[150, 0] = near[2, 0] + factor * limit
        limit = _limit(p)
    assert limit > OUTLIER_MM + 1  # the noise sets the threshold here, not the 3 mm floor
    log = _log(tmp_path, p)
    assert log.outlier[150] == flagged
    np.testing.assert_array_equal(log.outlier, reference_outliers(p))


@pytest.mark.parametrize("rows, flagged", [(4, []), (5, [2]), (6, [2])])
def test_the_outlier_test_needs_five_valid_samples(tmp_path, rows, flagged):
    p = _line(rows)
    p[2, 0] += 20.0
    assert np.flatnonzero(_log(tmp_path, p).outlier).tolist() == flagged


def test_read_logs_reads_each_with_the_threshold_given(tmp_path):
    from cosim.contract.errors import UserError
    from cosim_plugins.raw_log import read_logs

    p = _line(30)
    p[10, 0] += 4.0  # beyond the 3 mm default, within 5 mm
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    for path in (a, b):
        write_log(path, 20.0 * np.arange(30), np.ones((30, 3)), p * 1e-3)
    logs = read_logs([a, b])
    assert [log.path for log in logs] == [str(a), str(b)] and all(log.outlier[10] for log in logs)
    assert not any(log.outlier.any() for log in read_logs([a, b], outlier_mm=5.0))
    with pytest.raises(UserError) as err:
        read_logs([])
    assert str(err.value) == "no log files given"


def test_the_writer_never_writes_minus_zero(tmp_path):
    path = tmp_path / "z.csv"
    write_log(path, [0.0, 20.0, 40.0], -np.zeros((3, 3)), -np.zeros((3, 3)))
    assert "-0" not in path.read_text()


def _raw(tmp_path, rows, name="edge.csv"):
    path = tmp_path / name
    path.write_text("t_ms,omega_x,omega_y,omega_z,p_x,p_y,p_z\n" + "\n".join(",".join(r) for r in rows) + "\n")
    return path


def _rows(t_ms, x_m=None):
    return [[f"{t:g}", "6.28", "0", "0", f"{(x_m[i] if x_m is not None else 0.001 * i):g}", "0.002", "0.003"]
            for i, t in enumerate(t_ms)]


def test_the_edges_of_the_readers_checks(tmp_path):
    from cosim.contract.errors import UserError

    one_ms = read_log(_raw(tmp_path, _rows(range(10)), "ms.csv"))  # 1 ms steps: still milliseconds
    assert one_ms.n == 10
    metre = read_log(_raw(tmp_path, _rows(range(0, 200, 20), [1.0 - 0.0001 * i for i in range(10)]), "m.csv"))
    assert metre.p_mm[0, 0] == pytest.approx(1000.0)  # |p| = 1 m exactly is metres
    rows = _rows(range(0, 200, 20))
    rows[3][0] = ""
    with pytest.raises(UserError) as err:
        read_log(_raw(tmp_path, rows, "t.csv"))
    assert str(err.value).endswith("line 5: missing or non-finite time")
    rows = _rows([0, 20, 20.5, 40, 60, 50, 80])  # a half-millisecond step first, then one backwards
    with pytest.raises(UserError) as err:
        read_log(_raw(tmp_path, rows, "back.csv"))
    assert str(err.value).endswith("line 7: time is not strictly increasing")


def test_the_quality_reports_the_duration_to_the_millisecond(tmp_path):
    log = read_log(_raw(tmp_path, _rows([1000, 1020, 1040, 1060, 1234.5678]), "q.csv"))
    assert log.quality()["duration_s"] == 0.235


def test_a_row_only_the_line_parser_reads_keeps_every_field_after_an_empty_one(tmp_path):
    """``1_000`` is a number to Python, not to numpy's fast reader: the line-by-line parser reads the
    file, and a row's fields after an empty one are still read."""
    rows = _rows(range(0, 200, 20))
    rows[4][0] = "8_0"  # 80 ms, written with a digit separator
    rows[6][2] = ""  # omega_y missing: the fields after it are still read
    log = read_log(_raw(tmp_path, rows, "slow.csv"))
    assert log.t_s[4] == pytest.approx(0.08) and not log.gap.any()
    assert np.isnan(log.omega_hz[6, 1]) and log.omega_hz[6, 2] == 0.0
    np.testing.assert_allclose(log.p_mm[6], [6.0, 2.0, 3.0], rtol=1e-12)
