"""Weights CSV: Live Link Face layout for ARKit-named key-models (header, rows, timecode), plain otherwise."""

from __future__ import annotations

import csv

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from facepuppet.export.csv import (
    LLF_BLENDSHAPES,
    LLF_HEAD_EYES,
    arkit_columns,
    head_angles,
    llf_timecode,
    write_weights_csv,
)


def read(path):
    with open(path, newline="") as fh:
        return list(csv.reader(fh))


def test_live_link_face_header_and_rows(tmp_path, ict):
    names = [str(n) for n in ict["expr_names"]]  # ICT spells them eyeBlink_L, browInnerUp_L, ...
    f = 17
    rng = np.random.default_rng(3)
    weights = rng.uniform(0, 1, size=(f, len(names)))
    path = tmp_path / "take.csv"
    assert write_weights_csv(path, weights, names, 30.0) == "arkit"
    rows = read(path)
    assert len(rows) == f + 1
    header = rows[0]
    assert header[:2] == ["Timecode", "BlendShapeCount"]
    assert header[2:] == list(LLF_BLENDSHAPES) + list(LLF_HEAD_EYES) and len(header) == 63
    assert header[2] == "EyeBlinkLeft" and header[54:57] == ["HeadYaw", "HeadPitch", "HeadRoll"]
    assert all(len(r) == 63 and r[1] == "61" for r in rows[1:])
    col = {n: i for i, n in enumerate(header)}
    row = np.array(rows[1 + 5][2:], dtype=float)  # frame 5
    np.testing.assert_allclose(row[col["EyeBlinkLeft"] - 2], weights[5, names.index("eyeBlink_L")], atol=1e-6)
    np.testing.assert_allclose(row[col["MouthSmileRight"] - 2], weights[5, names.index("mouthSmile_R")],
                               atol=1e-6)
    halves = weights[5, [names.index("browInnerUp_L"), names.index("browInnerUp_R")]].mean()
    np.testing.assert_allclose(row[col["BrowInnerUp"] - 2], halves, atol=1e-6)
    assert row[col["TongueOut"] - 2] == 0 and np.all(row[-9:] == 0)
    assert [r[0] for r in rows[1:4]] == ["00:00:00:00.000", "00:00:00:02.000", "00:00:00:04.000"]


@pytest.mark.parametrize("seconds,code", [
    (0, "00:00:00:00.000"), (1 / 30, "00:00:00:02.000"), (1.5, "00:00:01:30.000"),
    (3661 + 1 / 60, "01:01:01:01.000"), (1 / 29.97, "00:00:00:02.002"), (59.9999999, "00:01:00:00.000"),
    (0.999, "00:00:00:59.940"),
])
def test_timecode(seconds, code):
    assert llf_timecode(seconds) == code


@pytest.mark.parametrize("name,columns", [
    ("eyeBlink_L", ["EyeBlinkLeft"]), ("eyeBlinkLeft", ["EyeBlinkLeft"]), ("EyeBlinkLeft", ["EyeBlinkLeft"]),
    ("eyeBlink.R", ["EyeBlinkRight"]), ("mouthLeft", ["MouthLeft"]), ("jawOpen", ["JawOpen"]),
    ("cheekPuff_R", ["CheekPuff"]), ("mouthSmile", ["MouthSmileLeft", "MouthSmileRight"]),
    ("mouthRollLower", ["MouthRollLower"]), ("tongueOut", ["TongueOut"]), ("ears_wiggle", []), ("", []),
])
def test_arkit_columns(name, columns):
    assert [LLF_BLENDSHAPES[i] for i in arkit_columns(name)] == columns


def test_head_angles_and_their_columns(tmp_path):
    yaw_pitch_roll = np.array([[0.3, 0.0, 0.0], [0.0, 0.2, 0.0], [0.0, 0.0, -0.4], [0.25, -0.15, 0.1]])
    rot = Rotation.from_euler("YXZ", yaw_pitch_roll).as_matrix()  # intrinsic: R_y(yaw) R_x(pitch) R_z(roll)
    np.testing.assert_allclose(head_angles(rot), yaw_pitch_roll, atol=1e-12)
    # positive yaw turns the face (+z) toward its own left (+x)
    assert (rot[0] @ [0, 0, 1])[0] > 0
    path = tmp_path / "head.csv"
    write_weights_csv(path, np.zeros((4, 1)), ["jawOpen"], 60.0, head_rotation=rot)
    rows = read(path)
    values = np.array([r[54:57] for r in rows[1:]], dtype=float)
    np.testing.assert_allclose(values, yaw_pitch_roll / np.pi, atol=1e-6)


def test_plain_layout_with_invalid_frames(tmp_path):
    weights = np.array([[0.1, 0.2], [np.nan, 0.5], [0.3, 0.4]])
    rot = np.stack([np.eye(3)] * 3)
    path = tmp_path / "plain.csv"
    layout = write_weights_csv(path, weights, ["happy", "sad, very"], 25.0, head_rotation=rot,
                               valid=[True, True, False])
    assert layout == "plain"
    rows = read(path)
    assert rows[0] == ["time", "valid", "happy", "sad, very", "head_yaw", "head_pitch", "head_roll"]
    assert len(rows) == 4
    assert rows[1][:4] == ["0.000000", "1", "0.1", "0.2"]
    assert rows[2][:4] == ["0.040000", "0", "0", "0"] and rows[3][1:4] == ["0", "0", "0"]


def test_layout_choice_and_unmapped_warning(tmp_path):
    names = ["jawOpen", "eyeBlink_L", "grin"]
    with pytest.warns(UserWarning, match="grin"):
        assert write_weights_csv(tmp_path / "a.csv", np.zeros((2, 3)), names, 30) == "arkit"
    assert write_weights_csv(tmp_path / "b.csv", np.zeros((2, 3)), names, 30, layout="plain") == "plain"
    assert write_weights_csv(tmp_path / "c.csv", np.zeros((2, 3)), ["a", "b", "jawOpen"], 30) == "plain"
    header = read(tmp_path / "c.csv")[0]
    assert header == ["time", "valid", "a", "b", "jawOpen"]


def test_bad_arguments_write_nothing(tmp_path):
    path = tmp_path / "x.csv"
    with pytest.raises(ValueError, match=r"shape \(F, 2\)"):
        write_weights_csv(path, np.zeros((3, 3)), ["a", "b"], 30)
    with pytest.raises(ValueError, match="fps"):
        write_weights_csv(path, np.zeros((3, 2)), ["a", "b"], -1)
    with pytest.raises(ValueError, match="layout"):
        write_weights_csv(path, np.zeros((3, 2)), ["a", "b"], 30, layout="fbx")
    with pytest.raises(ValueError, match=r"valid must have shape \(3,\)"):
        write_weights_csv(path, np.zeros((3, 2)), ["a", "b"], 30, valid=[True])
    with pytest.raises(ValueError, match=r"head_rotation must have shape \(3, 3, 3\)"):
        write_weights_csv(path, np.zeros((3, 2)), ["a", "b"], 30, head_rotation=np.zeros((3, 3)))
    assert not list(tmp_path.iterdir())
