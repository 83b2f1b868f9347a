"""Loopback ports for the tests, chosen by the OS and held until the test's servers bind them.

Binding port 0 and closing the socket again (the usual trick) leaves a window in which another
process may take the port before the server under test binds it. A :class:`PortReservation`
keeps its sockets bound, with ``SO_REUSEADDR`` and not listening, until it is closed: the kernel
gives the port to no one else, while a server that binds with ``SO_REUSEADDR`` (zenoh's listeners
do) can still take it and listen.
"""

from __future__ import annotations

import socket


class PortReservation:
    """Ports reserved on loopback addresses (127.0.0.0/8 only); ``close()`` releases them."""

    def __init__(self):
        self._sockets: list[socket.socket] = []

    def port(self, address: str = "127.0.0.1") -> int:
        """A port the OS picks on ``address``, held by this reservation."""
        if not address.startswith("127."):
            raise ValueError(f"tests reserve loopback ports only, not {address}")
        s = socket.socket()
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        s.bind((address, 0))
        self._sockets.append(s)
        return s.getsockname()[1]

    def close(self) -> None:
        for s in self._sockets:
            s.close()
        self._sockets = []
