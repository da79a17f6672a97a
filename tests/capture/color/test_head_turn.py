"""The head-turn model's input and angles (:mod:`facepuppet.capture.color.head_turn`): known answers."""

import numpy as np

from facepuppet.capture.color.head_turn import (
    JITTER,
    N_FEATURES,
    RAY_SHARE,
    head_patch,
    ray_angles,
    training_pairs,
    turn_angles,
)
from facepuppet.capture.color.train import relight
from facepuppet.capture.pose import default_camera

PX = 48.0


def _crop(rng):
    """A smooth random crop of the tracker's size (134 x 125), with structure at a few pixels' scale."""
    import cv2

    small = rng.integers(0, 255, size=(34, 32, 3), dtype=np.uint8)
    return cv2.resize(small, (125, 134), interpolation=cv2.INTER_CUBIC)


def test_mirrored_input_is_the_input_of_the_mirrored_crop(rng):
    """``mirror=True`` reads the face mirrored about the eyes' midpoint (x = 0, crop pixel 62.4): the same
    numbers as the crop flipped left to right (whose x = 0 then sits at pixel 124 - 62.4 = 61.6), to the
    resampling's fixed-point weights (1/32 pixel)."""
    crop = _crop(rng)
    flipped = np.ascontiguousarray(crop[:, ::-1])
    S = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    S_flipped = np.array([[1.0, 0.0, (124 - 62.4) - 62.4], [0.0, 1.0, 0.0]])
    a = head_patch(crop, S, PX, mirror=True)
    b = head_patch(flipped, S_flipped, PX)
    assert a.shape == (N_FEATURES,)
    np.testing.assert_allclose(a, b, atol=0.01 * np.abs(b).max())
    assert np.abs(a - head_patch(crop, S, PX)).max() > 0.1       # not symmetric by itself


def test_input_does_not_change_with_the_light_strength(rng):
    """The gradients are divided by their root mean square: a crop 0.6 times as bright reads nearly the same
    (the rest is the rounding to 8 bits)."""
    crop = _crop(rng)
    dim = relight(crop, 0.6, 0.0, 1.0)
    a, b = head_patch(crop, np.eye(2, 3), PX), head_patch(dim, np.eye(2, 3), PX)
    assert np.abs(a - b).max() < 0.03 * np.abs(a).max()


def test_training_pairs_mirror_the_yaw(rng):
    crop = _crop(rng)
    xs, ys = training_pairs(crop, np.eye(2, 3), PX, np.array([0.1, -0.05, 0.02]), rng)
    assert len(xs) == len(ys) == 2 * (JITTER[0] + 1)
    np.testing.assert_allclose(ys[0], [0.1, -0.05])
    np.testing.assert_allclose(ys[1], [-0.1, -0.05])
    np.testing.assert_allclose(xs[1], head_patch(crop, np.eye(2, 3), PX, mirror=True))


def test_turn_adds_the_share_of_the_place_of_the_head():
    """A head whose origin (camera coordinates t) projects to pixel uv sits in the direction
    (atan(t_x / t_z), atan(t_y / t_z)); the turn of :func:`turn_angles` is the model's plus that share."""
    K = default_camera((640, 480))
    t = np.array([6.0, -3.0, 60.0])
    uv = (K @ t)[:2] / t[2]
    ray = ray_angles(uv, K)
    np.testing.assert_allclose(ray, [np.arctan(0.1), np.arctan(-0.05)])
    yaw, pitch = turn_angles(np.array([0.2, -0.1]), uv, K)
    np.testing.assert_allclose([yaw, pitch], np.array([0.2, -0.1]) + np.asarray(RAY_SHARE) * ray)


def test_turn_rotation_gives_its_angles_back():
    from facepuppet.capture.color.head_turn import turn_rotation
    from facepuppet.capture.pose import FRONTAL_ROTATION, HeadPose

    for angles in ([0.2, -0.1, 0.05], [-0.4, 0.3, -0.2]):
        R = FRONTAL_ROTATION @ turn_rotation(*angles)
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
        got = HeadPose(R, np.array([0.0, 0.0, 60.0]), default_camera((640, 480))).angles()
        np.testing.assert_allclose(got, angles, atol=1e-12)
