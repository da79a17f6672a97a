"""VMC protocol sender: the character's blend weights and head to VSeeFace, VNyan, Warudo (OSC over UDP).

Per frame one OSC bundle (time tag "immediately") goes to the receiver, holding in this order:

=============================================  ==============================================================
``/VMC/Ext/Blend/Val name:s value:f``          one per blend shape clip the rig drives (names below)
``/VMC/Ext/Blend/Apply``                       apply the values just sent
``/VMC/Ext/Bone/Pos "Head" px py pz qx qy qz   the head bone's local position (metres) and rotation (unit
qw`` (s, then 7 f)                             quaternion), Unity's frame; left out without a head pose
``/VMC/Ext/OK 1:i``                            the model is loaded
``/VMC/Ext/T time:f``                          the frame's time in the take, seconds
=============================================  ==============================================================

**Names.** "Perfect Sync" avatars (the VRM convention of VSeeFace, VNyan, Warudo, VMagicMirror, after
hinzka's 52-blendshape VRoid template) carry one blend shape clip per ARKit blendshape, named as ARKit names
it with the first letter capitalised -- Live Link Face's spelling (:data:`facepuppet.arkit.LLF_NAMES`):

==================================  ==================================  ========================
key-model (any spelling)            clip sent                           note
==================================  ==================================  ========================
``eyeBlinkLeft``, ``eyeBlink_L``    ``EyeBlinkLeft``
``jawOpen``                         ``JawOpen``
``mouthSmile`` (symmetric)          ``MouthSmileLeft``,                 both sides, same value
                                    ``MouthSmileRight``
``browInnerUp_L`` + ``_R``          ``BrowInnerUp``                     halves averaged
``smile`` (not ARKit's)             ``smile``                           sent under its own name
==================================  ==================================  ========================

``VmcConfig(names="arkit")`` sends ARKit's own spelling (``eyeBlinkLeft``) instead, for avatars whose clips
are named so; ``names="rig"`` sends the rig's names unchanged.

**Coordinates.** The head rotation arrives in the character's frame: right-handed, y up, the face looking
along +z, x toward the face's own left. A Unity avatar faces +z too, y up, but its x points to its own
*right* (Unity is left-handed). Positions therefore map as ``(x, y, z) -> (-x, y, z)`` and rotation
matrices as ``R_unity = S R S`` with ``S = diag(-1, 1, 1)``. For the unit quaternion ``(qx, qy, qz, qw)`` of
``R`` (scalar last) this is ``(qx, -qy, -qz, qw)``: Unity's quaternion of ``S R S`` by Unity's own
(standard) quaternion-to-matrix formula. Example: the face turned 30 degrees to its own left (yaw +30 degrees,
R = R_y(30 degrees)) is sent as ``(0, -sin 15 degrees, 0, cos 15 degrees) = (0, -0.258819, 0, 0.965926)``,
Unity's rotation of -30 degrees about its y axis, which turns an avatar's face from +z toward -x: its own
left. The VMC bone rotation is local (relative to the neck); with the neck at rest it is the head's rotation.
The position is :attr:`VmcConfig.head_position`, constant.
"""

from __future__ import annotations

import logging
import struct
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from facepuppet.arkit import ARKIT_NAMES, LLF_NAMES, arkit_name
from facepuppet.live._optional import import_extra
from facepuppet.live.frame import DEFAULT_HOST, LiveFrame
from facepuppet.live.names import arkit_map
from facepuppet.live.udp import UdpSender, UdpSocket

__all__ = ["VmcConfig", "VmcSender", "unity_quaternion", "vmc_names", "DEFAULT_VMC_PORT"]

log = logging.getLogger(__name__)

#: The VMC protocol's usual receiver port (VSeeFace's, VNyan's "VMC receiver" default).
DEFAULT_VMC_PORT = 39539
#: Unity's mirror of the character frame: x (the face's own left) becomes Unity's x (its own right) negated.
CHARACTER_TO_UNITY = np.diag([-1.0, 1.0, 1.0])
_SPELLINGS = {"perfect_sync": dict(zip(ARKIT_NAMES, (n[0].upper() + n[1:] for n in ARKIT_NAMES), strict=True)),
              "arkit": {n: n for n in ARKIT_NAMES}}
_BUNDLE_HEADER = 16  # "#bundle\0" and the 8-byte time tag
_LLF_TO_ARKIT = {n[0].upper() + n[1:]: n for n in ARKIT_NAMES}


@dataclass(frozen=True, kw_only=True)
class VmcConfig:
    """Options of the VMC sender.

    Attributes
    ----------
    names : {"perfect_sync", "arkit", "rig"}
        How ARKit-named key-models are spelled (module notes).
    head_bone : str
        The humanoid bone that carries the head rotation.
    head_position : (3,) float
        The head bone's local position sent with its rotation, metres, Unity's frame (receivers that move
        bones by rotation only ignore it; set it to the avatar's neck-to-head offset for those that do not).
    """

    names: str = "perfect_sync"
    head_bone: str = "Head"
    head_position: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if self.names not in ("perfect_sync", "arkit", "rig"):
            raise ValueError(f"names must be 'perfect_sync', 'arkit' or 'rig', got {self.names!r}")


def unity_quaternion(rotation: np.ndarray) -> np.ndarray:
    """(4,) Unity quaternion ``(qx, qy, qz, qw)`` of a (3, 3) rotation in the character's frame (module notes)."""
    r = np.asarray(rotation, dtype=np.float64)
    q = Rotation.from_matrix(CHARACTER_TO_UNITY @ r @ CHARACTER_TO_UNITY).as_quat()  # scalar last
    return q if q[3] >= 0 else -q


def vmc_names(names, spelling: str = "perfect_sync") -> tuple[tuple[str, ...], np.ndarray]:
    """Clip names sent and the (K, M) matrix from the rig's weights (M,) to their values (K,).

    ARKit-named key-models go out under ARKit blendshape names in ``spelling`` (halves averaged, symmetric
    keys on both sides), in Live Link Face's order; the others under their own names, after them.
    """
    names = [str(n) for n in names]
    if spelling == "rig":
        return tuple(names), np.eye(len(names))
    table = _SPELLINGS[spelling]
    amap = arkit_map(names)
    rows = [amap.matrix[c] for c in range(len(LLF_NAMES)) if amap.driven[c]]
    out = [table[_LLF_TO_ARKIT[LLF_NAMES[c]]] for c in range(len(LLF_NAMES)) if amap.driven[c]]
    for name in amap.unmapped:
        rows.append(np.eye(len(names))[names.index(name)])
        out.append(name)
    if len(set(out)) != len(out):
        dup = sorted({n for n in out if out.count(n) > 1})
        raise ValueError(f"key-model names collide with ARKit clip names: {', '.join(dup)}")
    return tuple(out), np.array(rows).reshape(len(out), len(names))


class VmcSender(UdpSender):
    """Sends each :class:`LiveFrame` as one VMC bundle to a UDP receiver, without blocking.

    Parameters
    ----------
    names : sequence of M str
        The rig's key-model names (every frame must carry these).
    host, port :
        The receiver (VSeeFace: its VMC receiver's port, 39539 by default).
    config : VmcConfig, optional
    """

    def __init__(self, names, host: str = DEFAULT_HOST, port: int = DEFAULT_VMC_PORT, *,
                 config: VmcConfig | None = None) -> None:
        self._builder = import_extra("pythonosc.osc_message_builder", "the VMC sender (--vmc)")
        self._bundle = import_extra("pythonosc.osc_bundle_builder", "the VMC sender (--vmc)")
        self.config = config or VmcConfig()
        self.names = tuple(str(n) for n in names)
        self.clip_names, self._matrix = vmc_names(self.names, self.config.names)
        if self.config.names != "rig" and not any(arkit_name(n) for n in self.names):
            log.info("--vmc: no key-model has an ARKit name; clips are sent under the rig's names")
        self._osc_message = import_extra("pythonosc.osc_message", "the VMC sender (--vmc)")
        self._templates = {head: self._template(head) for head in (False, True)}
        self._socket = UdpSocket(host, port, what="--vmc")

    def _message(self, address: str, *args) -> bytes:
        msg = self._builder.OscMessageBuilder
        builder = msg(address=address)
        for a in args:
            builder.add_arg(a, msg.ARG_TYPE_INT if isinstance(a, int) else
                            msg.ARG_TYPE_FLOAT if isinstance(a, float) else msg.ARG_TYPE_STRING)
        return builder.build().dgram

    def _template(self, head: bool) -> tuple[bytearray, np.ndarray]:
        """A bundle built by python-osc with zero values, and the byte offsets of its float32 values.

        Each message ends in its float arguments, so a value's offset follows from the message sizes; a
        frame's bundle is this template with its values written in place (OSC floats are big-endian).
        """
        messages = [(self._message("/VMC/Ext/Blend/Val", n, 0.0), 1) for n in self.clip_names]
        messages.append((self._message("/VMC/Ext/Blend/Apply"), 0))
        if head:
            messages.append((self._message("/VMC/Ext/Bone/Pos", self.config.head_bone, *[0.0] * 7), 7))
        messages.append((self._message("/VMC/Ext/OK", 1), 0))
        messages.append((self._message("/VMC/Ext/T", 0.0), 1))
        bundle = self._bundle.OscBundleBuilder(self._bundle.IMMEDIATELY)
        for dgram, _ in messages:
            bundle.add_content(self._osc_message.OscMessage(dgram))
        data = bytearray(bundle.build().dgram)
        offsets, at = [], _BUNDLE_HEADER
        for dgram, n_floats in messages:
            at += 4 + len(dgram)  # int32 size, then the message
            offsets.extend(at - 4 * (n_floats - k) for k in range(n_floats))
        return data, np.array(offsets)

    def encode(self, frame: LiveFrame) -> bytes:
        """The OSC bundle of one frame (module notes), as bytes."""
        if tuple(frame.names) != self.names:
            raise ValueError("frame.names differ from the names the VMC sender was made for")
        w = np.asarray(frame.weights, dtype=np.float64)
        values = [*(self._matrix @ np.where(np.isfinite(w), w, 0.0)).tolist()]
        head = frame.head_rotation is not None and bool(np.all(np.isfinite(frame.head_rotation)))
        if head:
            values += [*map(float, self.config.head_position), *unity_quaternion(frame.head_rotation).tolist()]
        values.append(float(frame.time))
        data, offsets = self._templates[head]
        out = bytearray(data)
        packed = struct.pack(f">{len(values)}f", *values)
        for k, at in enumerate(offsets.tolist()):
            out[at: at + 4] = packed[4 * k: 4 * k + 4]
        return bytes(out)
