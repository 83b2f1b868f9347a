"""Fixtures of the scale tests: loopback ports held until the servers under test bind them."""

from __future__ import annotations

import pytest
from ports import PortReservation


@pytest.fixture
def ports():
    """A :class:`ports.PortReservation` released after the test."""
    reservation = PortReservation()
    yield reservation
    reservation.close()
