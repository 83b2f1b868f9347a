"""A step's outputs as published: one row of float64 in the declared order, and outputs that do not
match the declared ports refused with their name."""

from __future__ import annotations

import re

import numpy as np
import pytest

from cosim.contract.component import ComponentError, Port
from cosim.runtime import bus
from cosim.runtime.portcache import PortStore
from cosim.runtime.stepper import Stepper


class _Wiring:
    periods = {"c": 1}
    outputs = {"c": [Port("v", (3,), "m"), Port("s", (), "Hz"), Port("m", (2, 2), "1")]}

    def edges_into(self, name):
        return []


class _Component:
    fault = None


@pytest.fixture
def stepper():
    session = bus.open_session()
    yield Stepper("c", _Component(), session, "r1", _Wiring(), PortStore(_Wiring.outputs), 1.0)
    session.close()


def test_outputs_are_laid_end_to_end_in_the_declared_order_whatever_their_types(stepper):
    stepper._publish(0, {"m": [[5, 6], [7, 8]], "s": 4.0, "v": np.array([1, 2, 3])})  # ints, a list, a float
    stepper._publish(1, {"m": np.arange(5.0, 9.0).reshape(2, 2), "s": np.float64(4.0), "v": [1.0, 2.0, 3.0]})
    (row,) = stepper.last_outputs
    assert row.dtype == np.float64 and row.tolist() == [1, 2, 3, 4, 5, 6, 7, 8]


@pytest.mark.parametrize("outputs, message", [
    ({"v": 1.0, "s": 4.0, "m": np.zeros((2, 2))}, "output 'v' has shape (), declared (3,)"),
    ({"v": np.zeros(3), "s": np.zeros(1), "m": np.zeros((2, 2))}, "output 's' has shape (1,), declared ()"),
    ({"v": np.zeros(3), "s": 4.0, "m": np.zeros(4)}, "output 'm' has shape (4,), declared (2, 2)"),
    ({"v": np.zeros(3), "s": 4.0}, "returned ports ['s', 'v'], expected ['m', 's', 'v']"),
])
def test_outputs_off_the_declared_ports_are_refused_by_name(stepper, outputs, message):
    with pytest.raises(ComponentError, match=re.escape(message)):
        stepper._publish(0, outputs)
