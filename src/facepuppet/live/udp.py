"""A non-blocking UDP socket for the live senders: a datagram that cannot go out now is dropped and counted.

A receiver that is not there costs nothing: UDP needs no connection, and errors the kernel reports back
(an ICMP "port unreachable" surfacing on a later send) are counted, never raised into the loop.
"""

from __future__ import annotations

import logging
import socket
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from facepuppet.live.frame import LiveFrame

__all__ = ["UdpSender", "UdpSocket"]

log = logging.getLogger(__name__)


class UdpSocket:
    """Datagrams to one ``host:port``, never blocking the caller.

    Parameters
    ----------
    host : str
        Receiver's name or address (resolved once, here).
    port : int
        Receiver's UDP port.
    what : str
        Name of the output for messages (``"--vmc"``).

    Attributes
    ----------
    sent, dropped : int
        Datagrams handed to the kernel, and datagrams dropped (buffer full or a reported error).
    """

    def __init__(self, host: str, port: int, *, what: str) -> None:
        try:
            family, _, _, _, address = socket.getaddrinfo(host, port, type=socket.SOCK_DGRAM)[0]
        except (OSError, UnicodeError) as e:
            raise ValueError(f"{what}: cannot resolve host {host!r} ({e})") from e
        self.what = what
        self.address = address
        self.sent = 0
        self.dropped = 0
        self._warned = False
        self._socket: socket.socket | None = socket.socket(family, socket.SOCK_DGRAM)
        self._socket.setblocking(False)

    def send(self, data: bytes) -> bool:
        """Send one datagram; False (and counted as dropped) if it could not go out now or the socket is closed."""
        if self._socket is None:
            return False
        try:
            self._socket.sendto(data, self.address)
        except OSError as e:  # BlockingIOError (buffer full), ConnectionRefusedError (ICMP), ...
            self.dropped += 1
            if not self._warned:
                self._warned = True
                log.warning("%s: datagram to %s:%s dropped (%s); further drops are counted silently",
                            self.what, self.address[0], self.address[1], e)
            return False
        self.sent += 1
        return True

    def close(self) -> None:
        """Close the socket (idempotent)."""
        if self._socket is not None:
            self._socket.close()
            self._socket = None


class UdpSender:
    """Base of the live senders: one frame becomes one datagram (``encode``) sent on a `UdpSocket`.

    Subclasses set ``self._socket`` in their constructor and define ``encode(frame) -> bytes``.
    """

    _socket: UdpSocket

    def encode(self, frame: LiveFrame) -> bytes:
        """The datagram of one frame."""
        raise NotImplementedError

    def send(self, frame: LiveFrame) -> None:
        """Send the frame's datagram; returns at once (a datagram the kernel will not take now is dropped)."""
        self._socket.send(self.encode(frame))

    @property
    def dropped(self) -> int:
        """Datagrams dropped so far."""
        return self._socket.dropped

    def close(self) -> None:
        """Close the socket (idempotent)."""
        self._socket.close()
