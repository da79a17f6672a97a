"""VRM avatars (VRM 1.0 ``VRMC_vrm`` and VRM 0.x ``VRM``): expressions and Perfect Sync morph targets are
key-models, and the animation goes back into the .vrm whole (the extension kept, the head bone turned)."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from facepuppet.export.scene_animation import write_scene_animation
from facepuppet.io.character import load_character
from facepuppet.io.scene import glb_bytes, parse_glb
from scene_characters import skinned_character, world_matrices


def _vrm(rng, version: int) -> bytes:
    doc, blob = parse_glb(skinned_character(rng, head_joint_name="Bone3")["glb"])  # no head name to find
    doc = copy.deepcopy(doc)
    if version == 1:
        doc["extensions"] = {"VRMC_vrm": {
            "specVersion": "1.0", "meta": {"name": "tiny", "licenseUrl": "https://example.org/l"},
            "humanoid": {"humanBones": {"hips": {"node": 1}, "head": {"node": 3}}},
            "expressions": {"preset": {"aa": {"morphTargetBinds": [{"node": 4, "index": 0, "weight": 0.8},
                                                                   {"node": 5, "index": 0, "weight": 0.8}]},
                                       "happy": {"morphTargetBinds": [{"node": 4, "index": 2, "weight": 1.0}]}},
                            "custom": {"smirk": {"morphTargetBinds": [{"node": 4, "index": 2, "weight": 0.5}]}}}}}
        doc["extensionsUsed"] = doc.get("extensionsUsed", []) + ["VRMC_vrm"]
    else:
        doc["extensions"] = {"VRM": {
            "humanoid": {"humanBones": [{"bone": "hips", "node": 1}, {"bone": "head", "node": 3}]},
            "blendShapeMaster": {"blendShapeGroups": [
                {"name": "A", "presetName": "a", "binds": [{"mesh": 0, "index": 0, "weight": 80},
                                                           {"mesh": 1, "index": 0, "weight": 80}]},
                {"name": "Joy", "presetName": "joy", "binds": [{"mesh": 0, "index": 2, "weight": 100}]}]}}}
        doc["extensionsUsed"] = doc.get("extensionsUsed", []) + ["VRM"]
    return glb_bytes(doc, blob)


@pytest.mark.parametrize("version", [1, 0])
def test_vrm_expressions_are_key_models_and_go_back_whole(tmp_path, rng, version):
    path = tmp_path / "avatar.vrm"
    path.write_bytes(_vrm(rng, version))
    c = load_character(path)
    assert {"jawOpen", "eyeBlinkLeft", "mouthSmileLeft", "aa", "happy"} <= set(c.names)  # Perfect Sync + presets
    jaw, aa = c.names.index("jawOpen"), c.names.index("aa")
    np.testing.assert_allclose(c.deltas[aa], 0.8 * c.deltas[jaw], atol=1e-12)  # on the head and the teeth
    np.testing.assert_allclose(c.deltas[c.names.index("happy")], c.deltas[c.names.index("mouthSmileLeft")])

    f = 4
    w = rng.uniform(0, 1, size=(f, 2))
    rot = Rotation.from_euler("YXZ", rng.uniform(-0.3, 0.3, size=(f, 3))).as_matrix()
    out = tmp_path / "out.vrm"
    write_scene_animation(out, c.source, ("aa", "eyeBlinkLeft"), w, 30.0, head_rotation=rot)
    doc_in, _ = parse_glb(path.read_bytes())
    doc, blob = parse_glb(out.read_bytes())
    assert doc["extensions"] == doc_in["extensions"] and doc["nodes"] == doc_in["nodes"]  # kept whole
    anim = doc["animations"][-1]
    by_node = {ch["target"]["node"]: (ch["target"]["path"], ch["sampler"]) for ch in anim["channels"]}
    assert by_node[3][0] == "rotation"  # the humanoid's head bone

    def values(node, width):
        acc = doc["accessors"][anim["samplers"][by_node[node][1]]["output"]]
        view = doc["bufferViews"][acc["bufferView"]]
        return np.frombuffer(blob, np.float32, f * width, view["byteOffset"]).reshape(f, width)

    np.testing.assert_allclose(values(4, 4)[:, 0], 0.8 * w[:, 0], atol=1e-6)   # head jawOpen from aa
    np.testing.assert_allclose(values(4, 4)[:, 1], w[:, 1], atol=1e-6)         # head eyeBlinkLeft
    np.testing.assert_allclose(values(5, 1)[:, 0], 0.8 * w[:, 0], atol=1e-6)   # teeth jawOpen from aa
    rest = world_matrices(doc_in)
    q = values(3, 4)
    posed = copy.deepcopy(doc_in)
    posed["nodes"][3]["rotation"] = [float(x) for x in q[2]]
    np.testing.assert_allclose(world_matrices(posed)[3][:3, :3], rot[2] @ rest[3][:3, :3], atol=1e-5)
