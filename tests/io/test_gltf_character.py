"""Characters in glTF: round trips through the writer, and hand-built files covering the reader's branches."""

from __future__ import annotations

import base64
import json

import numpy as np
import pygltflib
import pytest

from facepuppet.errors import FacepuppetError
from facepuppet.io.character import Character, load_character, save_character
from facepuppet.io.gltf import quaternion_matrix, read_gltf, write_glb
from gltf_validator import gltf_validator  # noqa: F401  (fixture)


def make_character(rng, v=40, m=3, name="toy") -> Character:
    neutral = rng.normal(size=(v, 3)).astype(np.float32).astype(np.float64)
    deltas = (rng.normal(size=(m, v, 3)) * 0.1).astype(np.float32).astype(np.float64)
    faces = np.array([[i, (i + 1) % v, (i + 2) % v] for i in range(0, v - 2, 2)])
    return Character(neutral, neutral[None] + deltas, tuple(f"key{i}" for i in range(m)), faces, name)


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
def test_round_trip_gives_identical_arrays_and_names(tmp_path, rng, gltf_validator, suffix):  # noqa: F811
    c = make_character(rng)
    path = tmp_path / f"toy{suffix}"
    save_character(path, c)
    gltf_validator.check(path)
    back = load_character(path)
    assert back.names == c.names and back.name == "toy"
    np.testing.assert_array_equal(back.neutral, c.neutral)
    stored = (c.targets - c.neutral).astype(np.float32)  # morph targets hold float32 deltas
    np.testing.assert_array_equal(back.targets, c.neutral + stored)
    np.testing.assert_allclose(back.targets, c.targets, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(back.faces, c.faces)


def test_normals_are_written_unit_and_valid(tmp_path, rng, gltf_validator):  # noqa: F811
    c = make_character(rng)
    path = tmp_path / "n.glb"
    write_glb(path, c, normals=True)
    report = gltf_validator.check(path)
    assert report["issues"]["numWarnings"] == 0
    g = pygltflib.GLTF2.load(str(path))
    assert g.meshes[0].primitives[0].attributes.NORMAL is not None
    assert g.meshes[0].extras["targetNames"] == list(c.names)


def test_ict_character_writes_a_valid_glb_and_reads_back(tmp_path, ict, gltf_validator):  # noqa: F811
    names = tuple(str(n) for n in ict["expr_names"][:12])
    c = Character(ict["neutral"].astype(np.float64), (ict["neutral"][None] + ict["expr_deltas"][:12]).astype(
        np.float64), names, ict["faces"], "ict")
    path = tmp_path / "ict.glb"
    write_glb(path, c, normals=True)
    gltf_validator.check(path)
    back = read_gltf(path)
    np.testing.assert_array_equal(back.neutral, ict["neutral"])
    np.testing.assert_allclose(back.targets, c.targets, atol=1e-5)
    assert back.names == names


def test_write_rejects_bad_characters(tmp_path, rng):
    c = make_character(rng)
    with pytest.raises(ValueError, match="normals need"):
        write_glb(tmp_path / "x.glb", Character(c.neutral, c.targets, c.names), normals=True)
    bad = Character(c.neutral, c.targets, c.names, faces=c.faces + 1000)
    with pytest.raises(ValueError, match="face indices"):
        write_glb(tmp_path / "x.glb", bad)
    nan = c.neutral.copy()
    nan[0, 0] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        write_glb(tmp_path / "x.glb", Character(nan, c.targets, c.names))
    assert not list(tmp_path.iterdir())


# ------------------------------------------------------------------------- hand-built files (pygltflib)

class Asset:
    """A glTF asset built piece by piece with pygltflib, saved as GLB, .gltf + .bin, or .gltf with a data URI."""

    def __init__(self) -> None:
        self.g = pygltflib.GLTF2(asset=pygltflib.Asset(version="2.0"))
        self.blob = bytearray()

    def view(self, data: bytes, stride: int | None = None) -> int:
        while len(self.blob) % 4:
            self.blob.append(0)
        self.g.bufferViews.append(pygltflib.BufferView(buffer=0, byteOffset=len(self.blob),
                                                       byteLength=len(data), byteStride=stride))
        self.blob.extend(data)
        return len(self.g.bufferViews) - 1

    def accessor(self, array, *, normalized=False, view=True, sparse=None, stride=None, offset=0) -> int:
        array = np.asarray(array)
        component = {np.int8: 5120, np.uint8: 5121, np.int16: 5122, np.uint16: 5123, np.uint32: 5125,
                     np.float32: 5126}[array.dtype.type]
        width = 1 if array.ndim == 1 else array.shape[1]
        acc = pygltflib.Accessor(componentType=component, count=len(array), normalized=normalized or None,
                                 type={1: "SCALAR", 3: "VEC3"}[width])
        if view:
            if stride is None:
                data = array.tobytes()
            else:  # interleave: each item followed by padding up to the stride
                item = array.itemsize * width
                rows = [array[i].tobytes() + b"\xee" * (stride - item) for i in range(len(array))]
                data = b"\xaa" * offset + b"".join(rows)
            acc.bufferView = self.view(data, stride)
            acc.byteOffset = offset
        if sparse is not None:
            idx, values = sparse
            acc.sparse = pygltflib.Sparse(
                count=len(idx),
                indices=pygltflib.AccessorSparseIndices(bufferView=self.view(np.asarray(idx, np.uint16).tobytes()),
                                                        componentType=5123),
                values=pygltflib.AccessorSparseValues(bufferView=self.view(np.asarray(values).tobytes())))
        self.g.accessors.append(acc)
        return len(self.g.accessors) - 1

    def mesh(self, primitives, names=None, name="face") -> int:
        self.g.meshes.append(pygltflib.Mesh(name=name, primitives=primitives,
                                            extras={"targetNames": names} if names is not None else {}))
        return len(self.g.meshes) - 1

    def primitive(self, positions, deltas, faces=None, **kw) -> pygltflib.Primitive:
        pos = self.accessor(np.asarray(positions, np.float32))
        targets = [pygltflib.Attributes(POSITION=self.accessor(d, **kw) if d is not None else None)
                   for d in deltas]
        indices = None if faces is None else self.accessor(np.asarray(faces, np.uint16).reshape(-1))
        return pygltflib.Primitive(attributes=pygltflib.Attributes(POSITION=pos), targets=targets,
                                   indices=indices)

    def save(self, path, kind="glb"):
        while len(self.blob) % 4:
            self.blob.append(0)
        self.g.buffers = [pygltflib.Buffer(byteLength=len(self.blob))]
        if kind == "glb":
            self.g.set_binary_blob(bytes(self.blob))
            self.g.save_binary(str(path))
        elif kind == "bin":
            (path.parent / "face data.bin").write_bytes(bytes(self.blob))
            self.g.buffers[0].uri = "face%20data.bin"
            self.g.save_json(str(path))
        else:
            self.g.buffers[0].uri = "data:application/octet-stream;base64," + base64.b64encode(
                bytes(self.blob)).decode()
            self.g.save_json(str(path))
        return path


def one_mesh_asset(positions, deltas, names=("a", "b"), **kw) -> Asset:
    a = Asset()
    a.mesh([a.primitive(positions, deltas, faces=[[0, 1, 2]], **kw)], names=list(names))
    a.g.nodes = [pygltflib.Node(mesh=0)]
    a.g.scenes = [pygltflib.Scene(nodes=[0])]
    return a


POS = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float32)


@pytest.mark.parametrize("kind,suffix", [("glb", ".glb"), ("bin", ".gltf"), ("uri", ".gltf")])
def test_buffers_in_glb_external_file_and_data_uri(tmp_path, kind, suffix):
    d = np.arange(24, dtype=np.float32).reshape(2, 4, 3) / 10
    path = one_mesh_asset(POS, list(d)).save(tmp_path / f"face{suffix}", kind)
    c = read_gltf(path)
    np.testing.assert_array_equal(c.neutral, POS)
    np.testing.assert_array_equal(c.targets, POS + d.astype(np.float64))
    assert c.names == ("a", "b") and c.name == "face"
    np.testing.assert_array_equal(c.faces, [[0, 1, 2]])


@pytest.mark.parametrize("dtype,scale", [(np.int8, 127), (np.uint8, 255), (np.int16, 32767), (np.uint16, 65535)])
def test_normalized_integer_deltas(tmp_path, dtype, scale):
    info = np.iinfo(dtype)
    raw = np.array([[info.min, 0, info.max], [1, 2, 3], [info.max, info.min, 0], [5, 6, 7]], dtype=dtype)
    path = one_mesh_asset(POS, [raw, raw[::-1].copy()], normalized=True).save(tmp_path / "n.glb")
    c = read_gltf(path)
    expect = np.maximum(raw.astype(np.float64) / scale, -1.0)
    np.testing.assert_allclose(c.targets[0] - c.neutral, expect, rtol=0, atol=1e-12)
    np.testing.assert_allclose(c.targets[1] - c.neutral, expect[::-1], rtol=0, atol=1e-12)
    assert expect.min() >= -1  # -128/127 and -32768/32767 clamp to -1


def test_plain_integer_deltas_are_not_scaled(tmp_path):
    raw = np.array([[1, -2, 3]] * 4, dtype=np.int16)
    c = read_gltf(one_mesh_asset(POS, [raw, raw]).save(tmp_path / "i.glb"))
    np.testing.assert_array_equal(c.targets[0] - c.neutral, raw)


def test_strided_buffer_view_with_offset(tmp_path):
    d = np.arange(12, dtype=np.float32).reshape(4, 3)
    c = read_gltf(one_mesh_asset(POS, [d, d], stride=16, offset=8).save(tmp_path / "s.glb"))
    np.testing.assert_array_equal(c.targets[1] - c.neutral, d)


def test_sparse_targets_with_and_without_base_view(tmp_path):
    a = Asset()
    base = np.full((4, 3), 0.5, dtype=np.float32)
    values = np.array([[1, 2, 3], [4, 5, 6]], dtype=np.float32)
    t0 = a.accessor(np.zeros((4, 3), np.float32), view=False, sparse=([1, 3], values))
    t1 = a.accessor(base, sparse=([0, 2], values))
    prim = pygltflib.Primitive(attributes=pygltflib.Attributes(POSITION=a.accessor(POS)),
                               targets=[pygltflib.Attributes(POSITION=t0), pygltflib.Attributes(POSITION=t1)])
    a.mesh([prim], names=["sparse_zero", "sparse_base"])
    c = read_gltf(a.save(tmp_path / "sparse.glb"))
    e0 = np.zeros((4, 3))
    e0[[1, 3]] = values
    e1 = np.full((4, 3), 0.5)
    e1[[0, 2]] = values
    np.testing.assert_array_equal(c.targets[0] - c.neutral, e0)
    np.testing.assert_array_equal(c.targets[1] - c.neutral, e1)
    assert c.names == ("sparse_zero", "sparse_base")


def test_primitives_concatenate_in_order_and_node_transforms_apply(tmp_path):
    a = Asset()
    d1 = np.ones((4, 3), np.float32)
    p1 = a.primitive(POS, [d1, 2 * d1], faces=[[0, 1, 2], [1, 2, 3]])
    pos2 = POS[:3] + 10
    p2 = a.primitive(pos2, [np.full((3, 3), 3, np.float32), np.full((3, 3), 4, np.float32)], faces=[[2, 1, 0]])
    a.mesh([p1, p2], names=["x", "y"])
    parent = np.eye(4)
    parent[:3, :3] *= 2
    parent[:3, 3] = [1, 2, 3]
    s = np.sqrt(0.5)
    a.g.nodes = [pygltflib.Node(matrix=parent.T.reshape(-1).tolist(), children=[1]),
                 pygltflib.Node(mesh=0, rotation=[0, 0, s, s], translation=[0, 0, 5], scale=[1, 1, 3])]
    a.g.scenes = [pygltflib.Scene(nodes=[0])]
    c = read_gltf(a.save(tmp_path / "tr.glb"))
    rz = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1.0]])
    world = parent @ np.block([[rz @ np.diag([1, 1, 3]), np.array([[0], [0], [5]])], [np.zeros((1, 3)), 1]])
    local = np.concatenate([POS, pos2]).astype(np.float64)
    np.testing.assert_allclose(c.neutral, local @ world[:3, :3].T + world[:3, 3], atol=1e-12)
    local_d = np.concatenate([np.ones((4, 3)), np.full((3, 3), 3.0)])
    np.testing.assert_allclose(c.targets[0] - c.neutral, local_d @ world[:3, :3].T, atol=1e-12)
    np.testing.assert_array_equal(c.faces, [[0, 1, 2], [1, 2, 3], [6, 5, 4]])
    np.testing.assert_allclose(quaternion_matrix([0, 0, s, s]), rz, atol=1e-15)


def test_meshes_with_targets_are_joined_by_name(tmp_path):
    a = Asset()
    a.mesh([a.primitive(POS, [np.ones((4, 3), np.float32), 2 * np.ones((4, 3), np.float32)])],
           names=["jawOpen", "smile"], name="head")
    a.mesh([a.primitive(POS[:2], [np.full((2, 3), 5, np.float32)])], names=["jawOpen"], name="teeth")
    a.mesh([a.primitive(POS, [])], name="hat")  # no targets: left out
    a.g.nodes = [pygltflib.Node(mesh=0), pygltflib.Node(mesh=1), pygltflib.Node(mesh=2)]
    a.g.scenes = [pygltflib.Scene(nodes=[0, 1, 2])]
    path = a.save(tmp_path / "two.glb")
    c = read_gltf(path)
    assert c.names == ("jawOpen", "smile") and len(c.neutral) == 6
    d = c.targets - c.neutral
    np.testing.assert_array_equal(d[0, 4:], 5)
    np.testing.assert_array_equal(d[1, 4:], 0)
    teeth = read_gltf(path, mesh="teeth")
    assert teeth.names == ("jawOpen",) and len(teeth.neutral) == 2
    with pytest.raises(FacepuppetError, match="no morph targets"):
        read_gltf(path, mesh=2)
    with pytest.raises(ValueError, match="no mesh named"):
        read_gltf(path, mesh="nose")
    with pytest.raises(ValueError, match="out of range"):
        read_gltf(path, mesh=7)


def test_default_target_names_and_primitive_extras(tmp_path):
    a = one_mesh_asset(POS, [np.zeros((4, 3), np.float32)] * 2)
    a.g.meshes[0].extras = {}
    assert read_gltf(a.save(tmp_path / "a.glb")).names == ("target_0", "target_1")
    a.g.meshes[0].primitives[0].extras = {"targetNames": ["p", "q"]}
    assert read_gltf(a.save(tmp_path / "b.glb")).names == ("p", "q")


# ----------------------------------------------------------------------------------------- error branches

def test_no_mesh(tmp_path):
    a = Asset()
    a.accessor(POS)
    with pytest.raises(FacepuppetError, match="no mesh"):
        read_gltf(a.save(tmp_path / "empty.glb"))


def test_no_morph_targets(tmp_path):
    a = one_mesh_asset(POS, [])
    with pytest.raises(FacepuppetError, match="no mesh has morph targets"):
        read_gltf(a.save(tmp_path / "plain.glb"))


def test_target_with_other_vertex_count(tmp_path):
    a = one_mesh_asset(POS, [np.zeros((3, 3), np.float32), np.zeros((4, 3), np.float32)])
    with pytest.raises(FacepuppetError, match="morph target 0 has 3 vertices, the mesh has 4"):
        read_gltf(a.save(tmp_path / "bad.glb"))


def test_target_names_of_wrong_length(tmp_path):
    a = one_mesh_asset(POS, [np.zeros((4, 3), np.float32)] * 2, names=["only"])
    with pytest.raises(FacepuppetError, match="lists 1 names for 2 morph targets"):
        read_gltf(a.save(tmp_path / "names.glb"))


def test_repeated_target_names(tmp_path):
    a = one_mesh_asset(POS, [np.zeros((4, 3), np.float32)] * 2, names=["x", "x"])
    with pytest.raises(FacepuppetError, match="repeat: x"):
        read_gltf(a.save(tmp_path / "dup.glb"))


def test_primitives_with_different_target_counts(tmp_path):
    a = Asset()
    a.mesh([a.primitive(POS, [POS]), a.primitive(POS, [POS, POS])], names=["a"])
    with pytest.raises(FacepuppetError, match="primitive 1 has 2 morph targets"):
        read_gltf(a.save(tmp_path / "prims.glb"))


def test_unreadable_files(tmp_path):
    junk = tmp_path / "junk.glb"
    junk.write_bytes(b"glTF\x02\x00\x00\x00garbage")
    with pytest.raises(FacepuppetError, match="junk.glb"):
        read_gltf(junk)
    text = tmp_path / "junk.gltf"
    text.write_text("{not json")
    with pytest.raises(FacepuppetError, match="junk.gltf"):
        read_gltf(text)
    with pytest.raises(FacepuppetError, match="no such file"):
        read_gltf(tmp_path / "missing.glb")


def test_missing_or_short_external_buffer(tmp_path):
    path = one_mesh_asset(POS, [POS, POS]).save(tmp_path / "ext.gltf", "bin")
    (tmp_path / "face data.bin").write_bytes(b"\x00" * 8)
    with pytest.raises(FacepuppetError, match="buffer 0 holds 8 bytes"):
        read_gltf(path)
    (tmp_path / "face data.bin").unlink()
    with pytest.raises(FacepuppetError, match="cannot read buffer file"):
        read_gltf(path)


def test_accessor_past_its_view(tmp_path):
    a = one_mesh_asset(POS, [POS, POS])
    a.g.accessors[1].count = 40
    with pytest.raises(FacepuppetError, match="runs past buffer view"):
        read_gltf(a.save(tmp_path / "short.glb"))


def test_load_character_dispatch_errors(tmp_path):
    (tmp_path / "one.obj").write_text("v 0 0 0\n")
    with pytest.raises(FacepuppetError, match="one OBJ holds no key-models"):
        load_character(tmp_path / "one.obj")
    (tmp_path / "c.fbx").write_text("x")
    with pytest.raises(FacepuppetError, match="unknown character format"):
        load_character(tmp_path / "c.fbx")
    with pytest.raises(FacepuppetError, match="no such file"):
        load_character(tmp_path / "nothing.glb")
    with pytest.raises(ValueError, match="neutral"):
        load_character(tmp_path / "c.fbx", neutral="x")


def test_written_json_is_minimal_and_names_targets(tmp_path, rng):
    c = make_character(rng, m=2)
    save_character(tmp_path / "c.gltf", c)
    doc = json.loads((tmp_path / "c.gltf").read_text())
    prim = doc["meshes"][0]["primitives"][0]
    assert doc["meshes"][0]["extras"]["targetNames"] == ["key0", "key1"]
    assert len(prim["targets"]) == 2 and doc["meshes"][0]["weights"] == [0.0, 0.0]
    assert doc["buffers"][0]["uri"].startswith("data:application/octet-stream;base64,")


def test_glb_named_gltf_still_reads(tmp_path, rng):
    c = make_character(rng)
    write_glb(tmp_path / "c.glb", c)
    (tmp_path / "c.glb").rename(tmp_path / "c.gltf")
    assert read_gltf(tmp_path / "c.gltf").names == c.names


def test_validator_reports_errors(tmp_path, gltf_validator):  # noqa: F811
    from facepuppet.io.glb import GltfBuilder

    b = GltfBuilder()
    acc = b.add_accessor(POS, target=34962, min_max=True)
    b.json["accessors"][acc]["max"] = [9.0, 9.0, 9.0]  # wrong bounds: the validator must say so
    b.json["meshes"] = [{"primitives": [{"attributes": {"POSITION": acc}}]}]
    b.write(tmp_path / "bad.glb")
    assert gltf_validator.report(tmp_path / "bad.glb")["issues"]["numErrors"] > 0
    with pytest.raises(AssertionError, match="ACCESSOR_MAX_MISMATCH"):
        gltf_validator.check(tmp_path / "bad.glb")


def test_compressed_mesh_without_its_extra_names_the_install(tmp_path, monkeypatch):
    import sys

    a = one_mesh_asset(POS, [POS, POS])
    a.g.extensionsUsed = a.g.extensionsRequired = ["KHR_draco_mesh_compression"]
    a.g.meshes[0].primitives[0].extensions = {"KHR_draco_mesh_compression": {"bufferView": 0, "attributes": {}}}
    monkeypatch.setitem(sys.modules, "DracoPy", None)  # the extra not installed
    with pytest.raises(FacepuppetError, match=r"KHR_draco_mesh_compression.*pip install 'facepuppet\[draco\]'"):
        read_gltf(a.save(tmp_path / "draco.glb"))


def test_skinned_mesh_ignores_its_node_transform(tmp_path):
    a = one_mesh_asset(POS, [POS, POS])
    a.g.nodes = [pygltflib.Node(mesh=0, skin=0, translation=[5, 5, 5]), pygltflib.Node()]
    a.g.skins = [pygltflib.Skin(joints=[1])]
    a.g.scenes = [pygltflib.Scene(nodes=[0, 1])]
    np.testing.assert_array_equal(read_gltf(a.save(tmp_path / "skin.glb")).neutral, POS)
