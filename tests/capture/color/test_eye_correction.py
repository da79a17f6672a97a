"""The eyes' correction of the aligned face frame, held against the alignment
(:func:`facepuppet.capture.color.face.far_correction`): known answers on the digital performer."""

import numpy as np

from facepuppet.capture.color.face import FAR_TURN, far_correction
from facepuppet.capture.color.tracker import ColorTracker


def _turn_about(deg: float, centre: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """The correction (a, b, tx, ty) turning by ``deg`` degrees (and scaling) about ``centre`` (2,) crop pixels."""
    t = np.radians(deg)
    a, b = scale * np.cos(t), scale * np.sin(t)
    R = np.array([[a, -b], [b, a]])
    return np.r_[a, b, centre - R @ centre]


def _turn_of(correction: np.ndarray) -> float:
    return float(np.degrees(np.arctan2(correction[1], correction[0])))


def test_a_correction_is_far_when_it_turns_past_the_bound_whatever_its_shift_and_scale():
    bound = float(np.degrees(FAR_TURN))
    centre = np.array([60.0, 40.0])
    assert not far_correction(np.array([1.0, 0.0, 12.0, -9.0]))
    assert not far_correction(_turn_about(bound - 0.5, centre, 1.1))
    assert far_correction(_turn_about(-(bound + 0.5), centre, 0.9))
    assert far_correction(_turn_about(bound + 0.5, centre))


def test_eyes_held_far_from_the_aligned_face_are_searched_for_afresh():
    """A correction turned 20 degrees against the alignment (an eye held on a brow) is not searched from: the
    eye search starts on the aligned anchors, and the correction, smoothed towards what it finds, turns back to
    the settled one (searched from where it was, it stays turned)."""
    from facepuppet.demo.performer import render_performer
    from facepuppet.demo.script import KEY_NAMES

    frame = render_performer(np.zeros(len(KEY_NAMES)), size=(320, 320))
    tracker = ColorTracker()
    for i in range(6):
        assert tracker.track(frame, 33 * i).valid
    settled = tracker._follow.correction.copy()
    assert abs(_turn_of(settled)) < 2.0
    eyes = tracker._place.anchors_px[:2].mean(axis=0)
    tracker._follow.correction = _turn_about(20.0, eyes)
    for i in range(6, 20):
        assert tracker.track(frame, 33 * i).valid
    assert abs(_turn_of(tracker._follow.correction) - _turn_of(settled)) < 1.0
    np.testing.assert_allclose(tracker._follow.correction[2:], settled[2:], atol=1.5)
