"""compare: errors of a model on a hand-written log, checked against hand-computed numbers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosim_plugins.identify.compare import compare, format_table
from cosim_plugins.identify.dataset import Dataset
from cosim_plugins.identify.model import Model
from cosim_plugins.raw_log import HEADER

# Positions in mm (the file holds metres); row 4 has no measurement.
POSITIONS_MM = [(0, 0, 0), (1, 0, 0), (2, 1, 0), (3, 1, 1), None, (5, 2, 1), (6, 2, 2), (7, 3, 2),
                (8, 3, 3), (9, 4, 3), (10, 4, 4), (11, 5, 4), (12, 5, 5)]


class ConstantVelocity(Model):
    """x_next = [p + dt v, v]: predictions easy to do by hand."""

    name = "cv-test"
    dt_s = 0.02

    def _step(self, x, u):
        return np.concatenate([x[:, :3] + self.dt_s * x[:, 3:], x[:, 3:]], axis=1)

    @property
    def n_params(self):
        return 0


@pytest.fixture
def tiny_dataset(tmp_path):
    lines = [HEADER]
    for i, p in enumerate(POSITIONS_MM):
        pos = ",".join(f"{c / 1000:g}" for c in p) if p else ",,"
        lines.append(f"{20 * i},0,0,6.283185307,{pos}")
    path = tmp_path / "tiny.csv"
    path.write_text("\n".join(lines) + "\n")
    return Dataset.from_paths([path])


def test_pairs_and_windows_skip_the_gap(tiny_dataset):
    ds = tiny_dataset
    # states need P_i and P_{i-1}: rows 1-3 and 6-12; pairs need states i and i+1
    assert ds.pair_index().tolist() == [1, 2, 6, 7, 8, 9, 10, 11]
    assert ds.window_index(5).tolist() == [6, 7]
    np.testing.assert_allclose(ds.x[2], [2, 1, 0, 50, 50, 0])  # V = (P_2 - P_1) / 20 ms


def test_compare_matches_hand_computed_errors(tiny_dataset):
    result = compare({"cv": ConstantVelocity()}, tiny_dataset)
    r = result["models"]["cv"]
    # One step, P_hat_{i+1} = 2 P_i - P_{i-1}:
    #   i=1: (2,0,0) vs (2,1,0): |e| = 1;   i=2: (3,2,0) vs (3,1,1): |e| = sqrt 2
    #   i=6..11: the step alternates (1,0,1) / (1,1,0), error (0,+-1,-+1): sqrt 2 each (6 pairs)
    assert r["n_pairs"] == 8
    assert r["one_step_mm"]["x"] == pytest.approx(0.0, abs=1e-9)
    assert r["one_step_mm"]["y"] == pytest.approx(8 / 8)
    assert r["one_step_mm"]["z"] == pytest.approx(7 / 8)
    assert r["one_step_mm"]["norm"] == pytest.approx((1 + 7 * math.sqrt(2)) / 8)
    # 0.1 s = 5 steps from i = 6 and 7: P_i + 5 (P_i - P_{i-1}) vs P_{i+5}: errors (0,-3,3), (0,3,-3)
    assert r["rollout_mm"]["0.1"] == pytest.approx(3 * math.sqrt(2))
    assert r["rollout_detail"]["0.1"]["windows"] == 2
    assert r["rollout_detail"]["0.1"]["y"] == pytest.approx(3.0)
    # no gap-free window is 21 or 50 steps long
    assert list(r["rollout_mm"]) == ["0.1", "0.42", "1.0"]
    assert r["rollout_mm"]["0.42"] is None and r["rollout_mm"]["1.0"] is None
    assert "cv" in format_table(result)
