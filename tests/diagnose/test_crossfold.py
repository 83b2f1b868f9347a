"""A borderline gain tested on every fold of the time blocks (cosim_plugins.diagnose.crossfold)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from cosim.contract.errors import UserError
from cosim_plugins.diagnose.crossfold import CrossFolds
from cosim_plugins.diagnose.stepwise import Fit
from cosim_plugins.diagnose.verdict import MIN_T, blocks_t, gain_block_means

KEY = "1.0"
BLOCKS, PER_BLOCK = 10, 5  # one fold's held-out data: 10 blocks of 5 windows


def _ev(errors_mm: np.ndarray) -> dict:
    """A held-out evaluation whose windows' error sizes are ``errors_mm`` (w,)."""
    err = np.zeros((len(errors_mm), 3))
    err[:, 0] = errors_mm
    return {KEY: {"valid": np.ones(len(errors_mm), dtype=bool), "err": err}}


def _gains(mean_mm: float) -> np.ndarray:
    """(w,) errors of a model whose gain over a 1 mm model is ``mean_mm`` +- 0.3 mm, block by block in turn."""
    per_block = mean_mm + 0.3 * np.resize([1.0, -1.0], BLOCKS)
    return 1.0 - np.repeat(per_block, PER_BLOCK)


class FoldFitter:
    """A fold's fitter: ``refit`` of a model gives the fold's evaluation of it (a table by the model's name)."""

    def __init__(self, table: dict):
        self.table, self.refits = table, []
        self.test_starts, self.block_rows = np.arange(BLOCKS * PER_BLOCK), PER_BLOCK

    def refit(self, jm) -> Fit:
        self.refits.append(jm.name)
        return Fit(jm, _ev(self.table[jm.name]), {})


def _folds(gain_mm: list, too_short: tuple = ()) -> tuple[CrossFolds, list]:
    """CrossFolds over two other folds whose candidate gains ``gain_mm[k]`` on average; fold k in ``too_short``
    cannot be built."""
    fitters = [FoldFitter({"before": np.ones(BLOCKS * PER_BLOCK), "with": _gains(g)}) for g in gain_mm]

    def build(k):
        if k in too_short:
            raise UserError("logs too short to fit")
        return fitters[k]

    return CrossFolds(build, len(gain_mm)), fitters


def _first_fold(gain_mm: float) -> tuple[np.ndarray, Fit, Fit]:
    before = Fit(SimpleNamespace(name="before"), _ev(np.ones(BLOCKS * PER_BLOCK)), {})
    fit = Fit(SimpleNamespace(name="with"), _ev(_gains(gain_mm)), {})
    means = gain_block_means(before.ev[KEY], fit.ev[KEY], np.arange(BLOCKS * PER_BLOCK), PER_BLOCK)
    return means, before, fit


def test_a_gain_on_every_fold_passes_and_one_on_the_first_alone_does_not():
    means, before, fit = _first_fold(0.2)
    t_first = blocks_t(means)
    assert 1.7 <= t_first < MIN_T  # borderline on its own fold (10 blocks)
    folds, fitters = _folds([0.2, 0.2])
    t_all, used = folds.t_stat(means, before, fit, KEY)
    assert used == 3 and t_all >= MIN_T and t_all > 1.4 * t_first  # 30 blocks: about sqrt(3) x
    # the same first fold, nothing gained on the others: the t falls
    spurious, _ = _folds([0.0, 0.0])
    t_spurious, _ = spurious.t_stat(means, before, fit, KEY)
    assert t_spurious < t_first
    # a round compares every candidate with the same model before: each fold refits it once
    folds.t_stat(means, before, fit, KEY)
    assert [f.refits.count("before") for f in fitters] == [1, 1]


def test_a_fold_too_short_is_left_out():
    means, before, fit = _first_fold(0.2)
    folds, fitters = _folds([0.2, 0.2], too_short=(1,))
    t_all, used = folds.t_stat(means, before, fit, KEY)
    fold0 = 1.0 - fitters[0].table["with"][::PER_BLOCK]  # fold 0's block means (its model before: 1 mm)
    assert used == 2 and t_all == pytest.approx(blocks_t(np.concatenate([means, fold0])))
    assert fitters[1].refits == []


@pytest.mark.parametrize("entry,asked", [
    ({"identifiable": True, "reduction": 0.36, "t_stat": 2.1}, True),
    ({"identifiable": True, "reduction": 0.36, "t_stat": 3.4}, False),  # passes alone
    ({"identifiable": True, "reduction": 0.15, "t_stat": 1.2}, False),  # too weak for three folds to lift
    ({"identifiable": True, "reduction": 0.43, "t_stat": 1.6}, True),  # a large drop in few blocks (a step-out)
    ({"identifiable": True, "reduction": 0.43, "t_stat": 0.8}, False),
    ({"identifiable": True, "reduction": 0.05, "t_stat": 2.5}, False),  # a drop too small to name
    ({"identifiable": False, "reduction": 0.36, "t_stat": 2.5}, False),
])
def test_only_a_borderline_t_asks_the_other_folds(entry, asked):
    assert CrossFolds(lambda k: None, 2).wanted(entry) is asked
