"""Figures of a series computed as it arrives, in memory that does not grow with its length.

* :class:`Moments`: count, mean, standard deviation (population, as ``np.std``) and maximum,
  merged batch by batch (Chan's pairwise update); equal to the figures of the whole series
  up to floating-point rounding (relative ~1e-12).
* :class:`Quantiles`: quantiles of non-negative values from a fixed histogram of
  log-spaced bins, each bin ``RATIO`` = 1.001 times as wide as the one before, from
  ``LOW`` = 1e-9 to ``HIGH`` = 1e9 (in the values' own unit). Stated error: a quantile is
  within a relative ``QUANTILE_REL_ERROR`` = 5e-4 of ``np.percentile``'s (linear
  interpolation) for values in [LOW, HIGH]; values below LOW count as 0 (absolute error
  below LOW), the smallest and largest values are kept exactly. Memory: 41,467 counts
  (330 kB) per series, whatever its length.
"""

from __future__ import annotations

import math

import numpy as np

RATIO = 1.001
LOW, HIGH = 1e-9, 1e9
#: bins between LOW and HIGH; index 0 holds [0, LOW), index N_BINS + 1 holds [HIGH, inf)
N_BINS = math.ceil(math.log(HIGH / LOW) / math.log(RATIO))
#: largest relative error of a quantile of values in [LOW, HIGH] (half a bin, in ratio)
QUANTILE_REL_ERROR = math.sqrt(RATIO) - 1.0


class Moments:
    """Count, mean, spread and maximum of the finite values added so far."""

    __slots__ = ("n", "mean", "m2", "max")

    def __init__(self):
        self.n, self.mean, self.m2, self.max = 0, 0.0, 0.0, -math.inf

    def add(self, values: np.ndarray) -> None:
        """``values``: any shape; NaN and inf are left out."""
        v = np.asarray(values, dtype=float).ravel()
        v = v[np.isfinite(v)]
        if not len(v):
            return
        nb, mb = len(v), float(np.mean(v))
        m2b = float(np.sum((v - mb) ** 2))
        n = self.n + nb
        delta = mb - self.mean
        self.mean += delta * nb / n
        self.m2 += m2b + delta * delta * self.n * nb / n
        self.n = n
        self.max = max(self.max, float(np.max(v)))

    def figures(self) -> dict | None:
        """``{mean, std, max}``, None before any finite value."""
        if not self.n:
            return None
        return {"mean": self.mean, "std": math.sqrt(max(self.m2, 0.0) / self.n), "max": self.max}


class Quantiles:
    """Quantiles of the finite, non-negative values added so far (see the module doc for the error)."""

    __slots__ = ("counts", "n", "min", "max", "what")

    def __init__(self, what: str = "values"):
        self.counts = np.zeros(N_BINS + 2, dtype=np.int64)
        self.n, self.min, self.max, self.what = 0, math.inf, -math.inf, what

    def add(self, values: np.ndarray) -> None:
        """Count the finite ``values`` (any shape) into the histogram."""
        v = np.asarray(values, dtype=float).ravel()
        v = v[np.isfinite(v)]
        if not len(v):
            return
        if v.min() < 0:
            raise ValueError(f"{self.what}: a negative value ({v.min():g}); quantiles are kept of values >= 0")
        index = np.floor(np.log(np.maximum(v, LOW) / LOW) / math.log(RATIO)).astype(np.int64) + 1
        index = np.clip(np.where(v < LOW, 0, index), 0, N_BINS + 1)
        self.counts += np.bincount(index, minlength=N_BINS + 2)
        self.n += len(v)
        self.min, self.max = min(self.min, float(v.min())), max(self.max, float(v.max()))

    def add_one(self, value: float) -> None:
        """One value (cheaper than :meth:`add` of one: for a figure kept tick by tick)."""
        if not math.isfinite(value):
            return
        if value < 0:
            raise ValueError(f"{self.what}: a negative value ({value:g}); quantiles are kept of values >= 0")
        i = 0 if value < LOW else min(int(math.log(value / LOW) / math.log(RATIO)) + 1, N_BINS + 1)
        self.counts[i] += 1
        self.n += 1
        self.min, self.max = min(self.min, value), max(self.max, value)

    def _at_rank(self, cumulative: np.ndarray, rank: int) -> float:
        """The estimated value of the ``rank``-th smallest (0-based)."""
        if rank <= 0:
            return self.min
        if rank >= self.n - 1:
            return self.max
        i = int(np.searchsorted(cumulative, rank, side="right"))
        value = 0.0 if i == 0 else self.max if i == N_BINS + 1 else LOW * RATIO ** (i - 0.5)
        return min(max(value, self.min), self.max)

    def quantile(self, q: float) -> float | None:
        """The ``q`` quantile (0..1), interpolated between ranks as ``np.percentile``; None if empty."""
        if not self.n:
            return None
        cumulative = np.cumsum(self.counts)
        h = (self.n - 1) * q
        lo, hi = math.floor(h), math.ceil(h)
        a = self._at_rank(cumulative, lo)
        b = a if hi == lo else self._at_rank(cumulative, hi)
        return a + (h - lo) * (b - a)
