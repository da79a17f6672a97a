"""Finding the face at its true size when the head is tilted or the light is cool or dark
(:mod:`facepuppet.capture.color.detect`, :class:`~facepuppet.capture.color.acquire.Acquirer`).

The answers are known without a reference tracker: a frame turned by an angle shows the same face turned, so the
eyes a fresh tracker finds on the turned frame are those it finds on the frame as filmed, turned the same way; a
frame in a cool or dark light shows the face where it was, at its size.
"""

import cv2
import numpy as np
import pytest

from facepuppet.capture.color.detect import BOX_UNIT, EYE_PLACES, TILTS, FaceWindow, face_windows
from facepuppet.capture.color.face import FaceFrame
from facepuppet.capture.curves import CURVE_NAMES

_IDX = {n: i for i, n in enumerate(CURVE_NAMES)}
#: Frames of each clip acquired (indices), apart enough to show different poses and expressions.
FRAMES = {"performer_b_exaggerated": (0, 40, 120), "performer_a": (0, 150)}
ANGLES = (-30.0, -20.0, -10.0, 10.0, 20.0, 30.0)


def _turn(angle, shape):
    h, w = shape[:2]
    return cv2.getRotationMatrix2D((w / 2.0, h / 2.0), angle, 1.0)


def _turned(rgb, angle):
    """The frame turned ``angle`` degrees counter-clockwise about its centre, edges reflected (a tilted head)."""
    h, w = rgb.shape[:2]
    return cv2.warpAffine(rgb, _turn(angle, rgb.shape), (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)


def _eyes(curves):
    """(right, left) eye centres (2, 2) of a frame's curves (the mean of each upper lid's end points)."""
    return np.stack([curves[_IDX[f"eye_{s}_upper"]][[0, 3]].mean(axis=0) for s in ("right", "left")])


def _acquired(rgb):
    """The eye centres (2, 2) a new colour tracker finds on one frame, or None."""
    from facepuppet.capture.color.tracker import ColorTracker

    f = ColorTracker().track(rgb, 0)
    return _eyes(f.curves) if f.valid else None


@pytest.fixture(scope="module", params=sorted(FRAMES))
def clip_frames(request, assets):
    name = request.param
    cap = cv2.VideoCapture(str(assets / "video" / f"{name}.mp4"))
    out, k = [], 0
    while k <= max(FRAMES[name]):
        ok, bgr = cap.read()
        if not ok:
            break
        if k in FRAMES[name]:
            out.append(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))
        k += 1
    cap.release()
    plain = [_acquired(rgb) for rgb in out]
    assert all(e is not None for e in plain)
    return name, out, plain


def test_a_window_holds_a_face_of_its_size_where_it_is():
    # A window of 100 pixels on a copy turned 30 degrees about (50, 50); the face frame its eyes give, and
    # frames of other sizes and places.
    T = cv2.getRotationMatrix2D((50.0, 50.0), 30.0, 1.0)
    win = FaceWindow(np.array([0.0, 0.0, 100.0, 100.0]), T)
    f = win.frame()
    assert abs(f.unit - (EYE_PLACES[1][0] - EYE_PLACES[0][0]) * 100.0) < 1e-9
    assert abs(np.degrees(f.roll) - 30.0) < 1e-9                        # the copy turned counter-clockwise
    assert np.allclose(T[:, :2] @ f.origin + T[:, 2], [50.0, 100.0 * EYE_PLACES[0][1]])
    assert win.holds(f)
    assert not win.holds(FaceFrame(f.origin, f.axis * BOX_UNIT[1] * 1.05 / (f.unit / 100.0)))    # too large
    assert not win.holds(FaceFrame(f.origin, f.axis * BOX_UNIT[0] * 0.95 / (f.unit / 100.0)))    # too small
    assert not win.holds(FaceFrame(f.origin + [0.0, 120.0], f.axis))                              # elsewhere


def test_a_tilted_face_is_found_by_its_turned_window(clip_frames):
    """The frame turned by the first tilt searched: the window of the copy turned back holds the face the upright
    search finds on the frame as filmed, turned."""
    name, frames, _ = clip_frames
    tilt = [t for t in TILTS if t][0]
    rgb = frames[0]
    upright = [w for w in face_windows(rgb, tilts=(0.0,))][0].frame()
    T = _turn(-tilt, rgb.shape)
    wins = face_windows(_turned(rgb, -tilt), tilts=(tilt,))
    assert wins, name
    f = wins[0].frame()
    want = FaceFrame(T[:, :2] @ upright.origin + T[:, 2], T[:, :2] @ upright.axis)
    assert np.hypot(*(f.origin - want.origin)) < 0.15 * want.unit, (f.origin, want.origin)
    assert abs(np.log(f.unit / want.unit)) < 0.1
    assert abs(np.degrees(f.roll - want.roll)) < 3.0


@pytest.mark.parametrize("angle", ANGLES)
def test_a_tilted_head_is_found_at_its_size(clip_frames, angle):
    """A new tracker on each frame turned by ``angle``: the eyes where the frame as filmed has them, turned; the
    eye-centre distance within 15 % of theirs, the error of each eye under 0.15 of it."""
    name, frames, plain = clip_frames
    for k, (rgb, eyes) in enumerate(zip(frames, plain, strict=True)):
        T = _turn(angle, rgb.shape)
        want = eyes @ T[:, :2].T + T[:, 2]
        got = _acquired(_turned(rgb, angle))
        assert got is not None, (name, k, angle)
        unit = float(np.linalg.norm(want[1] - want[0]))
        ratio = float(np.linalg.norm(got[1] - got[0])) / unit
        err = float(np.linalg.norm(got - want, axis=1).max()) / unit
        assert 0.85 < ratio < 1.15 and err < 0.15, (name, k, angle, round(ratio, 3), round(err, 3))


def _cool(rgb):
    """A monitor's or daylight's blue cast: red 0.8, blue 1.25."""
    return np.clip(rgb * np.array([0.8, 1.0, 1.25]) + 0.5, 0, 255).astype(np.uint8)


def _dark(rgb):
    """A dim brown light, or a darker complexion, roughly: levels to the power 1.6, then R, G, B by 0.72, 0.62,
    0.55."""
    return np.clip(255.0 * (rgb / 255.0) ** 1.6 * np.array([0.72, 0.62, 0.55]) + 0.5, 0, 255).astype(np.uint8)


@pytest.mark.parametrize("light", [_cool, _dark], ids=["cool", "dark"])
def test_a_face_in_cool_or_dark_light_is_found_at_its_size(clip_frames, light):
    name, frames, plain = clip_frames
    for k, (rgb, want) in enumerate(zip(frames, plain, strict=True)):
        got = _acquired(light(rgb))
        assert got is not None, (name, k)
        unit = float(np.linalg.norm(want[1] - want[0]))
        ratio = float(np.linalg.norm(got[1] - got[0])) / unit
        err = float(np.linalg.norm(got - want, axis=1).max()) / unit
        assert 0.85 < ratio < 1.15 and err < 0.15, (name, k, round(ratio, 3), round(err, 3))
