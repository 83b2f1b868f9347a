"""Real-time pacing on a simulated clock: an absolute schedule, late ticks skipped and counted."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from cosim.api import RunRequest, run
from cosim.runtime.pacing import Pacer

TOY = Path(__file__).parent / "data" / "toy.yaml"

class FakeClock:
    """A clock that moves only when told: waiting advances it exactly."""

    def __init__(self):
        self.now = 100.0
        self.stopped = False

    def __call__(self) -> float:
        return self.now

    def wait(self, timeout_s: float) -> bool:
        self.now += timeout_s
        return self.stopped

    def is_set(self) -> bool:
        return self.stopped


def test_ticks_follow_an_absolute_grid_and_a_missed_slot_is_not_made_up():
    clock = FakeClock()
    pacer = Pacer(dt_s=0.02, factor=1.0, n_ticks=8, stop=clock, clock=clock)
    work_s = [0.001, 0.005, 0.025, 0.0, 0.045, 0.0, 0.0, 0.0]  # tick 2 overruns by 5 ms, tick 4 by 25 ms
    starts = []
    for work in work_s:
        assert pacer.wait()
        starts.append(round((clock.now - 100.0) * 1e3, 6))
        clock.now += work
    # tick 3 starts 5 ms late in its own slot (60 ms); tick 4's slot (80 ms) holds;
    # tick 5's slot (100 ms) is gone at 125 ms, as is 120 ms: it waits for 140 ms
    assert starts == [0.0, 20.0, 40.0, 65.0, 80.0, 140.0, 160.0, 180.0]
    summary = pacer.summary()
    assert summary["missed"] == 2 and summary["longest_miss_run"] == 2 and summary["ticks"] == 8
    assert summary["lateness_ms"]["max"] == pytest.approx(5.0)
    assert summary["lateness_ms"]["p50"] == pytest.approx(0.0)


def test_a_stop_ends_the_wait():
    clock = FakeClock()
    pacer = Pacer(dt_s=0.02, factor=2.0, n_ticks=3, stop=clock, clock=clock)
    assert pacer.wait()
    clock.stopped = True
    assert not pacer.wait()


def test_a_paced_run_reports_its_lateness(tmp_path):
    summary = run(RunRequest(TOY, tmp_path, ["duration_s=1"], progress=False, realtime=10.0))
    rt = json.loads((tmp_path / "summary.json").read_text())["realtime"]
    assert rt == summary["realtime"] and rt["factor"] == 10.0
    assert rt["ticks"] == summary["steps"] == 50
    assert set(rt["lateness_ms"]) == {"p50", "p99", "max"} and rt["lateness_ms"]["max"] >= 0
    assert rt["sched_fifo"] is True or rt["sched_fifo"].startswith("not permitted")
