"""The ARKit vocabulary: 52 names, Live Link Face spelling and order, matching of other spellings."""

from __future__ import annotations

import doctest
import re

import pytest

import facepuppet.arkit
from facepuppet.arkit import ARKIT_NAMES, LLF_NAMES, arkit_name, arkit_parts, llf_name


def test_the_52_names():
    assert len(ARKIT_NAMES) == len(set(ARKIT_NAMES)) == 52
    assert list(ARKIT_NAMES) == sorted(ARKIT_NAMES)
    assert all(re.fullmatch(r"[a-z]+([A-Z][a-z]+)+", n) for n in ARKIT_NAMES)
    sided = [n for n in ARKIT_NAMES if n.endswith(("Left", "Right"))]
    assert len(sided) == 40  # 18 left/right pairs and the directional jawLeft/Right, mouthLeft/Right
    assert {n[:-4] for n in sided if n.endswith("Left")} == {n[:-5] for n in sided if n.endswith("Right")}
    assert len(ARKIT_NAMES) - len(sided) == 12  # browInnerUp, cheekPuff, jawForward, ..., tongueOut
    assert {n for n in ARKIT_NAMES if n.startswith("eye")} == {
        f"eye{a}{s}" for a in ("Blink", "LookDown", "LookIn", "LookOut", "LookUp", "Squint", "Wide")
        for s in ("Left", "Right")}


def test_live_link_face_spelling_and_order():
    assert len(LLF_NAMES) == 52
    assert set(LLF_NAMES) == {n[0].upper() + n[1:] for n in ARKIT_NAMES}
    # Live Link Face's CSV columns: left eye, right eye, jaw, mouth, brows, cheeks, nose, tongue
    assert LLF_NAMES[:2] == ("EyeBlinkLeft", "EyeLookDownLeft") and LLF_NAMES[7] == "EyeBlinkRight"
    assert LLF_NAMES[14:18] == ("JawForward", "JawRight", "JawLeft", "JawOpen")
    assert LLF_NAMES[41:44] == ("BrowDownLeft", "BrowDownRight", "BrowInnerUp")
    assert LLF_NAMES[-1] == "TongueOut"
    assert [llf_name(n) for n in ARKIT_NAMES] == [n[0].upper() + n[1:] for n in ARKIT_NAMES]


def spellings(name: str) -> list[str]:
    """Ways rigs spell ARKit blendshape ``name``."""
    out = [name, name[0].upper() + name[1:], name.lower(), re.sub(r"(?<!^)([A-Z])", r"_\1", name).lower()]
    m = re.fullmatch(r"(.+?)(Left|Right)", name)
    if m and m.group(1) not in ("jaw", "mouth"):
        base, side = m.groups()
        out += [f"{base}_{side[0]}", f"{base}.{side[0]}", f"{base}{side[0]}", f"{base}-{side}",
                f"{base[0].upper()}{base[1:]}_{side[0]}", f"{base} {side.lower()}"]
    return out


@pytest.mark.parametrize("name", ARKIT_NAMES)
def test_every_spelling_of_every_name(name):
    for spelt in spellings(name):
        assert arkit_parts(spelt) == ((name,), None), spelt
        assert arkit_name(spelt) == name, spelt
        assert llf_name(spelt) == name[0].upper() + name[1:]


@pytest.mark.parametrize("name,parts", [
    ("eyeBlink_L", (("eyeBlinkLeft",), None)), ("EyeBlinkLeft", (("eyeBlinkLeft",), None)),
    ("eyeBlink.R", (("eyeBlinkRight",), None)), ("  jawOpen ", (("jawOpen",), None)),
    ("mouthLeft", (("mouthLeft",), None)), ("jawRight", (("jawRight",), None)),
    # symmetric keys stand for both sides
    ("mouthSmile", (("mouthSmileLeft", "mouthSmileRight"), None)),
    ("eyeLookIn", (("eyeLookInLeft", "eyeLookInRight"), None)),
    ("BrowOuterUp", (("browOuterUpLeft", "browOuterUpRight"), None)),
    # halves of a shape ARKit has as one keep their side
    ("browInnerUp_L", (("browInnerUp",), "left")), ("browInnerUp_R", (("browInnerUp",), "right")),
    ("cheekPuff_R", (("cheekPuff",), "right")), ("CheekPuffLeft", (("cheekPuff",), "left")),
    ("mouthClose.L", (("mouthClose",), "left")),
    # jaw and mouth toward a side are not halves of one shape
    ("jaw", None), ("mouth", None),
    ("_neutral", None), ("", None), ("L", None), ("left", None), ("smile", None), ("ears_wiggle", None),
    ("eyeBlink_X", None), ("browInnerDown_L", None),
])
def test_parts(name, parts):
    assert arkit_parts(name) == parts


def test_symmetric_keys_and_halves_are_not_one_name():
    assert arkit_name("mouthSmile") is None and arkit_name("browInnerUp_L") is None
    assert arkit_name("browInnerUp") == "browInnerUp"
    with pytest.raises(ValueError, match="'mouthSmile' is not the name of one ARKit blendshape"):
        llf_name("mouthSmile")
    with pytest.raises(ValueError, match="grin"):
        llf_name("grin")


def test_ict_names(ict):
    """ICT FaceKit's 53 expressions: ARKit's 52 less tongueOut, with browInnerUp and cheekPuff in halves."""
    names = [str(n) for n in ict["expr_names"]]
    parts = {n: arkit_parts(n) for n in names}
    assert all(p is not None for p in parts.values()), [n for n, p in parts.items() if p is None]
    halves = sorted(n for n, p in parts.items() if p[1] is not None)
    assert halves == ["browInnerUp_L", "browInnerUp_R", "cheekPuff_L", "cheekPuff_R"]
    shown = {s for p in parts.values() for s in p[0]}
    assert shown == set(ARKIT_NAMES) - {"tongueOut"}


def test_docstring_examples():
    assert doctest.testmod(facepuppet.arkit).failed == 0
