"""A regional animation's GLB (split morph targets): validator-clean, and three.js and Blender play the formula."""

from __future__ import annotations

import numpy as np
import pytest

from animated_scenes import make_character
from blender_python import blender  # noqa: F401  (fixture)
from facepuppet.export.gltf_regional import split_character, write_regional_glb
from gltf_validator import gltf_validator  # noqa: F401  (fixture)
from three_loader import three_loader  # noqa: F401  (fixture)

Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def regional_scene(tmp_path, rng, frames=9, fps=30):
    c = make_character(rng, v=30, m=3)
    x = c.neutral[:, 0]
    left = np.clip((x.max() - x) / np.ptp(x), 0, 1).astype(np.float32).astype(np.float64)
    masks = np.stack([np.zeros_like(left), left, 1 - left])           # background, left, right
    masks[0] = 1 - masks[1:].sum(0)
    names = ("background", "left", "right")
    w = rng.uniform(0, 1, size=(frames, 3, 3))
    path = tmp_path / "regional.glb"
    write_regional_glb(path, c, masks, names, w, fps)
    return c, masks, names, w, path, fps


def formula(c, masks, w):
    """T_B + sum_k sum_i M_k (.) w_ik (T_i - T_B), (V, 3)."""
    d = c.targets - c.neutral[None]
    return c.neutral + np.einsum("kv,ki,ivc->vc", masks, w, d)


def test_split_character_plays_the_formula_as_morph_targets(rng):
    c = make_character(rng, v=20, m=3)
    masks = rng.uniform(size=(2, 20))
    masks /= masks.sum(0)
    s = split_character(c, masks, ("a", "b"))
    assert s.names == tuple(f"{r}/{n}" for r in "ab" for n in c.names)
    w = rng.uniform(size=(2, 3))
    got = s.neutral + np.tensordot(w.reshape(-1), s.targets - s.neutral[None], 1)
    np.testing.assert_allclose(got, formula(c, masks, w), atol=1e-12)
    with pytest.raises(ValueError, match="weights must have shape"):
        write_regional_glb("x.glb", c, masks, ("a", "b"), np.zeros((3, 3, 3)), 30)


def test_regional_glb_is_valid(tmp_path, rng, gltf_validator):  # noqa: F811
    *_, path, _ = regional_scene(tmp_path, rng)
    gltf_validator.check(path)


def test_regional_glb_plays_in_threejs(tmp_path, rng, three_loader):  # noqa: F811
    c, masks, names, w, path, fps = regional_scene(tmp_path, rng)
    out = three_loader.play(path, [float(np.float32(5 / fps))])
    (mesh,) = out["meshes"]
    assert mesh["influences"] == 9
    (at5,) = out["samples"]
    np.testing.assert_allclose(at5["influences"], w[5].reshape(-1), atol=1e-6)
    np.testing.assert_allclose(at5["positions"], formula(c, masks, w[5]), atol=1e-5)


def test_regional_glb_plays_in_blender(tmp_path, rng, blender):  # noqa: F811
    c, masks, names, w, path, fps = regional_scene(tmp_path, rng)
    out = blender.load(path, fps, [5])
    (mesh,) = out["meshes"]
    assert mesh["shape_keys"][1:] == [f"{r}/{n}" for r in names for n in c.names]
    (at5,) = out["samples"]
    np.testing.assert_allclose(at5["positions"][mesh["name"]], formula(c, masks, w[5]) @ Y_UP_TO_Z_UP.T, atol=1e-5)
