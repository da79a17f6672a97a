"""The digital performer: its true curves against its own pictures, symmetry, expressions, pose, linearity."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from facepuppet.capture.color.transform import DEFAULT_WEIGHTS, LipHue, lip_hue_table, transform
from facepuppet.capture.curves import CURVE_NAMES, POINT_NAMES, bezier_points
from facepuppet.capture.pose import STABLE_FEATURES, estimate_pose, generic_points, pose_points_from_curves
from facepuppet.demo.performer import (
    head_pose,
    performer_curves,
    performer_curves_3d,
    performer_points,
    render_performance,
    render_performer,
)
from facepuppet.demo.script import KEY_NAMES, Script

C = {n: i for i, n in enumerate(CURVE_NAMES)}
SIZE = (480, 480)


def key(name: str, value: float = 1.0) -> np.ndarray:
    w = np.zeros(len(KEY_NAMES))
    w[KEY_NAMES.index(name)] = value
    return w


def mid(curve: np.ndarray) -> np.ndarray:
    return bezier_points(curve, 3)[1]


@pytest.mark.parametrize("expression", [None, "jawOpen", "mouthSmile", "eyeBlink", "browDown", "mouthFunnel"])
def test_true_curves_lie_on_dark_or_lip_pixels(expression):
    w = np.zeros(13) if expression is None else key(expression)
    motion = np.array([0.12, -0.05, 0.04, 0.5, -0.3, 1.0])
    img = render_performer(w, motion, SIZE)
    intensity = transform(img, DEFAULT_WEIGHTS, lip_hue_table(LipHue()))  # Eq. 1: high on features
    near = cv2.dilate(intensity, np.ones((3, 3), np.uint8))  # a curve on an outline: its pixel or a neighbour
    pose = head_pose(motion, SIZE)
    skin_head = np.array([[1.0, 4.0, 0.5], [-1.0, 4.0, 0.5], [0.0, 4.5, 0.5], [3.5, -3.0, -1.0],
                          [-3.5, -3.0, -1.0], [2.5, -9.0, -1.0], [-2.0, -8.5, 0.0]])
    sx, sy = np.round(pose.project(skin_head)).astype(int).T
    skin = intensity[sy, sx].max()
    samples = bezier_points(performer_curves(w, motion, SIZE), 30)[:, 3:-3]  # away from the thin ends
    x, y = np.round(samples[..., 0]).astype(int), np.round(samples[..., 1]).astype(int)
    on_curve = near[y, x]
    for name, values in zip(CURVE_NAMES, on_curve, strict=True):
        assert np.quantile(values, 0.05) > skin + 0.1, f"{name}: {np.quantile(values, 0.05):.2f} vs skin {skin:.2f}"


def test_neutral_frontal_face_has_mirror_symmetric_curves():
    c = performer_curves(np.zeros(13), np.zeros(6), SIZE)
    mirror = c.copy()
    mirror[..., 0] = SIZE[0] - c[..., 0]  # principal point in the middle of the image
    for left in ("brow", "eye_{}_upper", "eye_{}_lower"):
        a = left.format("left") if "{}" in left else f"{left}_left"
        b = left.format("right") if "{}" in left else f"{left}_right"
        np.testing.assert_allclose(mirror[C[a]], c[C[b]], atol=1e-9)
    np.testing.assert_allclose(mirror[C["nostril_left"]][::-1], c[C["nostril_right"]], atol=1e-9)
    for lip in ("lip_upper_outer", "lip_lower_outer", "lip_upper_inner", "lip_lower_inner"):
        np.testing.assert_allclose(mirror[C[lip]][::-1], c[C[lip]], atol=1e-9)
    # the performer's left appears on the image's right; curves run inner to outer and right to left
    assert c[C["brow_left"], :, 0].mean() > SIZE[0] / 2 > c[C["brow_right"], :, 0].mean()
    assert c[C["eye_left_upper"], 3, 0] > c[C["eye_left_upper"], 0, 0]
    assert c[C["lip_upper_outer"], 0, 0] < c[C["lip_upper_outer"], 3, 0]
    # image y down: brows above eyes above nostrils above lips
    ys = [c[C[n], :, 1].mean() for n in ("brow_left", "eye_left_upper", "nostril_left", "lip_upper_outer")]
    assert ys == sorted(ys)


def test_jaw_open_separates_the_inner_lips_in_proportion():
    gaps = []
    for value in (0.0, 0.5, 1.0):
        c = performer_curves(key("jawOpen", value))
        gaps.append(mid(c[C["lip_lower_inner"]])[1] - mid(c[C["lip_upper_inner"]])[1])
    assert abs(gaps[0]) < 1.0
    assert gaps[2] > 15.0  # about 1.3 cm at 15 px per cm
    assert gaps[1] == pytest.approx((gaps[0] + gaps[2]) / 2, abs=0.5)
    # the mouth opening is dark in the picture
    c = performer_curves(key("jawOpen"))
    centre = (mid(c[C["lip_lower_inner"]]) + mid(c[C["lip_upper_inner"]])) / 2
    img = render_performer(key("jawOpen"))
    assert img[int(centre[1]), int(centre[0])].max() < 80


def test_blink_brings_the_lids_together_and_hides_the_eye():
    for side in ("left", "right"):
        up, lo = C[f"eye_{side}_upper"], C[f"eye_{side}_lower"]
        open_ = performer_curves(np.zeros(13))
        shut = performer_curves(key("eyeBlink"))
        assert mid(open_[lo])[1] - mid(open_[up])[1] > 8.0
        np.testing.assert_allclose(shut[up], shut[lo], atol=0.05)
    # no sclera left: no near-white pixels around the eyes
    for w, expect_white in ((np.zeros(13), True), (key("eyeBlink"), False)):
        img = render_performer(w).astype(int)
        c = performer_curves(w)
        box = np.concatenate([c[C["eye_left_upper"]], c[C["eye_right_upper"]]])
        x0, y0 = np.floor(box.min(0)).astype(int) - 3
        x1, y1 = np.ceil(box.max(0)).astype(int) + 12
        white = (img[y0:y1, x0:x1].min(axis=2) > 200).sum()
        assert (white > 20) == expect_white


@pytest.mark.parametrize("motion", [[0.2, 0.0, 0.0, 0, 0, 0], [-0.15, 0.08, -0.06, 1.0, -0.5, 1.5]])
def test_head_motion_moves_the_curves_as_the_projection_and_the_pose_is_recovered(motion):
    motion = np.asarray(motion, float)
    w = key("mouthSmile", 0.6)
    pose = head_pose(motion, SIZE)
    c = performer_curves(w, motion, SIZE)
    ends3 = performer_curves_3d(w)[:, [0, 3]].reshape(-1, 3)
    np.testing.assert_allclose(c[:, [0, 3]].reshape(-1, 2), pose.project(ends3), atol=1e-9)
    np.testing.assert_allclose(pose.angles(), motion[:3], atol=1e-12)
    # the tracker's pose solver, fed the true stable curve ends, finds the true pose (the face is the generic one)
    solved = estimate_pose(pose_points_from_curves(c), SIZE)
    assert solved
    np.testing.assert_allclose(solved.angles(), motion[:3], atol=2e-3)
    np.testing.assert_allclose(solved.translation, pose.translation, atol=0.05)


def test_yaw_to_the_performers_left_moves_the_nose_to_the_image_right():
    base = performer_curves(np.zeros(13))
    turned = performer_curves(np.zeros(13), [0.2, 0, 0, 0, 0, 0])
    def nose_vs_eyes(c):
        return c[C["nostril_left"], 0, 0] - (c[C["eye_left_upper"], 0, 0] + c[C["eye_right_upper"], 0, 0]) / 2
    assert nose_vs_eyes(turned) > nose_vs_eyes(base) + 3.0


def test_points_are_the_generic_face_at_rest_and_linear_in_the_weights():
    rng = np.random.default_rng(1)
    p0 = performer_points(np.zeros(13))
    assert p0.shape == (len(POINT_NAMES), 3)
    np.testing.assert_allclose(p0, generic_points(), atol=1e-12)
    a, b = rng.uniform(0, 1, 13), rng.uniform(0, 1, 13)
    mixed = 0.3 * performer_points(a) + 0.7 * performer_points(b)
    np.testing.assert_allclose(performer_points(0.3 * a + 0.7 * b), mixed, atol=1e-12)
    np.testing.assert_allclose(performer_points(2 * a) - p0, 2 * (performer_points(a) - p0), atol=1e-12)
    # every key moves some point, and the stable features never move
    stable = [POINT_NAMES.index(n) for n in ("eye_left_upper:0", "eye_left_upper:3", "eye_right_upper:0",
                                              "eye_right_upper:3", "nostril_left:0", "nostril_left:3",
                                              "nostril_right:0")]
    assert len(STABLE_FEATURES) == len(stable)
    for k in range(13):
        d = np.linalg.norm(performer_points(np.eye(13)[k]) - p0, axis=1)
        assert d.max() > 0.2, KEY_NAMES[k]
        assert d[stable].max() == 0.0, KEY_NAMES[k]


def test_points_with_head_motion_are_in_camera_coordinates():
    w, motion = key("jawOpen", 0.4), np.array([0.1, 0.05, -0.03, 0.5, 0.2, -1.0])
    cam = performer_points(w, motion)
    pose = head_pose(motion, SIZE)
    uv = cam @ pose.camera_matrix.T
    from facepuppet.capture.curves import curve_points

    np.testing.assert_allclose(uv[:, :2] / uv[:, 2:], curve_points(performer_curves(w, motion, SIZE)), atol=0.05)


def test_rendering_is_deterministic_and_noise_is_mild():
    w = key("mouthSmile", 0.5)
    a = render_performer(w, None, (200, 160))
    assert a.shape == (160, 200, 3) and a.dtype == np.uint8
    assert np.array_equal(a, render_performer(w, None, (200, 160)))
    b = render_performer(w, None, (200, 160), rng=np.random.default_rng(5))
    diff = np.abs(a.astype(int) - b.astype(int))
    assert diff.mean() < 5.0 and diff.max() < 40


def test_script_rendering_and_the_frame_iterator_agree():
    weights = np.stack([np.zeros(13), key("jawOpen"), key("eyeBlink", 0.5)])
    motion = np.zeros((3, 6))
    motion[:, 0] = [0.0, 0.1, -0.1]
    script = Script(weights, motion, fps=30.0)
    frames, curves = render_performer(script, size=(160, 160))
    assert frames.shape == (3, 160, 160, 3) and curves.shape == (3, len(CURVE_NAMES), 4, 2)
    for i, frame in enumerate(render_performance(script, (160, 160), seed=0)):
        assert np.array_equal(frame, frames[i])
        np.testing.assert_allclose(curves[i], performer_curves(weights[i], motion[i], (160, 160)))


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="weights"):
        render_performer(np.zeros(12))
    with pytest.raises(ValueError, match="head_motion"):
        performer_curves(np.zeros(13), np.zeros(5))
    with pytest.raises(ValueError, match="size"):
        render_performer(np.zeros(13), size=(10, 10))
    with pytest.raises(ValueError, match="weights"):
        performer_points(np.full(13, np.nan))


def test_each_key_is_told_apart_from_the_others_in_the_image_plane():
    """No key's 2D point displacement is (nearly) a combination of the others with weights in [0, 1]."""
    from scipy.optimize import lsq_linear

    p0 = performer_points(np.zeros(13))
    d = np.stack([(performer_points(np.eye(13)[k]) - p0)[:, :2].ravel() for k in range(13)])
    for k in range(13):
        others = np.delete(d, k, axis=0)
        fit = lsq_linear(others.T, d[k], bounds=(0.0, 1.0))
        assert np.linalg.norm(fit.fun) / np.linalg.norm(d[k]) > 0.2, KEY_NAMES[k]
