"""The performance written into the character's own scene: everything kept, one animation added (Eq. 14)."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from blender_python import blender  # noqa: F401  (fixture)
from facepuppet.export.scene_animation import find_head_joint, write_scene_animation
from facepuppet.io.gltf import read_gltf
from facepuppet.io.scene import parse_glb
from gltf_validator import gltf_validator  # noqa: F401  (fixture)
from scene_characters import HEAD_DEFAULTS, skinned_character, world_matrices
from three_loader import three_loader  # noqa: F401  (fixture)

DRIVEN = ("jawOpen", "eyeBlinkLeft", "mouthSmileLeft")


def _accessor(doc, blob, index) -> np.ndarray:
    acc = doc["accessors"][index]
    view = doc["bufferViews"][acc["bufferView"]]
    width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}[acc["type"]]
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    return np.frombuffer(blob, np.float32, acc["count"] * width, start).reshape(acc["count"], width)


def _written(tmp_path, rng, *, rotation=True, **kw):
    made = skinned_character(rng, **kw)
    src = tmp_path / "char.glb"
    src.write_bytes(made["glb"])
    character = read_gltf(src)
    f = 6
    weights = rng.uniform(0, 1, size=(f, len(DRIVEN)))
    rot = Rotation.from_euler("YXZ", rng.uniform(-0.4, 0.4, size=(f, 3))).as_matrix() if rotation else None
    out = tmp_path / "out.glb"
    write_scene_animation(out, character.source, DRIVEN, weights, 30.0, head_rotation=rot,
                          pivot=np.array([0.0, 1.7, 0.0]))
    return made, character, weights, rot, out


def test_reader_joins_meshes_and_keeps_the_source(tmp_path, rng):
    made = skinned_character(rng)
    (tmp_path / "c.glb").write_bytes(made["glb"])
    c = read_gltf(tmp_path / "c.glb")
    assert c.names == ("jawOpen", "eyeBlinkLeft", "mouthSmileLeft", "extraShape")
    assert len(c.neutral) == 40 + 12 + 10
    assert parse_glb(c.source) == parse_glb(made["glb"])  # a plain GLB is kept: same JSON, same bytes


def test_everything_not_animated_is_identical(tmp_path, rng, gltf_validator):  # noqa: F811
    made, character, weights, rot, out = _written(tmp_path, rng)
    doc_in, blob_in = parse_glb(made["glb"])
    doc_out, blob_out = parse_glb(out.read_bytes())
    assert blob_out[:len(blob_in)] == blob_in  # every accessor's bytes untouched
    expect = copy.deepcopy(doc_in)
    n_views, n_acc = len(doc_in["bufferViews"]), len(doc_in["accessors"])
    assert doc_out["bufferViews"][:n_views] == doc_in["bufferViews"]
    assert doc_out["accessors"][:n_acc] == doc_in["accessors"]
    added = doc_out["animations"][-1]
    for key in ("bufferViews", "accessors", "animations"):
        expect[key] = doc_out[key]
    expect["buffers"][0]["byteLength"] = len(blob_out)
    assert doc_out == expect  # nothing else changed: no node added (the head joint turns)
    assert len(doc_out["animations"]) == 2 and doc_out["animations"][0] == doc_in["animations"][0]
    gltf_validator.check(out)

    targets = {c["target"]["node"]: (c["target"]["path"], c["sampler"]) for c in added["channels"]}
    assert set(targets) == {3, 4, 5, 6}  # the head joint and the three meshes' nodes
    head_w = _accessor(doc_out, blob_out, added["samplers"][targets[4][1]]["output"]).reshape(6, 4)
    np.testing.assert_allclose(head_w[:, :3], weights, atol=1e-6)
    np.testing.assert_allclose(head_w[:, 3], HEAD_DEFAULTS[3], atol=1e-7)  # not driven: the file's default
    teeth_w = _accessor(doc_out, blob_out, added["samplers"][targets[5][1]]["output"]).reshape(6, 1)
    np.testing.assert_allclose(teeth_w[:, 0], weights[:, 0], atol=1e-6)
    eyes_w = _accessor(doc_out, blob_out, added["samplers"][targets[6][1]]["output"]).reshape(6, 1)
    np.testing.assert_allclose(eyes_w[:, 0], weights[:, 1], atol=1e-6)

    # the head joint's new local rotation turns it by R_f in scene space: world = R_f · rest world
    assert targets[3][0] == "rotation"
    quats = _accessor(doc_out, blob_out, added["samplers"][targets[3][1]]["output"])
    rest = world_matrices(doc_in)
    for frame in range(6):
        posed = copy.deepcopy(doc_in)
        posed["nodes"][3]["rotation"] = [float(x) for x in quats[frame]]
        world = world_matrices(posed)[3][:3, :3]
        np.testing.assert_allclose(world, rot[frame] @ rest[3][:3, :3], atol=1e-5)


def test_eq14_per_mesh(tmp_path, rng):
    made, character, weights, _, out = _written(tmp_path, rng, rotation=False)
    doc, blob = parse_glb(out.read_bytes())
    world = world_matrices(doc)
    full = np.zeros((len(weights), 4))
    full[:, :3] = weights
    full[:, 3] = HEAD_DEFAULTS[3]
    expected = character.neutral[None] + np.einsum("fk,kvd->fvd", full, character.deltas)   # Eq. 14
    offset = 0
    for name, node in (("teeth", 5), ("eyes", 6), ("head", 4)):  # the reader's order: depth first
        base, deltas, _ = made["parts"][name]
        k = len(deltas)
        w = full[:, :k] if name == "head" else full[:, [0]] if name == "teeth" else full[:, [1]]
        local = base[None] + np.einsum("fk,kvd->fvd", w, deltas)
        m = np.eye(4) if name == "head" else world[node]  # the skinned head is in its bind pose
        shown = local @ m[:3, :3].T + m[:3, 3]
        np.testing.assert_allclose(shown, expected[:, offset:offset + len(base)], atol=1e-5)
        offset += len(base)


def test_no_head_joint_adds_one_pivot_node(tmp_path, rng, gltf_validator):  # noqa: F811
    made, character, weights, rot, out = _written(tmp_path, rng, head_joint_name="Bone3", skinned=False)
    doc_in, _ = parse_glb(made["glb"])
    doc_out, _ = parse_glb(out.read_bytes())
    assert find_head_joint(doc_in) is None
    assert len(doc_out["nodes"]) == len(doc_in["nodes"]) + 1
    head = len(doc_in["nodes"])
    assert doc_out["nodes"][head]["name"] == "facepuppet_head"
    assert doc_out["nodes"][head]["children"] == [1, 4]  # below the faces' lowest common ancestor
    assert doc_out["nodes"][0]["children"] == [head] and doc_out["scenes"] == doc_in["scenes"]
    gltf_validator.check(out)
    anim = doc_out["animations"][-1]
    by_path = {c["target"]["path"]: c["sampler"] for c in anim["channels"] if c["target"]["node"] == head}
    _, blob = parse_glb(out.read_bytes())
    q = _accessor(doc_out, blob, anim["samplers"][by_path["rotation"]]["output"])
    t = _accessor(doc_out, blob, anim["samplers"][by_path["translation"]]["output"])
    rest = world_matrices(doc_out)
    pivot = np.array([0.0, 1.7, 0.0])
    for frame in range(len(rot)):
        posed = copy.deepcopy(doc_out)
        posed["nodes"][head]["rotation"] = [float(x) for x in q[frame]]
        posed["nodes"][head]["translation"] = [float(x) for x in t[frame]]
        turn = np.eye(4)
        turn[:3, :3], turn[:3, 3] = rot[frame], pivot - rot[frame] @ pivot
        for node in (4, 5, 6):  # each face node turns by R_f about the pivot, in scene space
            np.testing.assert_allclose(world_matrices(posed)[node], turn @ rest[node], atol=1e-5)


@pytest.mark.parametrize("name", ["Head", "mixamorig:Head", "J_Bip_C_Head", "DEF-head", "Armature|head"])
def test_head_joint_names(name):
    doc = {"nodes": [{"name": "Hips"}, {"name": name}], "skins": [{"joints": [0, 1]}]}
    assert find_head_joint(doc) == 1
    doc["nodes"][1]["name"] = "Headlight"
    assert find_head_joint(doc) is None


def test_whole_scene_plays_in_threejs(tmp_path, rng, three_loader):  # noqa: F811
    made, character, weights, _, out = _written(tmp_path, rng, rotation=False)
    t = float(np.float32(3 / 30.0))
    report = three_loader.play(out, [t], clip="performance")
    assert {c["name"] for c in report["clips"]} == {"idle", "performance"}
    assert {m["name"] for m in report["meshes"]} >= {"HeadMesh", "Teeth", "Eyes"}
    full = np.concatenate([weights[3], [HEAD_DEFAULTS[3]]])
    expected = character.neutral + np.tensordot(full, character.deltas, axes=1)  # Eq. 14
    shown = report["samples"][0]["meshPositions"]
    n_teeth, n_eyes = len(made["parts"]["teeth"][0]), len(made["parts"]["eyes"][0])
    np.testing.assert_allclose(shown["Teeth"], expected[:n_teeth], atol=1e-5)
    np.testing.assert_allclose(shown["Eyes"], expected[n_teeth:n_teeth + n_eyes], atol=1e-5)
    np.testing.assert_allclose(shown["HeadMesh"], expected[n_teeth + n_eyes:], atol=1e-5)  # skinned, bind pose


def test_whole_scene_loads_in_blender(tmp_path, rng, blender):  # noqa: F811
    """Blender imports both animations as actions and shows the idle one; the performance's action holds the
    weights of every mesh, and each mesh's evaluated vertices are Eq. 14 at the shape-key values shown."""
    made, character, weights, _, out = _written(tmp_path, rng, rotation=False)
    report = blender.load(out, 30, [3])
    assert {"Teeth", "Eyes", "head"} <= {m["name"] for m in report["meshes"]}
    (action,) = [a for a in report["actions"] if a["name"].startswith("performance")]
    curves = {}
    for fc in action["fcurves"]:
        curves.setdefault(fc["data_path"], []).append(fc["values"])
    for name, k in (("jawOpen", 0), ("eyeBlinkLeft", 1), ("mouthSmileLeft", 2)):
        for values in curves[f'key_blocks["{name}"].value']:  # head, teeth and eyes carry the same curve
            np.testing.assert_allclose(values, weights[:, k], atol=1e-6)
    assert len(curves['key_blocks["jawOpen"].value']) == 2 and 'key_blocks["extraShape"].value' in curves
    sample = report["samples"][0]
    n_teeth, n_eyes = len(made["parts"]["teeth"][0]), len(made["parts"]["eyes"][0])
    slices = {"Teeth": slice(0, n_teeth), "Eyes": slice(n_teeth, n_teeth + n_eyes),
              "head": slice(n_teeth + n_eyes, None)}
    y_up_to_z_up = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    for mesh, sl in slices.items():
        keys = sample["shape_keys"][mesh]
        w = np.array([keys.get(n, 0.0) for n in character.names])
        expected = character.neutral[sl] + np.tensordot(w, character.deltas[:, sl], axes=1)  # Eq. 14
        np.testing.assert_allclose(sample["positions"][mesh], expected @ y_up_to_z_up.T, atol=1e-5, err_msg=mesh)


def test_gltf_output_is_json_with_the_buffer_embedded(tmp_path, rng, gltf_validator):  # noqa: F811
    made = skinned_character(rng)
    (tmp_path / "c.glb").write_bytes(made["glb"])
    character = read_gltf(tmp_path / "c.glb")
    out = tmp_path / "out.gltf"
    write_scene_animation(out, character.source, DRIVEN, rng.uniform(0, 1, size=(3, 3)), 30.0)
    assert out.read_text(encoding="utf-8").lstrip().startswith("{")
    gltf_validator.check(out)
    back = read_gltf(out)
    assert back.names == character.names
    np.testing.assert_array_equal(back.targets, character.targets)
