"""The raw log's text: what a lab's hand-edited or exported file may look like, and what the writer puts down.

A raw log of the paper's length is read by numpy's C parser; the line-by-line parser is the
fallback that names a bad line, about 30x slower. These tests pin which files take which path,
the header variants the reader accepts (a byte-order mark, spaces), trailing blank lines, the
outlier rule's strict inequality, and the writer's times written exactly (epoch milliseconds).
"""

from __future__ import annotations

import numpy as np
import pytest

import cosim_plugins.raw_log as raw_log
from cosim.contract.errors import UserError
from cosim_plugins.raw_log import HEADER, LogWriter, read_log


def _text(rows: list[str], header: str = HEADER, tail: str = "\n") -> str:
    return header + "\n" + "\n".join(rows) + tail


def _rows(n: int = 8) -> list[str]:
    return [f"{20 * i},6.283185307,0,0,{0.001 * (10 + i):.6f},0.002,-0.003" for i in range(n)]


@pytest.fixture
def no_line_parser(monkeypatch):
    """The line-by-line parser made to fail the test: the file must be read by the fast one."""
    def refuse(body, path):
        raise AssertionError(f"{path}: read line by line")

    monkeypatch.setattr(raw_log, "_parse_slow", refuse)


def test_empty_fields_anywhere_are_read_by_the_fast_parser_as_nan(tmp_path, no_line_parser):
    rows = _rows()
    rows[2] = "40,6.283185307,0,0,,,"  # no position: three empty fields, the line ending in a comma
    rows[4] = "80,,,0,0.014,0.002,-0.003"  # two empty fields in a row mid-line
    rows[7] = "140,6.283185307,0,0,0.017,0.002,"  # the last line ends with an empty field
    path = tmp_path / "gaps.csv"
    path.write_text(_text(rows, tail=""))  # no newline after the last field
    log = read_log(path)
    assert log.n == 8
    assert log.gap.tolist() == [False, False, True, False, False, False, False, True]
    assert np.isnan(log.omega_hz[4, :2]).all() and log.omega_hz[4, 2] == 0.0
    np.testing.assert_allclose(log.p_mm[4], [14.0, 2.0, -3.0], rtol=1e-12)
    np.testing.assert_allclose(log.t_s, 0.02 * np.arange(8), rtol=1e-12)


def test_both_parsers_return_the_same_array(tmp_path):
    rows = _rows(6)
    rows[1] = "20,6.283185307,0,0,,,"
    text = _text(rows)
    fast = raw_log._parse(text, tmp_path / "x.csv")
    slow = raw_log._parse_slow(text.splitlines()[1:], tmp_path / "x.csv")
    assert fast.shape == (6, 7)
    np.testing.assert_array_equal(fast, slow)


@pytest.mark.parametrize("header", ["\ufeff" + HEADER, HEADER.replace(",", ", "), " " + HEADER + " "],
                         ids=["byte-order-mark", "spaces", "padded"])
def test_header_variants_a_spreadsheet_writes_are_accepted(tmp_path, header):
    path = tmp_path / "h.csv"
    path.write_text(_text(_rows(), header=header), encoding="utf-8")
    log = read_log(path)
    assert log.n == 8 and log.p_mm[0, 0] == pytest.approx(10.0)


@pytest.mark.parametrize("tail", ["\n\n", "\n\n\n", "\n \n"], ids=["one", "two", "spaces"])
def test_trailing_blank_lines_are_not_rows(tmp_path, tail, no_line_parser):
    path = tmp_path / "t.csv"
    path.write_text(_text(_rows(), tail=tail))
    assert read_log(path).n == 8


def test_a_file_that_is_not_text_is_refused_by_name(tmp_path):
    path = tmp_path / "binary.csv"
    path.write_bytes(HEADER.encode() + b"\n\xff\xfe\x00\x81")
    with pytest.raises(UserError, match=r"binary\.csv: cannot read: .*codec can't decode"):
        read_log(path)


def test_a_jump_exactly_at_the_threshold_stays(tmp_path):
    """The rule is "further than the threshold": a residual equal to it is no outlier."""
    p_m = np.zeros((9, 3))
    p_m[:, 1] = 1e-6 * np.arange(1, 10)  # y creeps 1 um a row: no repeats, a robust sigma far below 3 mm
    p_m[4, 0] = 0.003  # x jumps 3 mm at the middle row, all else on the line
    path = tmp_path / "edge.csv"
    raw_log.write_log(path, 20.0 * np.arange(9), np.ones((9, 3)), p_m)
    jump_mm = float(np.float64(0.003) * 1e3)  # the reader's mm of the written value
    assert not read_log(path, outlier_mm=jump_mm).outlier.any()
    below = read_log(path, outlier_mm=np.nextafter(jump_mm, 0.0))
    assert below.outlier.tolist() == [False] * 4 + [True] + [False] * 4


def test_epoch_millisecond_times_are_written_exactly(tmp_path):
    """A rig stamping rows in Unix milliseconds (13 digits) gets them back to the millisecond."""
    t_ms = 1_732_560_000_123 + 20 * np.arange(4)
    path = tmp_path / "epoch.csv"
    with LogWriter(path) as log:
        log.append(t_ms, np.zeros((4, 3)), np.zeros((4, 3)))
    times = [line.split(",")[0] for line in path.read_text().splitlines()[1:]]
    assert times == [str(t) for t in t_ms]


def test_fractional_times_keep_twelve_digits(tmp_path):
    path = tmp_path / "frac.csv"
    with LogWriter(path) as log:
        log.append([0.5, 20.25, 1234567.125], np.zeros((3, 3)), np.zeros((3, 3)))
    times = [line.split(",")[0] for line in path.read_text().splitlines()[1:]]
    assert times == ["0.5", "20.25", "1234567.125"]
