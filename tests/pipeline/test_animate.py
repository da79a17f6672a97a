"""animate's middle (map_track): mapper on valid frames, hold/ease on lost ones, gain; rig checks; head frame."""

from __future__ import annotations

import numpy as np
import pytest

from facepuppet.capture.curves import CURVE_NAMES, POINT_NAMES
from facepuppet.errors import FacepuppetError
from facepuppet.io.track import Track
from facepuppet.pipeline.animate import AnimateConfig, head_rotation_in_character, map_track
from facepuppet.pipeline.gain import parse_gain
from facepuppet.pipeline.smoothing import SmoothingConfig

P = len(POINT_NAMES)


class LinearMapper:
    """w = <d, B_i> / |B_i|^2 for orthogonal displacement patterns B_i: exact on their span."""

    def __init__(self, neutral, basis):
        self.neutral, self.basis = neutral, basis

    def weights(self, points):
        d = np.asarray(points) - self.neutral
        return np.einsum("...pd,mpd->...m", d, self.basis) / np.einsum("mpd,mpd->m", self.basis, self.basis)


class StubRig:
    def __init__(self, mapper, names, point_names=POINT_NAMES):
        self.mapper, self.names, self.point_names = mapper, tuple(names), tuple(point_names)


def make_track(points, valid, fps=30.0, backend="color"):
    f = len(points)
    points = np.where(valid[:, None, None], points, np.nan)
    return Track(fps=fps, frame_size=np.array([64, 64]), valid=valid, curves=np.zeros((f, len(CURVE_NAMES), 4, 2)),
                 curve_names=CURVE_NAMES, points=points, point_names=POINT_NAMES,
                 rotation=np.tile(np.diag([1.0, -1.0, -1.0]), (f, 1, 1)), translation=np.zeros((f, 3)),
                 backend=backend)


@pytest.fixture
def setup(rng):
    neutral = rng.normal(size=(P, 3))
    q, _ = np.linalg.qr(rng.normal(size=(P * 3, 2)))
    basis = q.T.reshape(2, P, 3)
    w_true = np.clip(np.stack([np.linspace(0, 1, 60), 0.5 + 0.4 * np.sin(np.arange(60) / 5)], axis=1), 0, 1)
    points = neutral + np.einsum("fm,mpd->fpd", w_true, basis)
    return StubRig(LinearMapper(neutral, basis), ["jawOpen", "mouthSmile"]), points, w_true


def test_unsmoothed_weights_are_the_mappers(setup):
    rig, points, w_true = setup
    cfg = AnimateConfig(smoothing=SmoothingConfig(enabled=False))
    anim = map_track(rig, make_track(points, np.ones(60, bool)), cfg)
    np.testing.assert_allclose(anim.weights, w_true, atol=1e-9)
    np.testing.assert_allclose(anim.raw, w_true, atol=1e-9)
    assert anim.names == ("jawOpen", "mouthSmile") and anim.fps == 30.0


def test_lost_frames_hold_then_ease_and_gain_scales(setup):
    rig, points, w_true = setup
    valid = np.ones(60, bool)
    valid[30:] = False
    cfg = AnimateConfig(smoothing=SmoothingConfig(enabled=False), gain=parse_gain(["0.5"]))
    anim = map_track(rig, make_track(points, valid), cfg)
    assert np.isnan(anim.raw[30:]).all()
    np.testing.assert_allclose(anim.weights[:30], 0.5 * w_true[:30], atol=1e-9)
    np.testing.assert_allclose(anim.weights[30:37], np.tile(0.5 * w_true[29], (7, 1)), atol=1e-9)   # held 0.25 s
    np.testing.assert_allclose(anim.weights[-1], 0.0, atol=1e-12)                    # eased to neutral


def test_smoothing_keeps_constant_expression(setup):
    rig, points, _ = setup
    pts = np.repeat(points[40:41], 30, axis=0)
    anim = map_track(rig, make_track(pts, np.ones(30, bool)))
    np.testing.assert_allclose(anim.weights, np.repeat(anim.raw[:1], 30, axis=0), atol=1e-9)


def test_rig_for_other_feature_points_is_refused(setup):
    rig, points, _ = setup
    other = StubRig(rig.mapper, rig.names, [f"lm{i}" for i in range(P)])
    with pytest.raises(FacepuppetError, match="other.rig.npz: made for other feature points"):
        map_track(other, make_track(points, np.ones(60, bool)), rig_label="other.rig.npz")


def test_mapper_refusing_the_points_is_one_clear_error(setup):
    rig, points, _ = setup

    class Refuses:
        def weights(self, p):
            raise ValueError("points must have shape (P, 2)")

    with pytest.raises(FacepuppetError, match="r.npz: does not fit the track's feature points"):
        map_track(StubRig(Refuses(), rig.names), make_track(points, np.ones(60, bool)), rig_label="r.npz")


def test_head_rotation_frontal_is_identity_and_yaw_keeps_its_sense():
    frontal = np.diag([1.0, -1.0, -1.0])
    np.testing.assert_allclose(head_rotation_in_character(frontal[None])[0], np.eye(3))
    a = 0.3   # the performer turns to their own left: about the head's y (up) axis, positive
    yaw_head = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    r = head_rotation_in_character((frontal @ yaw_head)[None])[0]
    np.testing.assert_allclose(r, yaw_head, atol=1e-12)
