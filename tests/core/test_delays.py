"""Delayed edges against a loop computed by hand, in one process and with a process per component.

``data/loop.yaml``: a summer ``y_k = y_(k-1) + u(k - d_u)`` fed by a gain
``u_k = 0.5 (1 - y(k - d_y))``, where ``v(s)`` is the value produced at tick
``s``, or the initial output for ``s < 0``. The reference below is that
recurrence written out, not the other layout: a delay read off by a tick in
both layouts alike still fails here.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cosim.api import RunRequest, run
from cosim.contract.errors import UserError
from cosim.scenario.schema import MAX_DELAY_TICKS, load_scenario

LOOP = Path(__file__).parent / "data" / "loop.yaml"
TICKS = 20  # 0.4 s at 20 ms
Y0, U0, GAIN, REF = 0.25, 0.125, 0.5, 1.0  # the scenario's initial outputs and gain law


def by_hand(d_u: int, d_y: int, ticks: int = TICKS) -> tuple[np.ndarray, np.ndarray]:
    """(y (ticks,), u (ticks,)) of the loop with delays ``d_u`` (gain -> summer) and ``d_y`` (summer -> gain)."""
    y, u = [], []

    def seen(values, initial, stamp):
        return values[stamp] if stamp >= 0 else initial

    for k in range(ticks):
        y.append((y[-1] if y else Y0) + seen(u, U0, k - d_u))
        u.append(GAIN * (REF - seen(y, Y0, k - d_y)))
    return np.array(y), np.array(u)


def run_loop(out, d_u: int, d_y: int, processes: bool) -> tuple[np.ndarray, np.ndarray]:
    overrides = [f"components.summer.inputs.u.delay={d_u}", f"components.gain.inputs.y.delay={d_y}"]
    summary = run(RunRequest(LOOP, out, overrides, processes=processes, progress=False))
    assert summary["status"] == "ok" and summary["steps"] == TICKS
    with np.load(out / "trace.npz") as trace:
        return trace["summer.y"][:, 0], trace["gain.u"][:, 0]


def test_the_reference_is_the_recurrence_it_claims():
    """Spot values worked on paper: no delay on y, one on u."""
    y, u = by_hand(1, 0, ticks=3)
    # k=0: y = 0.25 + 0.125 (initial u) = 0.375, u = 0.5 (1 - 0.375) = 0.3125
    # k=1: y = 0.375 + 0.3125 = 0.6875,          u = 0.15625
    # k=2: y = 0.6875 + 0.15625 = 0.84375,       u = 0.078125
    np.testing.assert_array_equal(y, [0.375, 0.6875, 0.84375])
    np.testing.assert_array_equal(u, [0.3125, 0.15625, 0.078125])
    y3, _ = by_hand(3, 2, ticks=4)  # u's initial value is seen for the first three ticks
    np.testing.assert_array_equal(y3[:3], [0.375, 0.5, 0.625])


@pytest.mark.parametrize("d_y", [0, 1, 2, 3])
@pytest.mark.parametrize("d_u", [1, 2, 3])
def test_one_process_follows_the_hand_computed_loop(tmp_path, d_u, d_y):
    y, u = run_loop(tmp_path, d_u, d_y, processes=False)
    y_ref, u_ref = by_hand(d_u, d_y)
    np.testing.assert_array_equal(y, y_ref)
    np.testing.assert_array_equal(u, u_ref)


@pytest.mark.parametrize("d_u,d_y", [(1, 0), (2, 1), (3, 2), (1, 3)])
def test_a_process_per_component_follows_the_hand_computed_loop(tmp_path, d_u, d_y):
    y, u = run_loop(tmp_path, d_u, d_y, processes=True)
    y_ref, u_ref = by_hand(d_u, d_y)
    np.testing.assert_array_equal(y, y_ref)
    np.testing.assert_array_equal(u, u_ref)


def test_a_delay_beyond_the_limit_is_named():
    with pytest.raises(UserError) as err:
        load_scenario(LOOP, [f"components.gain.inputs.y.delay={MAX_DELAY_TICKS + 1}"])
    assert "delay" in str(err.value) and str(MAX_DELAY_TICKS) in str(err.value)
