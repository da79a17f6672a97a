"""What the live loop hands its outputs once per frame: :class:`LiveFrame`, and the :class:`Sender` protocol.

Every output of ``facepuppet live`` (the browser viewer, the VMC and Live Link Face senders) is a
:class:`Sender`: the loop calls ``send(frame)`` once per frame, from its own thread, and ``close()`` once at the
end. ``send`` never blocks the caller: UDP senders write to a non-blocking socket and drop a datagram the
kernel will not take; the viewer stores the frame in a one-slot mailbox its own thread reads.

Conventions, shared by all outputs:

- weights: one per key-model, in the rig's order, usually in [0, 1] (gain may exceed it);
- head rotation: (3, 3), the head's rotation in the character's frame (y up, the face looking along +z, x
  toward the face's own left; right-handed), as :func:`facepuppet.pipeline.animate.head_rotation_in_character`
  gives it; None when the tracker gives no head pose;
- ``timestamp``: ``time.perf_counter()`` seconds when the frame was captured (read from the camera or file);
  latency is the time from it to the packet being sent;
- curves: (C, 4, 2) float, the tracked curves as cubic Bezier control points in image pixels (x right, y
  down); image: (H, W, 3) uint8 RGB, the camera picture.
"""

from __future__ import annotations

import ipaddress
import logging
import re
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

__all__ = ["LiveFrame", "Sender", "parse_address", "is_loopback", "warn_if_exposed"]

log = logging.getLogger(__name__)

#: Host a server binds, or a sender sends to, when HOST:PORT gives no host.
DEFAULT_HOST = "127.0.0.1"
_ADDRESS = re.compile(r"^(?:(?P<host>\[[0-9A-Fa-f:.]+\]|[^:\[\]]+):)?(?P<port>\d{1,5})$")


@dataclass(frozen=True, kw_only=True)
class LiveFrame:
    """One frame of the live stream, as every output receives it.

    Attributes
    ----------
    index : int
        Frame number in the take, from 0.
    time : float
        Time of the frame in the take, seconds from its start (the video's time for a file).
    timestamp : float
        ``time.perf_counter()`` when the frame was captured, seconds.
    weights : (M,) float
        Blend weights, one per key-model, in the order of ``names``.
    names : tuple of M str
        Key-model names.
    head_rotation : (3, 3) float or None
        Head rotation in the character's frame (module notes), or None.
    valid : bool
        False when no face was found in this frame (the weights then hold or ease to neutral).
    curves : (C, 4, 2) float or None
        Tracked curves as cubic Bezier control points, image pixels.
    image : (H, W, 3) uint8 or None
        The camera picture, RGB.
    """

    index: int
    time: float
    timestamp: float
    weights: np.ndarray
    names: tuple[str, ...]
    head_rotation: np.ndarray | None = None
    valid: bool = True
    curves: np.ndarray | None = None
    image: np.ndarray | None = None

    def __post_init__(self) -> None:
        w = np.shape(self.weights)
        if len(w) != 1 or w[0] != len(self.names):
            raise ValueError(f"weights must have shape ({len(self.names)},) to match names, got {w}")
        if self.head_rotation is not None and np.shape(self.head_rotation) != (3, 3):
            raise ValueError(f"head_rotation must have shape (3, 3), got {np.shape(self.head_rotation)}")
        if self.curves is not None and (np.ndim(self.curves) != 3 or np.shape(self.curves)[1:] != (4, 2)):
            raise ValueError(f"curves must have shape (C, 4, 2), got {np.shape(self.curves)}")
        if self.image is not None and (np.ndim(self.image) != 3 or np.shape(self.image)[2] != 3):
            raise ValueError(f"image must have shape (H, W, 3), got {np.shape(self.image)}")


@runtime_checkable
class Sender(Protocol):
    """An output of the live loop: ``send`` once per frame (never blocks), ``close`` once at the end."""

    def send(self, frame: LiveFrame) -> None:
        """Send one frame; returns at once (a frame that cannot go out now is dropped, never queued)."""

    def close(self) -> None:
        """Stop and release sockets and threads; further ``send`` calls are ignored."""


def parse_address(text: str, *, what: str, default_host: str = DEFAULT_HOST) -> tuple[str, int]:
    """``(host, port)`` of ``"[HOST:]PORT"``; ValueError naming ``what`` (the option) when malformed.

    ``HOST`` is a name, an IPv4 address or a bracketed IPv6 address (``[::1]:8765``).

    Examples
    --------
    >>> parse_address("8765", what="--viewer")
    ('127.0.0.1', 8765)
    >>> parse_address("192.168.1.5:39539", what="--vmc")
    ('192.168.1.5', 39539)
    """
    m = _ADDRESS.match(str(text).strip())
    port = int(m["port"]) if m else -1
    if not m or not 0 < port < 65536:
        raise ValueError(f"{what}: expected [HOST:]PORT with a port in 1..65535, got {text!r}")
    host = m["host"] or default_host
    return host.strip("[]"), port


def is_loopback(host: str) -> bool:
    """True for ``localhost`` and addresses of the loopback interface (127.0.0.0/8, ::1)."""
    if host.lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def warn_if_exposed(host: str, what: str) -> None:
    """Log a warning when a server ``what`` binds an address other machines can reach."""
    if not is_loopback(host):
        log.warning("%s listens on %s, reachable from other machines on the network; "
                    "bind 127.0.0.1 to keep it on this computer", what, host)
