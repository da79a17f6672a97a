"""The built-in Monkey: the demo's key-model names, its own personality, and the demo drives it too."""

from __future__ import annotations

import numpy as np

from facepuppet.demo.characters import BUILTIN, builtin_character
from facepuppet.demo.monkey import KEY_NAMES, MONKEY_PARTS, monkey_character, monkey_colors
from facepuppet.demo.run import DemoConfig, run_demo
from facepuppet.demo.script import KEY_NAMES as DEMO_KEYS
from facepuppet.demo.toy import toy_character
from facepuppet.io.scene import parse_glb
from gltf_validator import gltf_validator  # noqa: F401  (fixture)


def _relative(c, name: str, axis: int = 1) -> float:
    """Largest displacement of key-model ``name`` along ``axis``, as a fraction of the head's height."""
    d = c.deltas[c.names.index(name)][:, axis]
    height = np.ptp(c.neutral[:, 1])
    return float(np.abs(d).max() / height)


def test_monkey_has_the_demo_key_models_and_its_own_personality():
    m, toy = monkey_character(), toy_character()
    assert KEY_NAMES == DEMO_KEYS and m.names == toy.names and "monkey" in BUILTIN
    assert np.isfinite(m.targets).all() and m.faces.max() < len(m.neutral)
    for k, name in enumerate(m.names):
        assert np.abs(m.deltas[k]).max() > 0.2, name  # every key-model moves something
    assert _relative(m, "jawOpen") > 1.2 * _relative(toy, "jawOpen")          # the jaw drops further
    assert _relative(m, "browInnerUp") > 1.2 * _relative(toy, "browInnerUp")  # the brows lift more
    assert np.ptp(m.neutral[m.deltas[m.names.index("jawOpen")][:, 1] < -0.1, 0]) > 8.0  # a wide muzzle moves
    colors = monkey_colors()
    assert colors.shape == m.neutral.shape and {tuple(c) for c in colors} == set(MONKEY_PARTS.values())
    doc, _ = parse_glb(builtin_character("monkey").source)
    assert "COLOR_0" in doc["meshes"][0]["primitives"][0]["attributes"] and doc["materials"]


def test_demo_drives_the_monkey_with_the_same_performance(tmp_path, gltf_validator):  # noqa: F811
    result = run_demo(tmp_path, DemoConfig(seconds=4.6, size=160, tracker="truth", preview=True, progress=False,
                                           monkey=True))
    for name in ("monkey.glb", "monkey-animation.glb", "preview-monkey.mp4", "preview.mp4"):
        assert result.files[name].is_file(), name
    gltf_validator.check(result.files["monkey-animation.glb"])
    gltf_validator.check(result.files["animation.glb"])
    doc, _ = parse_glb(result.files["monkey-animation.glb"].read_bytes())
    assert doc["meshes"][0]["name"] == "monkey" and len(doc["animations"]) == 1
