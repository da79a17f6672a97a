"""Live Link Face sender: the iPhone app's UDP packet, so Unreal's Live Link takes facepuppet as a face source.

**Packet** (version 6, big-endian, one per frame), the struct format :data:`PACKET_FORMAT` with the two
string lengths filled in:

=====================  ===========  ==========================================================
field                  type         value
=====================  ===========  ==========================================================
version                uint8        6
device id              int32 + n B  length, then UTF-8 (:attr:`LiveLinkConfig.device_id`)
subject name           int32 + n B  length, then UTF-8 (:attr:`LiveLinkConfig.subject`)
frame number           int32        ``floor(time * fps)``
subframe               float32      ``time * fps - frame number``, in [0, 1)
fps numerator          int32        the frame rate as a fraction (30 -> 30/1, 29.97 -> 30000/1001)
fps denominator        int32
count                  uint8        61
values                 61 float32   the 52 ARKit blendshapes in Live Link Face's order
                                    (:data:`facepuppet.arkit.LLF_NAMES`), then head yaw, pitch,
                                    roll, left-eye yaw, pitch, roll, right-eye yaw, pitch, roll
=====================  ===========  ==========================================================

Key-models reach the blendshapes as in the Live Link Face CSV (:mod:`facepuppet.live.names`); blendshapes
no key-model drives are 0. Head angles are those of :func:`facepuppet.export.csv.head_angles` (R = R_y(yaw)
R_x(pitch) R_z(roll) in the character's frame) divided by 180 degrees, Live Link Face's unit (as in its CSV:
+-1 is a half turn); without a head pose they are 0. Eye rotations are 0 (gaze is not tracked).

**Rigs without ARKit names.** Live Link Face carries ARKit's 52 blendshapes only: a rig none of whose
key-models has an ARKit name is refused (ValueError, one line); key-models without one in a rig that has
some are left out, with one warning when the sender is made.
"""

from __future__ import annotations

import math
import struct
import warnings
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from facepuppet.arkit import LLF_NAMES
from facepuppet.export.csv import LLF_HEAD_EYES, head_angles
from facepuppet.live.frame import DEFAULT_HOST, LiveFrame
from facepuppet.live.names import arkit_map
from facepuppet.live.udp import UdpSender, UdpSocket

__all__ = ["LiveLinkConfig", "LiveLinkSender", "encode_packet", "PACKET_FORMAT", "PACKET_VERSION",
           "DEFAULT_LIVELINK_PORT", "fps_fraction"]

#: Live Link Face's UDP port (Unreal's Live Link Face source listens here).
DEFAULT_LIVELINK_PORT = 11111
#: The packet version this module writes.
PACKET_VERSION = 6
#: Values per packet: the 52 blendshapes and 9 head/eye angles.
N_VALUES = len(LLF_NAMES) + len(LLF_HEAD_EYES)
#: struct format of one packet; ``{device}`` and ``{subject}`` are the UTF-8 lengths of the two strings.
#: version, device id (length, bytes), subject (length, bytes), frame, subframe, fps num/den, count, values.
PACKET_FORMAT = ">B" "i{device}s" "i{subject}s" "if" "ii" "B" f"{N_VALUES}f"


@dataclass(frozen=True, kw_only=True)
class LiveLinkConfig:
    """Options of the Live Link Face sender.

    Attributes
    ----------
    subject : str
        The Live Link subject name Unreal lists (and the face's Anim Blueprint picks).
    device_id : str
        The source's device id (Unreal groups subjects by it).
    fps : float
        Frame rate of the stream, for the frame number and the fps fraction.
    """

    subject: str = "facepuppet"
    device_id: str = "facepuppet"
    fps: float = 30.0

    def __post_init__(self) -> None:
        if not self.subject:
            raise ValueError("subject must not be empty")
        if not (math.isfinite(self.fps) and self.fps > 0):
            raise ValueError(f"fps must be a positive number, got {self.fps}")


def fps_fraction(fps: float) -> tuple[int, int]:
    """``(numerator, denominator)`` of a frame rate: NTSC rates (within 0.002 fps) as n*1000/1001
    (29.97 -> 30000/1001, 59.94 -> 60000/1001), others as the nearest fraction with a denominator <= 1001."""
    n = round(fps * 1001 / 1000)
    if abs(fps - round(fps)) > 0.01 and abs(n * 1000 / 1001 - fps) < 0.002:
        return n * 1000, 1001
    f = Fraction(fps).limit_denominator(1001)
    return f.numerator, f.denominator


def encode_packet(values: np.ndarray, *, time: float, config: LiveLinkConfig) -> bytes:
    """One Live Link Face packet (module notes) of (61,) values at ``time`` seconds."""
    values = np.asarray(values, dtype=np.float64)
    if values.shape != (N_VALUES,):
        raise ValueError(f"values must have shape ({N_VALUES},), got {values.shape}")
    device, subject = config.device_id.encode("utf-8"), config.subject.encode("utf-8")
    position = max(float(time), 0.0) * config.fps
    frame = int(math.floor(position))
    num, den = fps_fraction(config.fps)
    fmt = PACKET_FORMAT.format(device=len(device), subject=len(subject))
    return struct.pack(fmt, PACKET_VERSION, len(device), device, len(subject), subject,
                       frame, position - frame, num, den, N_VALUES, *np.nan_to_num(values).tolist())


class LiveLinkSender(UdpSender):
    """Sends each :class:`LiveFrame` as one Live Link Face packet to Unreal, without blocking.

    Parameters
    ----------
    names : sequence of M str
        The rig's key-model names; at least one must be ARKit's (module notes).
    host, port :
        Where Unreal listens (its Live Link Face source; port 11111).
    config : LiveLinkConfig, optional
    """

    def __init__(self, names, host: str = DEFAULT_HOST, port: int = DEFAULT_LIVELINK_PORT, *,
                 config: LiveLinkConfig | None = None) -> None:
        self.config = config or LiveLinkConfig()
        self.names = tuple(str(n) for n in names)
        self._map = arkit_map(self.names)
        if not self._map.driven.any():
            example = f" (e.g. {self.names[0]!r})" if self.names else ""
            raise ValueError(f"--livelink: no key-model of the rig has an ARKit name{example}; Live Link Face "
                             f"carries ARKit's 52 blendshapes only (use --vmc or --viewer)")
        if self._map.unmapped:
            warnings.warn(f"--livelink: key-models with no ARKit name are left out: "
                          f"{', '.join(self._map.unmapped)}", stacklevel=2)
        self._socket = UdpSocket(host, port, what="--livelink")

    def values(self, frame: LiveFrame) -> np.ndarray:
        """(61,) packet values of a frame (module notes)."""
        if tuple(frame.names) != self.names:
            raise ValueError("frame.names differ from the names the Live Link sender was made for")
        out = np.zeros(N_VALUES)
        out[: len(LLF_NAMES)] = self._map(frame.weights)
        rotation = frame.head_rotation
        if rotation is not None and np.all(np.isfinite(rotation)):
            out[len(LLF_NAMES): len(LLF_NAMES) + 3] = head_angles(np.asarray(rotation)[None])[0] / np.pi
        return out

    def encode(self, frame: LiveFrame) -> bytes:
        """The packet of one frame."""
        return encode_packet(self.values(frame), time=frame.time, config=self.config)
