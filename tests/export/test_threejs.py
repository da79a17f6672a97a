"""The animated GLB plays in three.js: GLTFLoader reads it, an AnimationMixer plays it, known answers come out.

three.js runs in Node (``three_load.mjs``): the influences, the head quaternion and the world-space vertex
positions it computes at a time are compared with what was written for that frame (and, between two frames,
with their linear / spherical-linear blend).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from animated_scenes import head_scene, make_character, morphed
from facepuppet.export.gltf_animation import write_animated_glb
from facepuppet.io.character import Character
from three_loader import three_loader  # noqa: F401  (fixture)


def key_time(frame: int, fps: float) -> float:
    """The time of a frame's key as stored (float32), so three.js lands on the key itself."""
    return float(np.float32(frame / fps))


def test_weights_play_in_threejs(tmp_path, rng, three_loader):  # noqa: F811
    c = make_character(rng)
    f, fps, m = 25, 30.0, 4
    weights = rng.uniform(0, 1, size=(f, m))
    path = tmp_path / "anim.glb"
    write_animated_glb(path, c, weights, fps)
    mid = (key_time(12, fps) + key_time(13, fps)) / 2
    out = three_loader.play(path, [key_time(7, fps), mid, key_time(f - 1, fps)])

    (mesh,) = out["meshes"]
    assert mesh["influences"] == m and mesh["relative"] is True
    assert mesh["dictionary"] == {name: i for i, name in enumerate(c.names)}
    (clip,) = out["clips"]
    assert clip["name"] == "performance"
    np.testing.assert_allclose(clip["duration"], (f - 1) / fps, rtol=1e-6)
    (track,) = clip["tracks"]
    assert track["name"].endswith(".morphTargetInfluences") and track["type"] == "number"
    assert track["keys"] == f and track["valueSize"] == m

    at7, between, last = out["samples"]
    np.testing.assert_allclose(at7["influences"], weights[7], atol=1e-6)
    np.testing.assert_allclose(between["influences"], (weights[12] + weights[13]) / 2, atol=1e-6)
    np.testing.assert_allclose(last["influences"], weights[-1], atol=1e-6)
    np.testing.assert_allclose(at7["positions"], morphed(c, weights[7]), atol=1e-5)


def test_head_rotation_plays_in_threejs(tmp_path, rng, three_loader):  # noqa: F811
    s = head_scene(tmp_path, rng)  # frame 4 lost: neutral
    c, weights, rot, pivot, fps, path = s.character, s.weights, s.rotation, s.pivot, s.fps, s.path
    f = len(weights)
    mid = (key_time(8, fps) + key_time(9, fps)) / 2
    out = three_loader.play(path, [key_time(4, fps), key_time(6, fps), mid])

    (clip,) = out["clips"]
    np.testing.assert_allclose(clip["duration"], (f - 1) / fps, rtol=1e-6)
    tracks = {t["name"]: t for t in clip["tracks"]}
    assert tracks["head.quaternion"]["type"] == "quaternion" and tracks["head.quaternion"]["valueSize"] == 4
    (morph,) = [t for name, t in tracks.items() if name.endswith(".morphTargetInfluences")]
    assert morph["keys"] == f and morph["valueSize"] == 3

    lost, at6, between = out["samples"]
    np.testing.assert_array_equal(lost["influences"], [0, 0, 0])
    np.testing.assert_allclose(at6["influences"], weights[6], atol=1e-6)
    q6 = Rotation.from_quat(at6["quaternions"]["head"])  # three.js's (x, y, z, w), as scipy's
    assert (q6 * rot[6].inv()).magnitude() < 1e-6
    # the head turns about the pivot: world = pivot + R (Eq. 14 - pivot)
    expect = pivot + rot[6].apply(morphed(c, weights[6]) - pivot)
    np.testing.assert_allclose(at6["positions"], expect, atol=1e-5)
    # between two keys: weights blend linearly, the head by slerp
    np.testing.assert_allclose(between["influences"], (weights[8] + weights[9]) / 2, atol=1e-6)
    halfway = Slerp([0, 1], rot[[8, 9]])(0.5)
    assert (Rotation.from_quat(between["quaternions"]["head"]) * halfway.inv()).magnitude() < 1e-5


def test_ict_character_plays_in_threejs(tmp_path, ict, three_loader):  # noqa: F811
    c = Character(ict["neutral"].astype(np.float64), (ict["neutral"][None] + ict["expr_deltas"]).astype(np.float64),
                  tuple(str(n) for n in ict["expr_names"]), ict["faces"], "ict")
    m, f, fps = len(c.names), 30, 30.0
    rng = np.random.default_rng(7)
    weights = rng.uniform(0, 1, size=(f, m))
    rot = Rotation.from_euler("YXZ", rng.uniform(-0.3, 0.3, size=(f, 3)))
    path = tmp_path / "ict.glb"
    write_animated_glb(path, c, weights, fps, head_rotation=rot.as_matrix(), normals=True)
    out = three_loader.play(path, [key_time(17, fps)])

    (mesh,) = out["meshes"]
    assert mesh["influences"] == m and mesh["dictionary"]["eyeBlink_L"] == c.names.index("eyeBlink_L")
    assert list(mesh["dictionary"]) == list(c.names)
    (sample,) = out["samples"]
    np.testing.assert_allclose(sample["influences"], weights[17], atol=1e-6)
    pivot = (c.neutral.min(axis=0) + c.neutral.max(axis=0)) / 2
    expect = pivot + rot[17].apply(morphed(c, weights[17]) - pivot)
    scale = np.abs(c.neutral).max()
    np.testing.assert_allclose(sample["positions"], expect, atol=1e-5 * scale)
