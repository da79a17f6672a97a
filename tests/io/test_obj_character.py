"""Characters from OBJ files: exact vertex order and count, fan triangulation, every error branch."""

from __future__ import annotations

import numpy as np
import pytest

from facepuppet.errors import FacepuppetError
from facepuppet.io.character import Character, load_character, save_character
from facepuppet.io.obj import read_obj, read_obj_character, write_obj

# Repeated coordinates (vertices 1 and 4), texture coordinates and normals that a mesh loader would use to
# merge or split vertices; a quad and a pentagon; negative indices; comments and groups.
TRICKY = """# exported by hand
mtllib face.mtl
o face
v 0 0 0
v 1 0 0
v 1 1 0
  v 1.0 0.0 0.0
v 0 1 0
vt 0 0
vt 1 0
vn 0 0 1
g part
usemtl skin
f 1/1/1 2/2/1 3/1/1 5/2/1
s off
f 2//1 3//1 4//1
f -1 -2 -3 -4 -5
"""


def test_vertices_in_file_order_and_faces_fanned(tmp_path):
    path = tmp_path / "face.obj"
    path.write_text(TRICKY)
    v, f = read_obj(path)
    np.testing.assert_array_equal(v, [[0, 0, 0], [1, 0, 0], [1, 1, 0], [1, 0, 0], [0, 1, 0]])
    np.testing.assert_array_equal(f, [[0, 1, 2], [0, 2, 4], [1, 2, 3], [4, 3, 2], [4, 2, 1], [4, 1, 0]])


def folder_character(tmp_path, rng, names=("smile", "blink"), v=30):
    base = rng.normal(size=(v, 3))
    faces = np.array([[i, i + 1, i + 2] for i in range(v - 2)])
    folder = tmp_path / "char"
    folder.mkdir()
    write_obj(folder / "neutral.obj", base, faces)
    targets = []
    for n in names:
        t = base + rng.normal(size=base.shape) * 0.01
        write_obj(folder / f"{n}.obj", t)
        targets.append(t)
    return folder, base, np.stack(targets), faces


def test_folder_reads_exactly(tmp_path, rng):
    folder, base, targets, faces = folder_character(tmp_path, rng)
    c = load_character(folder)
    assert c.names == ("blink", "smile") and c.name == "char"  # sorted by file name
    np.testing.assert_array_equal(c.neutral, base)
    np.testing.assert_array_equal(c.targets, targets[::-1])
    np.testing.assert_array_equal(c.faces, faces)


def test_named_neutral_and_explicit_list(tmp_path, rng):
    folder, base, targets, _ = folder_character(tmp_path, rng)
    (folder / "neutral.obj").rename(folder / "rest.obj")
    with pytest.raises(FacepuppetError, match="no neutral OBJ"):
        read_obj_character(folder)
    c = read_obj_character(folder, neutral="rest")
    np.testing.assert_array_equal(c.neutral, base)
    c = load_character(folder, neutral="rest.obj")
    assert c.names == ("blink", "smile")
    listed = read_obj_character([folder / "smile.obj", folder / "blink.obj"], neutral=folder / "rest.obj")
    assert listed.names == ("smile", "blink") and listed.name == "rest"
    np.testing.assert_array_equal(listed.targets, targets)
    with pytest.raises(ValueError, match="neutral"):
        read_obj_character([folder / "smile.obj"])
    with pytest.raises(FacepuppetError, match="not found"):
        read_obj_character(folder, neutral="nope")


def test_round_trip_through_a_folder(tmp_path, rng):
    base = rng.normal(size=(20, 3))
    c = Character(base, base[None] + rng.normal(size=(2, 20, 3)), ("jawOpen", "eyeBlink_L"),
                  np.array([[0, 1, 2], [2, 3, 4]]), "x")
    save_character(tmp_path / "out", c)
    back = load_character(tmp_path / "out")
    order = [back.names.index(n) for n in c.names]
    np.testing.assert_array_equal(back.targets[order], c.targets)
    np.testing.assert_array_equal(back.neutral, c.neutral)
    np.testing.assert_array_equal(back.faces, c.faces)


def test_ict_meshes_keep_vertex_count_and_order(tmp_path, ict):
    names = [str(n) for n in ict["expr_names"][:2]]
    c = Character(ict["neutral"].astype(np.float64), (ict["neutral"][None] + ict["expr_deltas"][:2]).astype(
        np.float64), tuple(names), ict["faces"], "ict")
    save_character(tmp_path / "ict", c)
    back = load_character(tmp_path / "ict")
    assert back.neutral.shape == (11248, 3)
    np.testing.assert_array_equal(back.neutral, c.neutral)
    np.testing.assert_array_equal(back.targets[[back.names.index(n) for n in names]], c.targets)
    np.testing.assert_array_equal(back.faces, ict["faces"])


def test_key_model_with_other_vertex_count_names_the_file(tmp_path, rng):
    folder, *_ = folder_character(tmp_path, rng)
    (folder / "blink.obj").write_text("v 0 0 0\nv 1 1 1\n")
    with pytest.raises(FacepuppetError, match=r"blink\.obj: 2 vertices, but the neutral neutral\.obj has 30"):
        load_character(folder)


@pytest.mark.parametrize("text,match", [
    ("f 1 2 3\n", "no vertices"),
    ("v 0 0\n", r"bad\.obj:1: bad vertex line"),
    ("v 0 0 0\nv 1 x 0\n", r"bad\.obj:2: bad vertex line"),
    ("v 0 0 0\nf 1 a 2\n", "bad face line"),
    ("v 0 0 0\nv 0 0 1\nf 1 2\n", "3 or more vertices"),
    ("v 0 0 0\nv 0 0 1\nv 1 0 0\nf 1 2 7\n", "face indices outside"),
])
def test_bad_obj_lines(tmp_path, text, match):
    path = tmp_path / "bad.obj"
    path.write_text(text)
    with pytest.raises(FacepuppetError, match=match):
        read_obj(path)


def test_folder_errors(tmp_path, rng):
    with pytest.raises(FacepuppetError, match="cannot read OBJ"):
        read_obj(tmp_path / "missing.obj")
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(FacepuppetError, match="no .obj files"):
        read_obj_character(empty)
    with pytest.raises(FacepuppetError, match="not a folder"):
        read_obj_character(tmp_path / "nothing")
    write_obj(empty / "neutral.obj", rng.normal(size=(3, 3)))
    with pytest.raises(FacepuppetError, match="no key-model OBJ"):
        read_obj_character(empty)
    with pytest.raises(ValueError, match="mesh"):
        load_character(empty, mesh="head")


def test_writing_refuses_unsafe_names(tmp_path, rng):
    base = rng.normal(size=(3, 3))
    for bad in ("neutral", "a/b", ".."):
        with pytest.raises(ValueError):
            save_character(tmp_path / "out", Character(base, base[None], (bad,)))
    assert not (tmp_path / "out").exists()
