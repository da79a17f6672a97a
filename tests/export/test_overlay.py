"""Overlay drawing (curves, head axes) and the overlay video (frame count, nothing left on failure)."""

import cv2
import numpy as np
import pytest

from facepuppet.capture.curves import CURVE_NAMES, POINT_NAMES
from facepuppet.capture.features import FrameFeatures
from facepuppet.capture.pose import FRONTAL_ROTATION
from facepuppet.errors import FacepuppetError
from facepuppet.export.overlay import AXIS_COLOURS, CURVE_COLOUR, OverlayWriter, draw_overlay, write_overlay_video
from facepuppet.io.track import Track

SIZE = 200  # square frames; default focal = 200 px


def frontal_features(curve_y=170.0):
    """A frontal head 50 cm away on the optical axis (origin at the image centre) and one straight curve."""
    curves = np.full((len(CURVE_NAMES), 4, 2), np.nan)
    curves[0] = np.linspace([20.0, curve_y], [180.0, curve_y], 4)
    return FrameFeatures(valid=True, curves=curves, rotation=FRONTAL_ROTATION.copy(),
                         translation=np.array([0.0, 0.0, 50.0]), points=np.zeros((len(POINT_NAMES), 3)))


def close_to(pixel, colour, tol=40):
    return np.abs(pixel.astype(int) - colour).max() <= tol


def test_curve_and_head_axes_are_drawn_where_they_project():
    black = np.zeros((SIZE, SIZE, 3), np.uint8)
    out = draw_overlay(black, frontal_features())
    assert out.shape == black.shape and out.dtype == np.uint8 and not black.any()  # input untouched
    # the curve along y = 170 from x = 20 to 180
    assert close_to(out[170, 100], CURVE_COLOUR) and close_to(out[170, 30], CURVE_COLOUR)
    assert not out[150, 100].any() and not out[190, 100].any() and not out[170, 5].any()
    # head x axis (performer's left = image right), 5 cm at 50 cm with f = 200 px: 20 px to the right
    assert close_to(out[100, 110], AXIS_COLOURS[0])
    # head y axis points up in the image
    assert close_to(out[90, 100], AXIS_COLOURS[1])
    assert not out[100, 70].any() and not out[130, 100].any()  # nothing to the left or below the origin


def test_lost_frame_is_marked_and_draws_no_curves():
    grey = np.full((SIZE, SIZE, 3), 50, np.uint8)
    out = draw_overlay(grey, FrameFeatures.lost(len(CURVE_NAMES), len(POINT_NAMES)))
    assert (out != grey).any()  # the "no face" mark
    assert (out[60:, :] == 50).all()  # in the top corner only


def make_track(n, valid=None):
    f = frontal_features()
    valid = np.ones(n, bool) if valid is None else np.asarray(valid)
    track = Track(fps=20.0, frame_size=np.array([SIZE, SIZE]), valid=valid,
                  curves=np.repeat(f.curves[None], n, 0), curve_names=CURVE_NAMES,
                  points=np.zeros((n, len(POINT_NAMES), 3)), point_names=POINT_NAMES,
                  rotation=np.repeat(f.rotation[None], n, 0), translation=np.repeat(f.translation[None], n, 0),
                  backend="test")
    return track


def write_video(path, n, size=SIZE):
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 20.0, (size, size))
    for _ in range(n):
        w.write(np.zeros((size, size, 3), np.uint8))
    w.release()
    return path


def read_frames(path):
    cap = cv2.VideoCapture(str(path))
    frames = []
    while True:
        ok, bgr = cap.read()
        if not ok:
            break
        frames.append(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))
    cap.release()
    return frames


def test_overlay_video_has_one_frame_per_tracked_frame(tmp_path):
    media = write_video(tmp_path / "in.mp4", 7)
    out = tmp_path / "overlay.mp4"
    write_overlay_video(out, media, make_track(5, valid=[1, 1, 0, 1, 1]))
    frames = read_frames(out)
    assert len(frames) == 5  # the track's length, not the medium's
    assert frames[0].shape == (SIZE, SIZE, 3)
    r, g, b = frames[0][170, 100].astype(int)
    assert r > 150 and g > 150 and b < 100  # the yellow curve, blurred a little by compression
    assert frames[2][170, 100].max() < 40  # lost frame: no curve
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.mp4", "overlay.mp4"]


def test_overlay_video_of_a_different_size_leaves_nothing(tmp_path):
    media = write_video(tmp_path / "in.mp4", 3, size=100)
    with pytest.raises(FacepuppetError, match="frame size 100x100 differs"):
        write_overlay_video(tmp_path / "overlay.mp4", media, make_track(3))
    assert [p.name for p in tmp_path.iterdir()] == ["in.mp4"]


def test_overlay_writer_leaves_nothing_on_error_or_without_frames(tmp_path):
    out = tmp_path / "o.mp4"
    f = frontal_features()
    with pytest.raises(RuntimeError, match="boom"), OverlayWriter(out, (SIZE, SIZE), 20.0) as w:
        w.write(np.zeros((SIZE, SIZE, 3), np.uint8), f)
        raise RuntimeError("boom")
    with pytest.raises(FacepuppetError, match="no frames"), OverlayWriter(out, (SIZE, SIZE), 20.0):
        pass
    with pytest.raises(FacepuppetError, match="frame of 10x10"), OverlayWriter(out, (SIZE, SIZE), 20.0) as w:
        w.write(np.zeros((10, 10, 3), np.uint8), f)
    assert list(tmp_path.iterdir()) == []
