"""The ARKit blendshape vocabulary: the 52 names, their Live Link Face spelling, and matching of other spellings.

Characters and tools spell the same blendshape in several ways: ``eyeBlinkLeft`` (ARKit, MediaPipe),
``EyeBlinkLeft`` (Live Link Face), ``eyeBlink_L`` (ICT FaceKit, many rigs), ``eyeBlink.L`` (Blender),
``eye_blink_left``; some rigs have one symmetric key ``eyeBlink`` for both sides, and some split a shape
ARKit has as one into halves (ICT's ``browInnerUp_L`` and ``browInnerUp_R``). Left and right are the
performer's own, as in ARKit.

``jawLeft``/``jawRight`` and ``mouthLeft``/``mouthRight`` move toward a side rather than being the two halves
of one shape, so a bare ``jaw`` or ``mouth`` is not a symmetric key for them.
"""

from __future__ import annotations

import re

__all__ = ["ARKIT_NAMES", "LLF_NAMES", "arkit_parts", "arkit_name", "llf_name"]

#: The 52 ARKit blendshapes in ARKit's spelling, in alphabetical order (MediaPipe's Face Landmarker scores
#: all but ``tongueOut`` in this order, after its own ``_neutral``).
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

#: The same 52 as Live Link Face spells them (capitalised) and orders its CSV columns.
LLF_NAMES: tuple[str, ...] = (
    "EyeBlinkLeft", "EyeLookDownLeft", "EyeLookInLeft", "EyeLookOutLeft", "EyeLookUpLeft", "EyeSquintLeft",
    "EyeWideLeft", "EyeBlinkRight", "EyeLookDownRight", "EyeLookInRight", "EyeLookOutRight", "EyeLookUpRight",
    "EyeSquintRight", "EyeWideRight", "JawForward", "JawRight", "JawLeft", "JawOpen", "MouthClose",
    "MouthFunnel", "MouthPucker", "MouthRight", "MouthLeft", "MouthSmileLeft", "MouthSmileRight",
    "MouthFrownLeft", "MouthFrownRight", "MouthDimpleLeft", "MouthDimpleRight", "MouthStretchLeft",
    "MouthStretchRight", "MouthRollLower", "MouthRollUpper", "MouthShrugLower", "MouthShrugUpper",
    "MouthPressLeft", "MouthPressRight", "MouthLowerDownLeft", "MouthLowerDownRight", "MouthUpperUpLeft",
    "MouthUpperUpRight", "BrowDownLeft", "BrowDownRight", "BrowInnerUp", "BrowOuterUpLeft",
    "BrowOuterUpRight", "CheekPuff", "CheekSquintLeft", "CheekSquintRight", "NoseSneerLeft",
    "NoseSneerRight", "TongueOut",
)

_KEY = {n.lower(): n for n in ARKIT_NAMES}  # spelling-free key -> ARKit name
_SEPARATORS = re.compile(r"[\s_.\-]+")
_SIDE_SUFFIXES = (("left", "left"), ("right", "right"), ("l", "left"), ("r", "right"))  # longest first
_DIRECTIONAL = frozenset({"jaw", "mouth"})  # jawLeft/jawRight, mouthLeft/mouthRight are not halves


def _key(name: str) -> str:
    return _SEPARATORS.sub("", str(name)).lower()


def arkit_parts(name: str) -> tuple[tuple[str, ...], str | None] | None:
    """The ARKit blendshapes a key-model name stands for, and the side it keeps.

    Parameters
    ----------
    name : str
        A key-model name in any of the spellings of the module notes.

    Returns
    -------
    (blendshapes, side) or None
        ``blendshapes``: the ARKit names (ARKit's spelling) the key-model shows, two for a symmetric key such
        as ``mouthSmile``; ``side``: ``"left"``/``"right"`` when the key-model is one half of a shape ARKit
        has as one (``browInnerUp_L``, ``cheekPuff_R``), else None. None if the name is not ARKit's.

    Examples
    --------
    >>> arkit_parts("eyeBlink_L")
    (('eyeBlinkLeft',), None)
    >>> arkit_parts("mouthSmile")
    (('mouthSmileLeft', 'mouthSmileRight'), None)
    >>> arkit_parts("cheekPuff_R")
    (('cheekPuff',), 'right')
    """
    key = _key(name)
    if key in _KEY:
        return (_KEY[key],), None
    if key not in _DIRECTIONAL and key + "left" in _KEY and key + "right" in _KEY:
        return (_KEY[key + "left"], _KEY[key + "right"]), None
    for suffix, side in _SIDE_SUFFIXES:
        base = key[: -len(suffix)]
        if key.endswith(suffix) and base:
            if base + side in _KEY:
                return (_KEY[base + side],), None
            if base in _KEY:
                return (_KEY[base],), side
    return None


def arkit_name(name: str) -> str | None:
    """ARKit's spelling of a name that is exactly one ARKit blendshape (``EyeBlink_L`` -> ``eyeBlinkLeft``).

    None for names that are not ARKit's, symmetric keys (two blendshapes) and halves of one.
    """
    parts = arkit_parts(name)
    return parts[0][0] if parts and len(parts[0]) == 1 and parts[1] is None else None


def llf_name(name: str) -> str:
    """Live Link Face's spelling of an ARKit blendshape name (``eyeBlinkLeft`` -> ``EyeBlinkLeft``).

    Raises
    ------
    ValueError
        If ``name`` is not one of :data:`ARKIT_NAMES` in any spelling.
    """
    full = arkit_name(name)
    if full is None:
        raise ValueError(f"{name!r} is not the name of one ARKit blendshape")
    return full[0].upper() + full[1:]
