"""Real-time pacing: ticks on an absolute wall-clock schedule, late ticks counted.

With ``factor`` F, tick slots start every ``dt_s / F`` seconds of wall time
from the first tick (F = 1: real time; 2: twice as fast). Slots are on an
absolute grid, so waiting never drifts. A tick that starts late within its
own slot starts at once (its lateness is recorded); one whose slot has
already passed is not made up: it waits for the next slot boundary and the
slots skipped are counted as missed (the skip policy of hardware-in-the-loop
runs). A stop request wakes a waiting pacer at once.

The loop's thread asks for ``SCHED_FIFO`` (a real-time priority) when the
process may have it (root or ``CAP_SYS_NICE``); whether it got it, and why
not, goes to the summary.
"""

from __future__ import annotations

import math
import os
import threading
import time

from cosim.record.streaming import Quantiles

#: priority asked for under SCHED_FIFO (1-99; low: above every normal thread, below the kernel's own)
FIFO_PRIORITY = 10


class Pacer:
    """Waits for each tick's slot; keeps lateness and misses.

    ``n_ticks``: ticks the run will take (None: until stopped); lateness is kept as a histogram
    (:class:`~cosim.record.streaming.Quantiles`, relative error <= 5e-4), so memory does not grow
    with the run; ``stop``: set to end a wait at once; ``clock``: seconds, monotonic.
    """

    def __init__(self, dt_s: float, factor: float, n_ticks: int | None, stop: threading.Event,
                 clock=time.perf_counter):
        if not factor > 0:
            raise ValueError(f"real-time factor must be > 0, got {factor}")
        self.factor, self.period_s, self.stop, self.clock = factor, dt_s / factor, stop, clock
        self.lateness_ms = Quantiles("tick lateness [ms]")
        self._latest_s = 0.0
        self.ticks = 0
        self.missed = 0
        self.longest_miss_run = 0
        self.sched_fifo: str | bool = False
        self._t0 = None
        self._slot = 0

    def realtime_priority(self) -> None:
        """Ask for SCHED_FIFO for the calling thread; records the outcome."""
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(FIFO_PRIORITY))
            self.sched_fifo = True
        except (AttributeError, PermissionError, OSError) as exc:
            self.sched_fifo = f"not permitted ({getattr(exc, 'strerror', None) or exc}); normal scheduling"

    def wait(self) -> bool:
        """Wait for the next tick's slot; False when a stop was requested meanwhile."""
        now = self.clock()
        if self._t0 is None:
            self._t0 = now
        target = self._t0 + self._slot * self.period_s
        if now - target >= self.period_s:  # its slot is gone: skip to the next boundary
            skipped = math.ceil((now - target) / self.period_s)
            self.missed += skipped
            self.longest_miss_run = max(self.longest_miss_run, skipped)
            self._slot += skipped
            target = self._t0 + self._slot * self.period_s
        if target > now and self.stop.wait(target - now):
            return False
        self._latest_s = max(self.clock() - target, 0.0)
        self.lateness_ms.add_one(self._latest_s * 1e3)
        self.ticks += 1
        self._slot += 1
        return not self.stop.is_set()

    def latest_ms(self) -> float:
        return self._latest_s * 1e3 if self.ticks else 0.0

    def summary(self) -> dict:
        """The ``realtime`` entry of ``summary.json``."""
        late = self.lateness_ms
        pct = (lambda q: round(late.quantile(q / 100), 3)) if late.n else (lambda q: None)
        return {
            "factor": self.factor,
            "ticks": self.ticks,
            "missed": self.missed,
            "longest_miss_run": self.longest_miss_run,
            "lateness_ms": {"p50": pct(50), "p99": pct(99),
                            "max": round(late.max, 3) if late.n else None},
            "sched_fifo": self.sched_fifo,
        }
