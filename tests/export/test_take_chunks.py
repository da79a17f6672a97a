"""The animation writers read a take chunk by chunk: the file is the same byte for byte at any chunk size."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from facepuppet.export.csv import write_weights_csv
from facepuppet.export.gltf_animation import rotation_quaternions, write_animated_glb
from facepuppet.export.scene_animation import write_scene_animation
from facepuppet.export.take import TakeRows
from facepuppet.io.character import Character, load_character
from scene_characters import skinned_character

F = 53


def _take(rng, m):
    w = rng.uniform(-0.2, 1.2, (F, m))
    w[4] = np.nan
    rot = Rotation.from_rotvec(rng.normal(0, 1.5, (F, 3))).as_matrix()   # big turns: hemisphere flips
    times = np.cumsum(rng.uniform(0.01, 0.05, F))
    return w, rot, times


def _character(rng) -> Character:
    neutral = rng.normal(size=(6, 3))
    return Character(neutral=neutral, targets=neutral[None] + rng.normal(size=(3, 6, 3)),
                     names=("jawOpen", "eyeBlinkLeft", "mouthSmileLeft"), faces=np.array([[0, 1, 2], [3, 4, 5]]))


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
def test_animated_glb_same_bytes_at_every_chunk_size(tmp_path, rng, suffix):
    c = _character(rng)
    w, rot, times = _take(rng, 3)
    write_animated_glb(tmp_path / f"whole{suffix}", c, w, 30.0, head_rotation=rot, times=times)
    whole = (tmp_path / f"whole{suffix}").read_bytes()
    for rows in (1, 7, F):
        take = TakeRows.from_arrays(w, times, rotation=rot, chunk_rows=rows)
        write_animated_glb(tmp_path / f"c{rows}{suffix}", c, take, 30.0)
        assert (tmp_path / f"c{rows}{suffix}").read_bytes() == whole, rows


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
@pytest.mark.parametrize("kind", [{}, {"skinned": False, "head_joint_name": "Nothing"}])
def test_scene_animation_same_bytes_at_every_chunk_size(tmp_path, rng, suffix, kind):
    (tmp_path / "c.glb").write_bytes(skinned_character(rng, **kind)["glb"])
    source = load_character(tmp_path / "c.glb").source
    names = ["jawOpen", "eyeBlinkLeft", "mouthSmileLeft"]
    w, rot, times = _take(rng, 3)
    write_scene_animation(tmp_path / f"whole{suffix}", source, names, w, 30.0, times=times, head_rotation=rot,
                          pivot=np.array([0.0, 1.7, 0.0]))
    whole = (tmp_path / f"whole{suffix}").read_bytes()
    for rows in (1, 7):
        take = TakeRows.from_arrays(w, times, rotation=rot, chunk_rows=rows)
        write_scene_animation(tmp_path / f"c{rows}{suffix}", source, names, take, 30.0,
                              pivot=np.array([0.0, 1.7, 0.0]))
        assert (tmp_path / f"c{rows}{suffix}").read_bytes() == whole, rows


@pytest.mark.parametrize("names", [("jawOpen", "eyeBlinkLeft", "mouthSmileLeft"), ("a", "b", "c")])
def test_weights_csv_same_bytes_at_every_chunk_size(tmp_path, rng, names):
    w, rot, times = _take(rng, 3)
    valid = rng.uniform(size=F) > 0.2
    write_weights_csv(tmp_path / "whole.csv", w, names, 30.0, head_rotation=rot, valid=valid, times=times)
    for rows in (1, 7):
        take = TakeRows.from_arrays(w, times, rotation=rot, valid=valid, chunk_rows=rows)
        write_weights_csv(tmp_path / f"c{rows}.csv", take, names, 30.0)
        assert (tmp_path / f"c{rows}.csv").read_bytes() == (tmp_path / "whole.csv").read_bytes()


def test_quaternions_continue_the_hemisphere_of_the_chunk_before():
    rot = Rotation.from_euler("y", np.linspace(0, 3 * np.pi, 40)[:, None]).as_matrix()   # passes q -> -q twice
    whole = rotation_quaternions(rot)
    first = rotation_quaternions(rot[:25])
    rest = rotation_quaternions(rot[25:], previous=first[-1])
    np.testing.assert_array_equal(np.concatenate([first, rest]), whole)
    assert (np.einsum("ij,ij->i", whole[1:], whole[:-1]) > 0).all()


def test_times_not_increasing_across_chunks_are_refused(tmp_path, rng):
    c = _character(rng)
    w, _, times = _take(rng, 3)
    times[10] = times[9]            # a repeat at a chunk's first row (chunks of 10)
    take = TakeRows.from_arrays(w, times, chunk_rows=10)
    with pytest.raises(ValueError, match="increasing"):
        write_animated_glb(tmp_path / "a.glb", c, take, 30.0)
    assert list(tmp_path.iterdir()) == []


def test_scene_head_without_joint_non_finite_rotation_is_the_rest_pose(tmp_path, rng):
    (tmp_path / "c.glb").write_bytes(skinned_character(rng, skinned=False, head_joint_name="Nothing")["glb"])
    source = load_character(tmp_path / "c.glb").source
    names = ["jawOpen", "eyeBlinkLeft", "mouthSmileLeft"]
    w, rot, _ = _take(rng, 3)
    bad = rot.copy()
    bad[3] = np.nan
    rest = rot.copy()
    rest[3] = np.eye(3)
    write_scene_animation(tmp_path / "nan.glb", source, names, w, 30.0, head_rotation=bad)
    write_scene_animation(tmp_path / "rest.glb", source, names, w, 30.0, head_rotation=rest)
    assert (tmp_path / "nan.glb").read_bytes() == (tmp_path / "rest.glb").read_bytes()
