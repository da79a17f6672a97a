"""The turned copies of a clip (``benchmarks/turned.py``): a face's mesh rotated and its pixels warped."""

import importlib.util
import os
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

_PATH = Path(__file__).resolve().parents[1] / "benchmarks" / "turned.py"
_spec = importlib.util.spec_from_file_location("turned", _PATH)
turned = importlib.util.module_from_spec(_spec)
sys.modules.setdefault("turned", turned)
_spec.loader.exec_module(turned)

ASSETS = Path(os.environ.get("FACEPUPPET_ASSETS", Path(__file__).resolve().parents[2] / "shared" / "assets"))


def _plane(n: int = 9, lo: float = 40.0, hi: float = 200.0, depth: float = 0.0) -> np.ndarray:
    """(n * n, 3) a flat grid of points facing the camera at ``depth``."""
    g = np.linspace(lo, hi, n)
    x, y = np.meshgrid(g, g)
    return np.c_[x.ravel(), y.ravel(), np.full(n * n, depth)]


def test_the_sweep_eases_in_over_a_second_and_swings_either_way():
    a = turned.sweep(np.arange(300), 30.0, 25.0, 10.0)
    assert a.shape == (300, 2)
    assert np.allclose(a[0], 0.0)
    t = np.arange(300) / 30.0
    late = t >= 1.0
    assert np.allclose(a[late, 0], np.radians(25.0) * np.sin(2 * np.pi * turned.YAW_HZ * t[late]))
    assert np.allclose(a[late, 1], np.radians(10.0) * np.sin(2 * np.pi * turned.PITCH_HZ * t[late] + 1.0))
    assert np.degrees(np.abs(a[:, 0])).max() == pytest.approx(25.0, abs=0.05)


def test_the_rotation_is_a_yaw_then_a_pitch():
    R = turned.rotation(np.radians(30.0), 0.0)
    assert np.allclose(R @ [0.0, 0.0, -1.0], [0.5, 0.0, -np.cos(np.radians(30.0))])    # a point nearer: right
    R = turned.rotation(0.0, np.radians(30.0))
    assert np.allclose(R @ [0.0, 0.0, -1.0], [0.0, 0.5, -np.cos(np.radians(30.0))])    # ... and down
    R = turned.rotation(0.4, -0.3)
    assert np.allclose(R @ R.T, np.eye(3)) and np.linalg.det(R) == pytest.approx(1.0)


def test_no_turn_leaves_the_frame_as_it_was():
    rng = np.random.default_rng(1)
    rgb = rng.integers(0, 256, (240, 240, 3), dtype=np.uint8)
    P = _plane()
    P[:, 2] = rng.uniform(-30.0, 30.0, len(P))
    triangles, outline = turned.mesh(P)
    out = turned.turn(rgb, P, triangles, outline, 0.0, 0.0)
    assert out is not rgb and np.array_equal(out, rgb)


def test_a_mark_on_a_turned_plane_lands_where_its_point_is_projected():
    """A flat face turned 30 degrees about its middle: a dark dot 40 pixels right of the middle lands
    40 cos(30 deg) right of it (to a pixel), the rows unmoved; a dot on a plane pitched lands as many rows off."""
    rgb = np.full((240, 240, 3), 200, np.uint8)
    cv2.circle(rgb, (160, 120), 4, (0, 0, 0), -1)
    P = _plane()
    triangles, outline = turned.mesh(P)

    def dot(img):
        ys, xs = np.nonzero(img[..., 0] < 100)
        return xs.mean(), ys.mean()

    x, y = dot(turned.turn(rgb, P, triangles, outline, np.radians(30.0), 0.0))
    assert x == pytest.approx(120 + 40 * np.cos(np.radians(30.0)), abs=1.0)
    assert y == pytest.approx(120.0, abs=0.5)
    rgb = np.full((240, 240, 3), 200, np.uint8)
    cv2.circle(rgb, (120, 160), 4, (0, 0, 0), -1)
    x, y = dot(turned.turn(rgb, P, triangles, outline, 0.0, np.radians(40.0)))
    assert (x, y) == (pytest.approx(120.0, abs=0.5), pytest.approx(120 + 40 * np.cos(np.radians(40.0)), abs=1.0))


def test_what_stands_nearer_hides_what_it_turns_in_front_of():
    """A plane with a spike standing 60 pixels towards the camera at its middle, its tip painted red: turned
    20 degrees, the tip is drawn where it is projected, 60 sin(20 deg) right of the middle, over the plane behind, and
    nothing red is left where it stood."""
    rgb = np.full((240, 240, 3), 200, np.uint8)
    cv2.circle(rgb, (120, 120), 5, (255, 0, 0), -1)
    P = _plane(n=9)
    middle = np.argmin(np.linalg.norm(P[:, :2] - 120.0, axis=1))
    P[middle, 2] = -60.0
    triangles, outline = turned.mesh(P)
    out = turned.turn(rgb, P, triangles, outline, np.radians(20.0), 0.0)
    red = (out[..., 0] > 200) & (out[..., 1] < 80)
    ys, xs = np.nonzero(red)
    assert xs.max() == pytest.approx(120 + 60 * np.sin(np.radians(20.0)), abs=1.0)
    assert red[118:123, 137].all() and ys.mean() == pytest.approx(120.0, abs=0.5)
    assert not red[:, :126].any()


@pytest.mark.skipif(not (ASSETS / "models" / "face_landmarker.task").is_file() and not os.environ.get("CI"),
                    reason="needs ../shared/assets (the landmark model and the performers' clips)")
def test_a_performers_turned_copy_turns_as_meant():
    """performer_c turned 25 degrees either way: MediaPipe's head yaw on the copy follows the sweep put in, in
    sign and at about 0.6 of its size (``turned.DEPTH_SCALE``; the performer's own head barely turns)."""
    from facepuppet.capture.pose import FRONTAL_ROTATION
    from facepuppet.capture.tracking import make_tracker

    model = str(ASSETS / "models" / "face_landmarker.task")
    mp = make_tracker("mediapipe", model_path=model)
    yaw, added = [], []
    try:
        for i, (rgb, a) in enumerate(turned.turned_frames(ASSETS / "video" / "performer_c.mp4", model, 25.0, 0.0)):
            if i % 4 == 0:
                f = mp.track(rgb, int(i * 1000 / 30))
                assert f.valid
                m = FRONTAL_ROTATION @ f.rotation
                yaw.append(np.degrees(np.arctan2(m[0, 2], m[2, 2])))
                added.append(np.degrees(a[0]))
            if i >= 160:
                break
    finally:
        mp.close()
    slope = np.polyfit(added, yaw, 1)[0]
    assert np.corrcoef(yaw, added)[0, 1] > 0.95
    assert 0.45 < slope < 0.8
