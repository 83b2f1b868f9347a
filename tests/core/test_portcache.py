"""The store of received port values, in-process: a row per producer and tick stamp, the few most recent
kept; payloads of one or several ticks split into rows and refused at the wrong size; the bus-fed cache
reading what a publisher put under its tick, waiting for a row that comes late and naming the one that
never comes; where each port lies in a row; which stamp a delayed edge reads."""

from __future__ import annotations

import re
import threading
import time

import numpy as np
import pytest

from cosim.contract.component import Port
from cosim.contract.errors import PortTimeout
from cosim.runtime import bus
from cosim.runtime.portcache import PortCache, PortStore, expected_stamp, port_slots

#: producer p: a vector, a scalar and a 2x2 matrix (8 values a row); q: a pair; scope: no outputs
OUTPUTS = {"p": (Port("v", (3,), "m"), Port("s", (), "Hz"), Port("m", (2, 2), "1")),
           "q": (Port("w", (2,), "V"),), "scope": ()}


def p_row(stamp: int) -> np.ndarray:
    """p's row (8,) produced at ``stamp``: 10 * stamp + 0..7, so a value names its tick and place."""
    return 10.0 * stamp + np.arange(8.0)


@pytest.fixture
def session():
    s = bus.open_session()  # in-process peer, nothing leaves the process
    yield s
    s.close()


def test_each_port_has_its_slot_in_the_row_in_declared_order():
    assert port_slots(OUTPUTS["p"]) == [(0, 3, None), (3, 4, ()), (4, 8, (2, 2))]
    assert port_slots([Port("a", (2, 3), "1"), Port("b", (1,), "1")]) == [(0, 6, (2, 3)), (6, 7, None)]
    assert port_slots([]) == []
    store = PortStore(OUTPUTS)
    assert store.slot("p", "m") == (4, 8, (2, 2)) and store.slot("q", "w") == (0, 2, None)


@pytest.mark.parametrize("tick, period, delay, stamp", [
    (0, 1, 0, 0), (5, 1, 0, 5), (5, 1, 1, 4), (5, 1, 3, 2),
    (0, 1, 1, -1), (2, 1, 3, -1), (3, 1, 3, 0),  # before the producer's first step: its initial outputs
    (0, 1, 3, -1), (0, 2, 1, -1), (1, 3, 3, -1),  # -1 however far before it, on any period's grid
    (5, 2, 0, 4), (5, 2, 1, 4), (6, 2, 1, 4), (7, 3, 0, 6), (2, 3, 0, 0), (3, 3, 1, 0), (4, 3, 1, 3),
])
def test_the_stamp_a_delayed_edge_reads(tick, period, delay, stamp):
    """The producer's last step at or before tick - delay, on its period's grid; -1 before its first."""
    assert expected_stamp(tick, period, delay) == stamp


def test_a_store_keeps_the_three_latest_rows_by_default():
    store = PortStore(OUTPUTS)
    for tick in (-1, 0, 1):
        store.store("q", tick, np.array([tick, -tick], float))
    assert store.has("q", -1) and sorted(store.rows_of("q")) == [-1, 0, 1]
    store.store("q", 2, np.array([2.0, -2.0]))
    assert not store.has("q", -1) and sorted(store.rows_of("q")) == [0, 1, 2]  # the oldest went
    assert store.row("q", 2).tolist() == [2.0, -2.0]


def test_a_store_keeps_as_many_rows_as_asked():
    store = PortStore(OUTPUTS, keep=5)
    for tick in range(7):
        store.store("q", tick, np.full(2, float(tick)))
    assert sorted(store.rows_of("q")) == [2, 3, 4, 5, 6]
    assert store.rows_of("p") == {}  # another producer's rows are its own


def test_a_payload_of_one_tick_is_its_row():
    store = PortStore(OUTPUTS)
    store.store_payload("p", [4], p_row(4).tobytes())
    row = store.row("p", 4)
    assert row.dtype == np.float64 and row.tolist() == p_row(4).tolist()
    assert store.has("p", 4) and not store.has("p", 3)


def test_a_payload_of_several_ticks_is_split_into_their_rows():
    store = PortStore(OUTPUTS, keep=4)
    store.store_payload("p", [2, 3, 5], np.concatenate([p_row(2), p_row(3), p_row(5)]).tobytes())
    assert sorted(store.rows_of("p")) == [2, 3, 5]
    for tick in (2, 3, 5):
        assert store.row("p", tick).tolist() == p_row(tick).tolist()
    store.store_payload("q", [7, 8], np.array([7.0, 7.5, 8.0, 8.5]).tobytes())
    assert store.row("q", 7).tolist() == [7.0, 7.5] and store.row("q", 8).tolist() == [8.0, 8.5]


def test_a_producer_without_outputs_has_empty_rows():
    """A node's reply for a component without outputs (a scope) carries its ticks and no values."""
    store = PortStore(OUTPUTS)
    store.store_payload("scope", [3, 4], b"")
    assert sorted(store.rows_of("scope")) == [3, 4] and store.row("scope", 4).shape == (0,)
    with pytest.raises(ValueError, match=re.escape("scope: payload holds 1 values, expected 1 x 0")):
        store.store_payload("scope", [5], np.zeros(1).tobytes())


@pytest.mark.parametrize("ticks, values", [([1], 7), ([1], 9), ([1, 2], 8), ([1, 2], 17)])
def test_a_payload_of_the_wrong_size_is_refused_with_the_sizes(ticks, values):
    store = PortStore(OUTPUTS)
    message = f"p: payload holds {values} values, expected {len(ticks)} x 8"
    with pytest.raises(ValueError, match=re.escape(message)):
        store.store_payload("p", ticks, np.zeros(values).tobytes())
    assert store.rows_of("p") == {}


def test_a_missing_row_is_named_by_producer_and_stamp():
    store = PortStore(OUTPUTS)
    store.store("p", 0, p_row(0))
    with pytest.raises(PortTimeout) as err:
        store.row("p", 7)
    assert str(err.value) == "no value of p.* for tick 7"
    assert (err.value.component, err.value.port, err.value.stamp) == ("p", None, 7)
    assert err.value.what == "its outputs"


def test_a_port_timeout_names_the_port_when_it_has_one():
    exc = PortTimeout("gain", "u", -1)
    assert str(exc) == "no value of gain.u for tick -1"
    assert (exc.component, exc.port, exc.stamp) == ("gain", "u", -1)
    assert exc.what == "its output 'u'"


def put(session, comp: str, tick: int, row: np.ndarray) -> None:
    """Publish ``row`` as ``comp``'s outputs of ``tick`` on run r1, as a stepper does."""
    pub = bus.publisher(session, bus.outputs_key("r1", comp))
    pub.put(row.tobytes(), attachment=bus.encode_tick(tick))
    pub.undeclare()


def test_the_cache_reads_each_row_under_the_tick_it_was_published_with(session):
    cache = PortCache(session, "r1", OUTPUTS)
    assert not cache.has("p", -1)
    put(session, "p", -1, p_row(-1))
    put(session, "p", 0, p_row(0))
    put(session, "q", 0, np.array([0.5, 1.5]))
    assert cache.has("p", -1) and cache.has("p", 0) and not cache.has("p", 1)  # has() takes what arrived
    assert cache.row("p", 0).tolist() == p_row(0).tolist()
    assert cache.row("p", -1).tolist() == p_row(-1).tolist()
    assert cache.row("q", 0).tolist() == [0.5, 1.5] and cache.row("q", 0).dtype == np.float64
    put(session, "q", 1, np.array([2.5, 3.5]))
    assert cache.row("q", 1).tolist() == [2.5, 3.5]  # not asked with has() first: row() takes it
    cache.close()


def test_the_cache_keeps_three_rows_by_default_and_as_many_as_asked(session):
    default, five = PortCache(session, "r1", OUTPUTS), PortCache(session, "r1", OUTPUTS, keep=5)
    for tick in range(6):
        put(session, "q", tick, np.full(2, float(tick)))
    assert [t for t in range(6) if default.has("q", t)] == [3, 4, 5]
    assert [t for t in range(6) if five.has("q", t)] == [1, 2, 3, 4, 5]
    default.close()
    five.close()


def test_the_cache_waits_for_a_row_that_comes_late(session):
    cache = PortCache(session, "r1", OUTPUTS)
    late = threading.Timer(0.05, put, (session, "p", 3, p_row(3)))
    late.start()
    try:
        assert cache.row("p", 3, timeout_s=10.0).tolist() == p_row(3).tolist()
    finally:
        late.join()
    cache.close()


def test_the_cache_gives_up_on_a_row_that_never_comes_after_its_timeout(session):
    cache = PortCache(session, "r1", OUTPUTS)
    put(session, "p", 0, p_row(0))
    t0 = time.monotonic()
    with pytest.raises(PortTimeout) as err:
        cache.row("p", 1, timeout_s=0.2)
    assert time.monotonic() - t0 >= 0.2
    assert str(err.value) == "no value of p.* for tick 1" and err.value.stamp == 1
    assert cache.row("p", 0).tolist() == p_row(0).tolist()  # what did come is still there
    cache.close()


def test_without_a_timeout_the_cache_does_not_wait(session, monkeypatch):
    cache = PortCache(session, "r1", OUTPUTS)
    waits = []

    def poll(fetch, timeout_s):
        waits.append(timeout_s)
        return fetch()

    monkeypatch.setattr(bus, "poll", poll)
    with pytest.raises(PortTimeout, match=re.escape("no value of q.* for tick 0")):
        cache.row("q", 0)
    assert waits == [0.0]
    cache.close()


def test_the_cache_subscribes_to_each_producer_with_outputs_until_closed(session):
    cache = PortCache(session, "r1", OUTPUTS)
    pubs = {c: bus.publisher(session, bus.outputs_key("r1", c)) for c in OUTPUTS}
    assert {c: p.matching_status.matching for c, p in pubs.items()} == {"p": True, "q": True, "scope": False}
    cache.close()
    assert not any(p.matching_status.matching for p in pubs.values())
    cache.close()  # a second close is harmless
    for p in pubs.values():
        p.undeclare()
