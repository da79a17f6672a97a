"""A regional animation written into the character's own scene: split morph targets added to its meshes.

Known answer: every mesh shows T_B + Σ_k Σ_i M_k ⊙ w_ik δ_i (+ its undriven targets at their defaults), read
back by our reader, played by three.js and by Blender; the scene's own data stay as they were.
"""

from __future__ import annotations

import numpy as np
import pytest

from blender_python import blender  # noqa: F401  (fixture)
from facepuppet.export.scene_animation import write_scene_animation
from facepuppet.export.scene_regional import scene_vertex_count
from facepuppet.io.gltf import read_gltf
from facepuppet.io.scene import parse_glb
from gltf_validator import gltf_validator  # noqa: F401  (fixture)
from scene_characters import HEAD_DEFAULTS, skinned_character
from three_loader import three_loader  # noqa: F401  (fixture)

DRIVEN = ("jawOpen", "eyeBlinkLeft", "mouthSmileLeft")
REGIONS = ("background", "upper", "lower")
FRAMES = 5


def _masks(character) -> np.ndarray:
    """Soft masks over the vertices by height, exactly zero far from their region (R, V); they sum to 1."""
    y = character.neutral[:, 1]
    t = np.clip((y - np.quantile(y, 0.3)) / (np.quantile(y, 0.7) - np.quantile(y, 0.3)), 0, 1)
    upper, lower = 0.8 * t, 0.8 * (1 - t)
    return np.stack([1 - upper - lower, upper, lower])


def _written(tmp_path, rng, *, suffix=".glb", morph_normals=True):
    made = skinned_character(rng, morph_normals=morph_normals)
    (tmp_path / "char.glb").write_bytes(made["glb"])
    character = read_gltf(tmp_path / "char.glb")
    masks = _masks(character)
    w = rng.uniform(0, 1, size=(FRAMES, len(REGIONS), len(DRIVEN)))
    out = tmp_path / f"out{suffix}"
    write_scene_animation(out, character.source, DRIVEN, w.reshape(FRAMES, -1), 30.0,
                          regions=(REGIONS, masks))
    return made, character, masks, w, out


def _expected(character, masks, w) -> np.ndarray:
    """(F, V, 3): T_B + Σ_k Σ_i M_k ⊙ w_ik δ_i + the undriven extraShape at its default."""
    names = list(character.names)
    d = character.deltas[[names.index(n) for n in DRIVEN]]
    extra = HEAD_DEFAULTS[3] * character.deltas[names.index("extraShape")]
    return character.neutral + extra + np.einsum("kv,fki,ivc->fvc", masks, w, d)


def test_scene_keeps_its_data_and_gets_split_targets(tmp_path, rng, gltf_validator):  # noqa: F811
    made, character, masks, w, out = _written(tmp_path, rng)
    doc_in, blob_in = parse_glb(made["glb"])
    doc_out, blob_out = parse_glb(out.read_bytes())
    assert blob_out[:len(blob_in)] == blob_in
    for key in ("bufferViews", "accessors"):
        assert doc_out[key][:len(doc_in[key])] == doc_in[key]
    for key in ("nodes", "skins", "materials", "textures", "images", "cameras"):
        assert doc_out[key] == doc_in[key]
    assert doc_out["animations"][0] == doc_in["animations"][0]
    head = doc_out["meshes"][0]
    split = [f"{r}/{n}" for r in REGIONS for n in DRIVEN]
    assert head["extras"]["targetNames"] == list(doc_in["meshes"][0]["extras"]["targetNames"]) + split
    assert head["weights"] == list(HEAD_DEFAULTS) + [0.0] * len(split)
    assert set(head["primitives"][0]["targets"][-1]) == {"POSITION", "NORMAL"}    # the normals split too
    assert any("sparse" in doc_out["accessors"][t["POSITION"]] for t in head["primitives"][0]["targets"][4:])
    teeth = doc_out["meshes"][1]
    assert teeth["extras"]["targetNames"] == ["jawOpen"] + [f"{r}/jawOpen" for r in REGIONS]
    gltf_validator.check(out)

    back = read_gltf(out)                      # our reader decodes the sparse targets: T = T_B + Σ w δ
    assert len(back.neutral) == len(character.neutral) == scene_vertex_count(made["glb"])
    names = list(back.names)
    for f in range(FRAMES):
        weights = np.zeros(len(names))
        weights[names.index("extraShape")] = HEAD_DEFAULTS[3]
        for k, r in enumerate(REGIONS):
            for i, n in enumerate(DRIVEN):
                weights[names.index(f"{r}/{n}")] = w[f, k, i]
        shown = back.neutral + np.tensordot(weights, back.deltas, axes=1)
        np.testing.assert_allclose(shown, _expected(character, masks, w)[f], atol=1e-5)


def test_animation_channels_drive_the_split_targets_only(tmp_path, rng):
    _, _, _, w, out = _written(tmp_path, rng)
    doc, blob = parse_glb(out.read_bytes())
    anim = doc["animations"][-1]
    by_node = {c["target"]["node"]: c["sampler"] for c in anim["channels"] if c["target"]["path"] == "weights"}
    acc = doc["accessors"][anim["samplers"][by_node[4]]["output"]]
    view = doc["bufferViews"][acc["bufferView"]]
    n_targets = len(doc["meshes"][0]["extras"]["targetNames"])
    keys = np.frombuffer(blob, np.float32, acc["count"], view.get("byteOffset", 0) + acc.get("byteOffset", 0))
    keys = keys.reshape(FRAMES, n_targets)
    np.testing.assert_allclose(keys[:, :3], 0.0)                       # the head's own driven targets: off
    np.testing.assert_allclose(keys[:, 3], HEAD_DEFAULTS[3], atol=1e-7)  # extraShape: its default
    np.testing.assert_allclose(keys[:, 4:], w.reshape(FRAMES, -1), atol=1e-6)


def test_masks_that_do_not_fit_the_scene_are_refused(tmp_path, rng):
    made = skinned_character(rng)
    v = scene_vertex_count(made["glb"])
    with pytest.raises(ValueError, match=f"region masks must be \\(3, {v}\\)"):
        write_scene_animation(tmp_path / "x.glb", made["glb"], DRIVEN, np.zeros((2, 9)), 30.0,
                              regions=(REGIONS, np.ones((3, v - 1)) / 3))
    assert not (tmp_path / "x.glb").exists()


def test_regional_scene_plays_in_threejs(tmp_path, rng, three_loader):  # noqa: F811
    made, character, masks, w, out = _written(tmp_path, rng)
    t = float(np.float32(3 / 30.0))
    shown = three_loader.play(out, [t], clip="performance")["samples"][0]["meshPositions"]
    expected = _expected(character, masks, w)[3]
    n_teeth, n_eyes = len(made["parts"]["teeth"][0]), len(made["parts"]["eyes"][0])
    np.testing.assert_allclose(shown["Teeth"], expected[:n_teeth], atol=1e-5)
    np.testing.assert_allclose(shown["Eyes"], expected[n_teeth:n_teeth + n_eyes], atol=1e-5)
    np.testing.assert_allclose(shown["HeadMesh"], expected[n_teeth + n_eyes:], atol=1e-5)


def test_regional_scene_loads_in_blender(tmp_path, rng, blender):  # noqa: F811
    """Blender's performance action carries the split weights on every mesh; each mesh's evaluated vertices are
    T_B + Σ w δ at the shape-key values it shows (Blender shows the scene's first action, idle)."""
    made, _, _, w, out = _written(tmp_path, rng)
    report = blender.load(out, 30, [3])
    (action,) = [a for a in report["actions"] if a["name"].startswith("performance")]
    curves = {}
    for fc in action["fcurves"]:
        curves.setdefault(fc["data_path"], []).append(fc["values"])
    for k, r in enumerate(REGIONS):
        for i, n in enumerate(DRIVEN):
            for values in curves[f'key_blocks["{r}/{n}"].value']:
                np.testing.assert_allclose(values, w[:, k, i], atol=1e-6)
    assert len(curves['key_blocks["upper/jawOpen"].value']) == 2       # head and teeth
    back = read_gltf(out)
    sample = report["samples"][0]
    n_teeth, n_eyes = len(made["parts"]["teeth"][0]), len(made["parts"]["eyes"][0])
    slices = {"Teeth": slice(0, n_teeth), "Eyes": slice(n_teeth, n_teeth + n_eyes),
              "head": slice(n_teeth + n_eyes, None)}
    y_up_to_z_up = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    for mesh, sl in slices.items():
        keys = sample["shape_keys"][mesh]
        weights = np.array([keys.get(n, 0.0) for n in back.names])
        expected = back.neutral[sl] + np.tensordot(weights, back.deltas[:, sl], axes=1)
        np.testing.assert_allclose(sample["positions"][mesh], expected @ y_up_to_z_up.T, atol=1e-5, err_msg=mesh)
