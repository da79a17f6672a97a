"""The animated GLB plays in Blender: its glTF importer reads it, the scene plays it, known answers come out.

Blender runs as the ``bpy`` module in its own venv (``blender_python.py``, ``blender_load.py``). The scene's frame
rate is set to the file's, so the importer keys frame f of the performance at Blender's frame f. Blender is z-up:
the importer maps glTF's (x, y, z) to (x, -z, y), so the expected positions and rotations are mapped the same
way before they are compared.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from animated_scenes import head_scene, make_character, morphed
from blender_python import blender  # noqa: F401  (fixture)
from facepuppet.demo.toy import toy_character
from facepuppet.export.gltf_animation import write_animated_glb

#: glTF's axes to Blender's: (x, y, z) -> (x, -z, y).
Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def in_blender(points: np.ndarray) -> np.ndarray:
    """Points (..., 3) in glTF's axes, in Blender's."""
    return points @ Y_UP_TO_Z_UP.T


def rotation_in_blender(rotation: Rotation) -> np.ndarray:
    """A rotation in glTF's axes as a 3 × 3 matrix in Blender's."""
    return Y_UP_TO_Z_UP @ rotation.as_matrix() @ Y_UP_TO_Z_UP.T


def shape_key_values(sample: dict, mesh: str, names) -> np.ndarray:
    return np.array([sample["shape_keys"][mesh][n] for n in names])


def weight_curves(action: dict, names) -> list[dict]:
    """The F-curves of the shape-key values, in the order of ``names``."""
    by_path = {fc["data_path"]: fc for fc in action["fcurves"]}
    return [by_path[f'key_blocks["{n}"].value'] for n in names]


def test_weights_play_in_blender(tmp_path, rng, blender):  # noqa: F811
    c = make_character(rng)
    f, fps, m = 25, 30, 4
    weights = rng.uniform(0, 1, size=(f, m))
    path = tmp_path / "anim.glb"
    write_animated_glb(path, c, weights, fps)
    out = blender.load(path, fps, [7, 12.5, f - 1])

    (mesh,) = out["meshes"]
    assert mesh["vertices"] == len(c.neutral)
    assert mesh["shape_keys"] == ["Basis", *c.names]
    assert mesh["use_relative"] is True and set(mesh["relative_to"]) == {"Basis"}
    (action,) = out["actions"]
    assert action["name"] == "performance"
    np.testing.assert_allclose(action["frame_range"], [0, f - 1], atol=1e-4)  # f frames, the first at 0
    curves = weight_curves(action, c.names)
    assert len(action["fcurves"]) == m
    for i, fc in enumerate(curves):
        assert fc["interpolations"] == ["LINEAR"]
        np.testing.assert_allclose(fc["frames"], np.arange(f), atol=1e-4)
        np.testing.assert_allclose(fc["values"], weights[:, i], atol=1e-6)

    at7, between, last = out["samples"]
    np.testing.assert_allclose(shape_key_values(at7, mesh["name"], c.names), weights[7], atol=1e-5)
    np.testing.assert_allclose(shape_key_values(between, mesh["name"], c.names), (weights[12] + weights[13]) / 2,
                               atol=1e-5)
    np.testing.assert_allclose(shape_key_values(last, mesh["name"], c.names), weights[-1], atol=1e-5)
    np.testing.assert_allclose(at7["positions"][mesh["name"]], in_blender(morphed(c, weights[7])), atol=1e-5)
    np.testing.assert_allclose(last["positions"][mesh["name"]], in_blender(morphed(c, weights[-1])), atol=1e-5)


def test_head_rotation_plays_in_blender(tmp_path, rng, blender):  # noqa: F811
    s = head_scene(tmp_path, rng)  # frame 4 lost: neutral
    c, weights, rot, pivot, fps, path = s.character, s.weights, s.rotation, s.pivot, s.fps, s.path
    f = len(weights)
    out = blender.load(path, fps, [4, 6, 8.5])

    (mesh,) = out["meshes"]
    name = mesh["name"]
    assert out["objects"]["head"] == {"type": "EMPTY", "parent": None}
    assert out["objects"][name]["parent"] == "head"
    (action,) = out["actions"]
    np.testing.assert_allclose(action["frame_range"], [0, f - 1], atol=1e-4)
    turns = [fc for fc in action["fcurves"] if fc["data_path"] == "rotation_quaternion"]
    assert sorted(fc["index"] for fc in turns) == [0, 1, 2, 3]
    for fc in turns:
        np.testing.assert_allclose(fc["frames"], np.arange(f), atol=1e-4)

    lost, at6, between = out["samples"]
    np.testing.assert_array_equal(shape_key_values(lost, name, c.names), [0, 0, 0])
    np.testing.assert_allclose(lost["positions"][name], in_blender(pivot + rot[4].apply(c.neutral - pivot)),
                               atol=1e-5)
    np.testing.assert_allclose(shape_key_values(at6, name, c.names), weights[6], atol=1e-5)
    head6 = np.array(at6["matrix_world"]["head"])
    np.testing.assert_allclose(head6[:3, :3], rotation_in_blender(rot[6]), atol=1e-5)
    np.testing.assert_allclose(head6[:3, 3], in_blender(pivot), atol=1e-6)
    # the head turns about the pivot: world = pivot + R (Eq. 14 - pivot)
    expect = pivot + rot[6].apply(morphed(c, weights[6]) - pivot)
    np.testing.assert_allclose(at6["positions"][name], in_blender(expect), atol=1e-5)
    # between two keys: weights blend linearly; Blender blends the quaternion's components and normalises,
    # which halfway between two keys is the slerp
    np.testing.assert_allclose(shape_key_values(between, name, c.names), (weights[8] + weights[9]) / 2, atol=1e-5)
    halfway = Slerp([0, 1], rot[[8, 9]])(0.5)
    np.testing.assert_allclose(np.array(between["matrix_world"]["head"])[:3, :3], rotation_in_blender(halfway),
                               atol=1e-5)


def test_toy_animation_plays_in_blender(tmp_path, blender):  # noqa: F811
    """The GLB ``facepuppet animate`` and the demo write for the Toy (default pivot), with a weight above 1."""
    c = toy_character()
    m, f, fps = len(c.names), 10, 30
    rng = np.random.default_rng(11)
    weights = rng.uniform(0, 1, size=(f, m))
    weights[5, 2] = 1.4  # --gain above 1 lets a weight exceed 1
    rot = Rotation.from_euler("YXZ", rng.uniform(-0.3, 0.3, size=(f, 3)))
    path = tmp_path / "animation.glb"
    write_animated_glb(path, c, weights, fps, head_rotation=rot.as_matrix())
    out = blender.load(path, fps, [5, 6])

    (mesh,) = out["meshes"]
    assert mesh["shape_keys"] == ["Basis", *c.names] and mesh["vertices"] == len(c.neutral)
    (action,) = out["actions"]
    np.testing.assert_allclose(action["frame_range"], [0, f - 1], atol=1e-4)
    for i, fc in enumerate(weight_curves(action, c.names)):
        np.testing.assert_allclose(fc["values"], weights[:, i], atol=1e-6)  # 1.4 included
    at5, at6 = out["samples"]
    # Blender clips a shape key's value to its slider range, [0, 1] unless the importer widens it; Blender
    # 5.0's importer widens it from each curve's first key only, so the 1.4 of frame 5 plays as 1 (the F-curve
    # holds 1.4; raising the key's Range Max in Blender restores it). The README says so.
    assert mesh["slider_ranges"][1 + 2] == [0.0, 1.0]
    np.testing.assert_allclose(shape_key_values(at5, mesh["name"], c.names), np.minimum(weights[5], 1), atol=1e-5)
    np.testing.assert_allclose(shape_key_values(at6, mesh["name"], c.names), weights[6], atol=1e-5)
    pivot = (c.neutral.min(axis=0) + c.neutral.max(axis=0)) / 2
    expect = pivot + rot[6].apply(morphed(c, weights[6]) - pivot)
    scale = np.abs(c.neutral).max()
    np.testing.assert_allclose(at6["positions"][mesh["name"]], in_blender(expect), atol=1e-5 * scale)
