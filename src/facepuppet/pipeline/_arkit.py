"""ARKit blendshape names, and how a character's key-model names relate to them.

Characters spell ARKit names in several ways: ``eyeBlinkLeft`` (ARKit, MediaPipe), ``eyeBlink_L`` (ICT
FaceKit, many Blender rigs), ``eyeBlink.L``, or one symmetric key ``eyeBlink`` for both sides. Left and right
are always the performer's own.
"""

from __future__ import annotations

import re

__all__ = ["ARKIT_NAMES", "arkit_parts"]

#: The 52 ARKit blendshapes (MediaPipe's blendshape categories without its ``_neutral``).
ARKIT_NAMES: tuple[str, ...] = (
    "browDownLeft", "browDownRight", "browInnerUp", "browOuterUpLeft", "browOuterUpRight",
    "cheekPuff", "cheekSquintLeft", "cheekSquintRight",
    "eyeBlinkLeft", "eyeBlinkRight", "eyeLookDownLeft", "eyeLookDownRight", "eyeLookInLeft",
    "eyeLookInRight", "eyeLookOutLeft", "eyeLookOutRight", "eyeLookUpLeft", "eyeLookUpRight",
    "eyeSquintLeft", "eyeSquintRight", "eyeWideLeft", "eyeWideRight",
    "jawForward", "jawLeft", "jawOpen", "jawRight",
    "mouthClose", "mouthDimpleLeft", "mouthDimpleRight", "mouthFrownLeft", "mouthFrownRight",
    "mouthFunnel", "mouthLeft", "mouthLowerDownLeft", "mouthLowerDownRight", "mouthPressLeft",
    "mouthPressRight", "mouthPucker", "mouthRight", "mouthRollLower", "mouthRollUpper",
    "mouthShrugLower", "mouthShrugUpper", "mouthSmileLeft", "mouthSmileRight", "mouthStretchLeft",
    "mouthStretchRight", "mouthUpperUpLeft", "mouthUpperUpRight",
    "noseSneerLeft", "noseSneerRight", "tongueOut",
)

_LOWER = {n.lower(): n for n in ARKIT_NAMES}
_SIDE = re.compile(r"^(.*?)[_.\-\s]?(l|r|left|right)$", re.IGNORECASE)


def arkit_parts(name: str) -> tuple[tuple[str, ...], str | None] | None:
    """The ARKit blendshapes a key-model name stands for, and the side it keeps.

    Parameters
    ----------
    name : str
        A key-model name.

    Returns
    -------
    (blendshapes, side) or None
        ``blendshapes``: the ARKit names whose scores show this key-model (two for a symmetric key such as
        ``mouthSmile``); ``side``: ``"left"``/``"right"`` when the key-model is one half of a shape ARKit has
        as one (ICT's ``browInnerUp_L``, ``cheekPuff_R``), else None. None if the name is not ARKit's.

    Examples
    --------
    >>> arkit_parts("eyeBlink_L")
    (('eyeBlinkLeft',), None)
    >>> arkit_parts("mouthSmile")
    (('mouthSmileLeft', 'mouthSmileRight'), None)
    >>> arkit_parts("cheekPuff_R")
    (('cheekPuff',), 'right')
    """
    key = name.strip().lower()
    if key in _LOWER:
        return (_LOWER[key],), None
    both = (_LOWER.get(key + "left"), _LOWER.get(key + "right"))
    if all(both):
        return (both[0], both[1]), None
    m = _SIDE.match(name.strip())
    if m:
        base, side = m.group(1).lower(), "left" if m.group(2).lower().startswith("l") else "right"
        full = _LOWER.get(base + side)
        if full:
            return (full,), None
        if base in _LOWER:
            return (_LOWER[base],), side
    return None
