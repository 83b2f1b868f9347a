"""A step's outputs as published: one row of float64 in the declared order, and outputs that do not
match the declared ports refused with their name; a step's inputs read over delayed edges from the rows
of producers with other periods, reshaped to their ports; a missing input named, a fault raised after
the step's outputs went out, and closing reporting only a fault set while closing. In-process: the
node layout (``--processes``) runs this same class."""

from __future__ import annotations

import re
import time

import numpy as np
import pytest
import zenoh

from cosim.contract.component import ComponentError, ComponentFault, Port
from cosim.contract.errors import PortTimeout
from cosim.runtime import bus
from cosim.runtime.portcache import PortCache, PortStore
from cosim.runtime.stepper import Stepper
from cosim.runtime.wiring import Edge, Wiring


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
    (row,) = stepper.last_outputs
    assert row.dtype == np.float64 and row.tolist() == [1, 2, 3, 4, 5, 6, 7, 8]
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


# --- a consumer's inputs, gathered for a tick over delayed edges, and what a step publishes ---------------

#: p (every 2nd tick): a vector, a scalar, a 2x2 matrix; q (every tick): a pair; c reads four of them
#: over delays 1, 0, 0 and 3 and publishes y; scope reads q and publishes nothing
OUTPUTS = {"p": (Port("v", (3,), "m"), Port("s", (), "Hz"), Port("m", (2, 2), "1")),
           "q": (Port("w", (2,), "V"),), "c": (Port("y", (2,), "1"),), "scope": ()}
EDGES = [Edge("p", "v", "c", "a", 1), Edge("p", "m", "c", "b", 0), Edge("p", "s", "c", "e", 0),
         Edge("q", "w", "c", "x", 3), Edge("q", "w", "scope", "w", 0)]
WIRING = Wiring({}, {}, OUTPUTS, EDGES, ["p", "q", "c", "scope"], {"p": 2, "q": 1, "c": 1, "scope": 1})


def p_row(stamp: int) -> np.ndarray:
    """p's row (8,) produced at ``stamp``: 10 * stamp + 0..7, so a value names its tick and place."""
    return 10.0 * stamp + np.arange(8.0)


def q_row(stamp: int) -> np.ndarray:
    return np.array([stamp, 0.5 + stamp])


class _Consumer:
    """Keeps the inputs of each step; outputs ``y = [t, tick]`` (two floats); ``fault_at``: a tick it faults at;
    ``close_fault``: the fault it sets while closing."""

    def __init__(self, fault_at=None, close_fault=None):
        self.fault, self.seen, self.fault_at, self.close_fault = None, [], fault_at, close_fault

    def initial_outputs(self):
        return {"y": np.array([-1.0, -1.0])}

    def step(self, t, inputs):
        self.seen.append({k: np.array(v) for k, v in inputs.items()})
        tick = round(t / 0.02)
        if tick == self.fault_at:
            self.fault = f"too hot at tick {tick}"
        return {"y": np.array([t, float(tick)])}

    def close(self):
        if self.close_fault:
            self.fault = self.close_fault


@pytest.fixture
def session():
    s = bus.open_session()  # in-process peer, nothing leaves the process
    yield s
    s.close()


def filled_store() -> PortStore:
    """p's rows at -1, 0, 2, 4 and q's at -1 to 5, as the bus would have left them."""
    store = PortStore(OUTPUTS, keep=8)
    for stamp in (-1, 0, 2, 4):
        store.store("p", stamp, p_row(stamp))
    for stamp in range(-1, 6):
        store.store("q", stamp, q_row(stamp))
    return store


@pytest.mark.parametrize("tick, p_v, p_m, q_w", [
    # tick: p.v over delay 1, p.m and p.s over delay 0 (p steps every 2nd tick), q.w over delay 3
    (0, -1, 0, -1), (1, 0, 0, -1), (2, 0, 2, -1), (3, 2, 2, 0), (4, 2, 4, 1), (5, 4, 4, 2),
])
def test_a_step_gets_each_input_from_the_row_its_edge_reads(session, tick, p_v, p_m, q_w):
    consumer = _Consumer()
    stepper = Stepper("c", consumer, session, "r1", WIRING, filled_store(), 1.0)
    stepper.step(tick, tick * 0.02)
    (seen,) = consumer.seen
    assert sorted(seen) == ["a", "b", "e", "x"]
    assert seen["a"].shape == (3,) and seen["a"].tolist() == p_row(p_v)[0:3].tolist()
    assert seen["e"].shape == () and float(seen["e"]) == p_row(p_m)[3]
    assert seen["b"].shape == (2, 2) and seen["b"].tolist() == p_row(p_m)[4:8].reshape(2, 2).tolist()
    assert seen["x"].shape == (2,) and seen["x"].tolist() == q_row(q_w).tolist()


def test_a_missing_input_names_the_producer_its_port_and_the_tick(session):
    stepper = Stepper("c", _Consumer(), session, "r1", WIRING, filled_store(), 1.0)
    with pytest.raises(PortTimeout) as err:  # tick 7: p.v over delay 1 reads p's tick 6, never stored
        stepper.step(7, 0.14)
    assert str(err.value) == "no value of p.v for tick 6"
    assert (err.value.component, err.value.port, err.value.stamp) == ("p", "v", 6)


def test_a_step_waits_its_timeout_for_an_input_on_the_bus(session):
    cache = PortCache(session, "r1", OUTPUTS)
    stepper = Stepper("scope", _Scope(), session, "r1", WIRING, cache, 0.2)
    t0 = time.monotonic()
    with pytest.raises(PortTimeout, match=re.escape("no value of q.w for tick 0")):
        stepper.step(0, 0.0)
    assert time.monotonic() - t0 >= 0.2
    cache.close()


class _Scope:
    """No outputs; keeps what it is given."""
    fault = None

    def __init__(self):
        self.seen = []

    def step(self, t, inputs):
        self.seen.append(inputs["w"].tolist())
        return {}

    def close(self):
        pass


def test_what_a_step_publishes_is_read_back_under_its_tick(session):
    cache = PortCache(session, "r1", OUTPUTS, keep=4)
    stepper = Stepper("c", _Consumer(), session, "r1", WIRING, filled_store(), 1.0)
    assert stepper.last_outputs == []
    stepper.publish_initial()
    assert cache.row("c", -1).tolist() == [-1.0, -1.0]
    stepper.step(3, 0.06)
    assert cache.row("c", 3).tolist() == [0.06, 3.0] and not cache.has("c", 2)
    (row,) = stepper.last_outputs
    assert row.tolist() == [0.06, 3.0]
    cache.close()


def test_a_component_without_outputs_publishes_nothing(session):
    listener = session.declare_subscriber(bus.outputs_key("r1", "scope"))
    scope = _Scope()
    stepper = Stepper("scope", scope, session, "r1", WIRING, filled_store(), 1.0)
    stepper.step(2, 0.04)
    assert scope.seen == [q_row(2).tolist()]
    (row,) = stepper.last_outputs
    assert row.shape == (0,)
    assert listener.try_recv() is None
    assert stepper.close() is None
    listener.undeclare()


def test_a_fault_stops_the_step_after_its_outputs_went_out(session):
    cache = PortCache(session, "r1", OUTPUTS)
    stepper = Stepper("c", _Consumer(fault_at=4), session, "r1", WIRING, filled_store(), 1.0)
    stepper.step(3, 0.06)  # no fault: no error
    with pytest.raises(ComponentFault, match="^too hot at tick 4$"):
        stepper.step(4, 0.08)
    assert cache.row("c", 4).tolist() == [0.08, 4.0]
    cache.close()


def test_no_outputs_at_all_are_refused_naming_the_ports_expected(stepper):
    with pytest.raises(ComponentError, match=re.escape("returned ports [], expected ['m', 's', 'v']")):
        stepper._publish(0, None)


@pytest.mark.parametrize("before, during, reported", [
    (None, None, None), (None, "supply lost", "supply lost"), ("too hot", None, None),
    ("too hot", "too hot", None), ("too hot", "supply lost", "supply lost"),
])
def test_closing_reports_only_a_fault_set_while_closing(session, before, during, reported):
    consumer = _Consumer(close_fault=during)
    consumer.fault = before
    stepper = Stepper("c", consumer, session, "r1", WIRING, filled_store(), 1.0)
    assert stepper.close() == reported


def test_a_closed_stepper_publishes_no_more(session):
    stepper = Stepper("c", _Consumer(), session, "r1", WIRING, filled_store(), 1.0)
    stepper.close()
    with pytest.raises(zenoh.ZError):
        stepper.publish_initial()
