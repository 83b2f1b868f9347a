"""A borderline gain tested on every fold of the time blocks (cross-fitting).

The held-out data are every third 5 s block of each log (:func:`.pipeline.split_logs`). On short logs that is
few 1 s blocks for the verdict's paired t: the 31 s of seed 67's multi_008 (a camera latency of 2.4 frames beside
a uniform flow) give 10, and the latency, given the flow, removed 36 % of the error at t = 2.1 while its drop and
its share of the excess over the noise floor passed. Such a candidate, and only such (drop >=
:data:`~.verdict.MIN_REDUCTION`, identifiable, :data:`CROSS_T_FROM` <= t < :data:`~.verdict.MIN_T`; from a
lower t for a large drop, below), is tested on the other two folds as well: the model before it and the model
with it are both refitted on each fold's training blocks (from their own solutions, every parameter free) and
compared on that fold's held-out blocks.
Every block of the logs is then held out once; the t of the block means of all three folds is the candidate's
t. A spurious gain does not come back on the other folds, and its t falls; a real one's grows about as the
square root of the blocks (that latency: t = 4.4 over the three folds). The drop stays the first fold's.

A large drop (>= :data:`LARGE_DROP`) is asked from a lower t (:data:`CROSS_T_FROM_LARGE`): an effect that acts
in few blocks has heavy-tailed block gains, and one fold's t swings with how many of those blocks it holds. Seed
118's multi_003 (a step-out at 15.5 Hz, the top of the spin-rate band, beside a quadratic drag): given the drag,
the step-out removed 43 % of the error at t = 1.6 on the first fold, and the backward check dropped it; over the
three folds it passes.

Each fold's refits of one model are remembered (a round compares every candidate with the same model before).
"""

from __future__ import annotations

import copy
from typing import Callable

import numpy as np

from cosim.contract.errors import UserError
from cosim_plugins.diagnose.stepwise import Fit
from cosim_plugins.diagnose.verdict import MIN_REDUCTION, MIN_T, blocks_t, gain_block_means

CROSS_T_FROM = 1.7  # a fold's t from which the other folds are asked too (sqrt(3) x 1.7 ~ MIN_T)
LARGE_DROP = 0.30  # a drop of this share of the error or more is asked from CROSS_T_FROM_LARGE
CROSS_T_FROM_LARGE = 1.0


class CrossFolds:
    """The other folds of a time-block split: ``build(k)`` makes the :class:`~.fitting.Fitter` of fold ``k``
    (0 .. ``n`` - 1) or raises UserError when that fold's data are too short (the fold is then left out)."""

    def __init__(self, build: Callable, n: int):
        self._build, self.n = build, n
        self._fitters: dict = {}
        self._refits: dict = {}  # {(fold, id(model)): (model, Fit)}: the model kept alive with its refit

    def wanted(self, entry: dict) -> bool:
        """True when ``entry`` (a rank entry of the first fold) is short of the verdict's t alone."""
        t_from = CROSS_T_FROM_LARGE if entry["reduction"] >= LARGE_DROP else CROSS_T_FROM
        return (entry["identifiable"] and entry["reduction"] >= MIN_REDUCTION
                and t_from <= entry["t_stat"] < MIN_T)

    def t_stat(self, first_means: np.ndarray, before: Fit, fit: Fit, key: str) -> tuple[float, int]:
        """(t of the gain of ``fit`` over ``before`` at horizon ``key`` on the held-out blocks of every fold,
        folds used): ``first_means`` (blocks,) the first fold's block means, then each other fold's."""
        means, used = [first_means], 1
        for k in range(self.n):
            fitter = self._fitter(k)
            if fitter is None:
                continue
            b, a = self._refit(k, fitter, before), self._refit(k, fitter, fit)
            means.append(gain_block_means(b.ev[key], a.ev[key], fitter.test_starts, fitter.block_rows))
            used += 1
        return blocks_t(np.concatenate(means)), used

    def _fitter(self, k: int):
        if k not in self._fitters:
            try:
                self._fitters[k] = self._build(k)
            except UserError:  # this fold's training or held-out blocks are too short: it is left out
                self._fitters[k] = None
        return self._fitters[k]

    def _refit(self, k: int, fitter, fit: Fit) -> Fit:
        key = (k, id(fit.model))
        if key not in self._refits:
            self._refits[key] = (fit.model, fitter.refit(copy.deepcopy(fit.model)))
        return self._refits[key][1]
