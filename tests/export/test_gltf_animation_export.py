"""The animated GLB: validator-clean, morph targets = key-models, weights and head rotation keyed per frame."""

from __future__ import annotations

import numpy as np
import pygltflib
import pytest
from scipy.spatial.transform import Rotation

from facepuppet.export.gltf_animation import rotation_quaternions, write_animated_glb
from facepuppet.io.character import Character
from facepuppet.io.gltf import quaternion_matrix, read_gltf
from gltf_validator import gltf_validator  # noqa: F401  (fixture)


def make_character(rng, v=30, m=4) -> Character:
    base = rng.normal(size=(v, 3)).astype(np.float32).astype(np.float64)
    faces = np.array([[i, i + 1, i + 2] for i in range(v - 2)])
    return Character(base, base[None] + rng.normal(size=(m, v, 3)) * 0.05, tuple(f"k{i}" for i in range(m)),
                     faces, "toy")


def read_accessor(g: pygltflib.GLTF2, index: int) -> np.ndarray:
    acc = g.accessors[index]
    view = g.bufferViews[acc.bufferView]
    width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}[acc.type]
    start = (view.byteOffset or 0) + (acc.byteOffset or 0)
    return np.frombuffer(g.binary_blob(), np.float32, acc.count * width, start).reshape(acc.count, width)


def test_weights_animation(tmp_path, rng, gltf_validator):  # noqa: F811
    c = make_character(rng)
    f, fps = 25, 30.0
    weights = rng.uniform(0, 1, size=(f, 4))
    path = tmp_path / "anim.glb"
    write_animated_glb(path, c, weights, fps)
    report = gltf_validator.check(path)
    assert report["issues"]["numWarnings"] == 0
    g = pygltflib.GLTF2.load(str(path))
    (anim,) = g.animations
    (sampler,) = anim.samplers
    assert sampler.interpolation == "LINEAR" and anim.channels[0].target.path == "weights"
    times = read_accessor(g, sampler.input)[:, 0]
    np.testing.assert_array_equal(times, (np.arange(f) / fps).astype(np.float32))
    out = read_accessor(g, sampler.output)
    assert out.shape == (f * 4, 1)
    np.testing.assert_array_equal(out[:, 0], weights.astype(np.float32).reshape(-1))
    back = read_gltf(path)
    assert back.names == c.names
    np.testing.assert_allclose(back.targets, c.targets, atol=1e-6)


def test_head_rotation_channel(tmp_path, rng, gltf_validator):  # noqa: F811
    c = make_character(rng, m=2)
    f = 12
    rot = Rotation.from_euler("YXZ", rng.uniform(-0.5, 0.5, size=(f, 3))).as_matrix()
    weights = rng.uniform(0, 1, size=(f, 2))
    weights[3] = np.nan  # a lost frame: written as neutral
    rot[5] = np.nan
    pivot = np.array([0.5, -1.0, 0.25])
    path = tmp_path / "head.glb"
    write_animated_glb(path, c, weights, 24.0, head_rotation=rot, pivot=pivot, normals=True)
    gltf_validator.check(path)
    g = pygltflib.GLTF2.load(str(path))
    anim = g.animations[0]
    head = anim.channels[1].target.node
    assert anim.channels[1].target.path == "rotation" and g.nodes[head].name == "head"
    np.testing.assert_allclose(g.nodes[head].translation, pivot)
    mesh_node = g.nodes[head].children[0]
    np.testing.assert_allclose(g.nodes[mesh_node].translation, -pivot)
    assert g.scenes[0].nodes == [head]
    quats = read_accessor(g, anim.samplers[1].output).astype(np.float64)
    for i in range(f):
        expect = np.eye(3) if i == 5 else rot[i]
        np.testing.assert_allclose(quaternion_matrix(quats[i]), expect, atol=1e-6)
    w = read_accessor(g, anim.samplers[0].output).reshape(f, 2)
    np.testing.assert_array_equal(w[3], 0)
    # the rest pose (identity head, zero weights) is the character as read
    back = read_gltf(path)
    np.testing.assert_allclose(back.neutral, c.neutral, atol=1e-6)


@pytest.mark.parametrize("axis", [[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]])
@pytest.mark.parametrize("angle", [0.0, 0.7, np.pi - 1e-9, np.pi])
def test_rotation_quaternions_known_answers(axis, angle):
    rv = np.asarray(axis, float) / np.linalg.norm(axis) * angle
    r = Rotation.from_rotvec(rv)
    q = rotation_quaternions(r.as_matrix()[None])[0]
    expect = r.as_quat()  # scipy's order is (x, y, z, w), as glTF's
    assert np.isclose(abs(np.dot(q, expect)), 1, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(q), 1)


def test_rotation_quaternions_stay_in_one_hemisphere():
    angles = np.linspace(0, 4 * np.pi, 50)
    q = rotation_quaternions(Rotation.from_euler("y", angles[:, None]).as_matrix())
    assert np.all(np.sum(q[1:] * q[:-1], axis=1) > 0)
    bad = np.stack([np.eye(3) * 2, np.full((3, 3), np.inf)])
    np.testing.assert_array_equal(rotation_quaternions(bad), [[0, 0, 0, 1], [0, 0, 0, 1]])


def test_bad_arguments_write_nothing(tmp_path, rng):
    c = make_character(rng, m=2)
    path = tmp_path / "x.glb"
    with pytest.raises(ValueError, match=r"weights must have shape \(F, 2\)"):
        write_animated_glb(path, c, np.zeros((5, 3)), 30)
    with pytest.raises(ValueError, match="F >= 1"):
        write_animated_glb(path, c, np.zeros((0, 2)), 30)
    with pytest.raises(ValueError, match="fps"):
        write_animated_glb(path, c, np.zeros((5, 2)), 0)
    with pytest.raises(ValueError, match=r"head_rotation must have shape \(5, 3, 3\)"):
        write_animated_glb(path, c, np.zeros((5, 2)), 30, head_rotation=np.zeros((4, 3, 3)))
    assert not list(tmp_path.iterdir())


def test_ict_animation_is_valid(tmp_path, ict, gltf_validator):  # noqa: F811
    m = 10
    c = Character(ict["neutral"].astype(np.float64),
                  (ict["neutral"][None] + ict["expr_deltas"][:m]).astype(np.float64),
                  tuple(str(n) for n in ict["expr_names"][:m]), ict["faces"], "ict")
    rng = np.random.default_rng(0)
    f = 60
    rot = Rotation.from_euler("YXZ", rng.uniform(-0.3, 0.3, size=(f, 3))).as_matrix()
    path = tmp_path / "ict_anim.glb"
    write_animated_glb(path, c, rng.uniform(0, 1, size=(f, m)), 30.0, head_rotation=rot, normals=True)
    gltf_validator.check(path)
