"""The built-in profile's yaw (:mod:`facepuppet.capture.color.nose_turn`): known answers."""

import numpy as np

from facepuppet.capture.color.nose_turn import (
    NOSE_DEPTH,
    PEAK_MARGIN,
    NoseTurn,
    face_to_image,
    nose_axis,
)
from facepuppet.capture.color.tracker import ColorTracker
from facepuppet.capture.pose import HeadPose, default_camera

UNIT = 100.0          # image pixels per face unit of the drawn faces
ORIGIN = (200.0, 120.0)


def _frame_map(unit=UNIT, origin=ORIGIN):
    """Face units -> image pixels of an upright face, eyes' midpoint at ``origin``."""
    return np.array([[unit, 0.0, origin[0]], [0.0, unit, origin[1]]])


def _nose(axis_x, rng=None, size=(400, 300)):
    """A drawn nose mirror-symmetric about face x = ``axis_x``: two dark nostrils, a bright tip, dark sides,
    on skin with a light gradient across it (and noise from ``rng``)."""
    w, h = size
    yy, xx = np.mgrid[0:h, 0:w].astype(float)
    u, v = (xx - ORIGIN[0]) / UNIT - axis_x, (yy - ORIGIN[1]) / UNIT
    g = 150.0 + 40.0 * (xx / w)                                            # the light's slope: not symmetric
    g -= 70.0 * np.exp(-(((np.abs(u) - 0.12) / 0.05) ** 2 + ((v - 0.78) / 0.03) ** 2))   # nostrils
    g += 50.0 * np.exp(-((u / 0.07) ** 2 + ((v - 0.65) / 0.06) ** 2))                  # the tip's highlight
    g -= 30.0 * np.exp(-(((np.abs(u) - 0.2) / 0.03) ** 2)) * ((v > 0.35) & (v < 0.8))    # the nose's sides
    if rng is not None:
        g += rng.normal(0.0, 4.0, g.shape)
    grey = np.clip(g, 0, 255).astype(np.uint8)
    return np.dstack([grey, (grey * 0.8).astype(np.uint8), (grey * 0.7).astype(np.uint8)])


def test_nose_axis_is_found_where_the_drawn_nose_is_symmetric(rng):
    for x in (-0.12, -0.03, 0.0, 0.05, 0.15):
        found = nose_axis(_nose(x, rng), _frame_map())
        assert found is not None and found[1] > 0.5
        assert abs(found[0] - x) < 0.01, (x, found)


def _stripes(period=0.16, size=(400, 300)):
    """Vertical dark stripes every ``period`` face units across the nose region: mirror-symmetric about each
    stripe and each gap between two, so the mirror match has several peaks of the same height."""
    w, h = size
    xx = np.mgrid[0:h, 0:w][1].astype(float)
    u = (xx - ORIGIN[0]) / UNIT
    grey = np.clip(150.0 - 60.0 * np.cos(2 * np.pi * u / period), 0, 255).astype(np.uint8)
    return np.dstack([grey, grey, grey])


def test_a_nose_alone_leads_and_a_match_of_several_peaks_gives_no_reading(rng):
    found = nose_axis(_nose(0.05, rng), _frame_map())
    assert found is not None and found[2] > PEAK_MARGIN
    found = nose_axis(_stripes(), _frame_map())
    assert found is not None and found[1] > 0.5 and found[2] < PEAK_MARGIN
    turn = NoseTurn(frames=31, every=1)
    M = _frame_map()
    for _ in range(10):
        turn(_nose(0.0), M)
    d = 0.06
    got = turn(_nose(d), M)
    assert abs(got - np.arcsin(d / NOSE_DEPTH)) < 0.015, got
    assert turn(_stripes(), M) == got                 # ambiguous: the last reading is held
    assert abs(turn(_nose(-d), M) + np.arcsin(d / NOSE_DEPTH)) < 0.015


def test_face_to_image_round_trips_the_crop():
    """A point of face units mapped by face_to_image lands where the crop matrix and the placement put it."""
    A = np.array([[0.4, 0.1, -20.0], [-0.1, 0.4, 5.0]])
    S = np.array([[1.05, -0.02, 3.0], [0.02, 1.05, -1.0]])
    px, origin = 48.0, (-1.3, -0.85)
    M = face_to_image(A, S, px, origin)
    p = np.array([0.3, 0.7])
    img = M[:, :2] @ p + M[:, 2]
    crop = A[:, :2] @ img + A[:, 2]
    unmoved = (p - origin) * px
    np.testing.assert_allclose(crop, S[:, :2] @ unmoved + S[:, 2], atol=1e-9)


def test_yaw_is_read_against_the_running_neutral():
    """A nose that stays put reads no turn; one moved by d face units from that neutral reads asin(d / k)."""
    turn = NoseTurn(frames=31, every=1)
    M = _frame_map()
    for _ in range(20):
        assert abs(turn(_nose(0.02), M)) < 1e-3
    d = 0.08
    got = turn(_nose(0.02 + d), M)
    assert abs(got - np.arcsin(d / NOSE_DEPTH)) < 0.015, got
    # a frame with no detail in the nose region keeps the last reading
    assert turn(np.full((300, 400, 3), 128, np.uint8), M) == got


def test_a_mirrored_frame_reads_the_opposite_yaw(assets):
    """performer_a turning its head, and the same frames mirrored left to right: the yaw comes out with the
    opposite sign (the nose's axis and the face frame mirror with the face)."""
    from facepuppet.io.frames import open_media

    with open_media(assets / "video" / "performer_a.mp4") as src:
        frames = [f for i, f in enumerate(src) if 200 <= i < 290]
    yaw, mirrored = [], []
    for out, flip in ((yaw, False), (mirrored, True)):
        tracker = ColorTracker()
        K = None
        for i, f in enumerate(frames):
            f = np.ascontiguousarray(f[:, ::-1]) if flip else f
            K = default_camera(f.shape[1::-1]) if K is None else K
            g = tracker.track(f, 33 * i)
            assert g.valid
            out.append(HeadPose(g.rotation, g.translation, K).angles()[0])
    yaw, mirrored = np.degrees(yaw), np.degrees(mirrored)
    assert yaw.std() > 2.0                                   # the head turns over these frames
    assert np.corrcoef(yaw, -mirrored)[0, 1] > 0.9
    assert np.abs(yaw + mirrored).mean() < 0.35 * np.abs(yaw).mean()


def test_the_drawn_performer_turning_its_head_reads_its_yaw():
    """The digital performer turning its head from side to side: the built-in profile's yaw follows the true
    one, the right way round (the drawn nose is flatter than a real one: it reads under the true turn), the
    pitch stays zero, and the roll still follows the true one."""
    from facepuppet.demo.performer import head_pose, render_performer
    from facepuppet.demo.script import KEY_NAMES

    size = (320, 320)
    phase = np.linspace(0.0, 4.0 * np.pi, 80)
    motion = np.zeros((len(phase), 6))
    motion[:, 0] = np.radians(10.0) * np.sin(phase)          # yaw
    motion[:, 2] = np.radians(8.0) * np.sin(phase + 1.0)     # roll
    tracker = ColorTracker()
    K = default_camera(size)
    got, true = [], []
    for i, m in enumerate(motion):
        f = tracker.track(render_performer(np.zeros(len(KEY_NAMES)), m, size), 33 * i)
        assert f.valid
        got.append(HeadPose(f.rotation, f.translation, K).angles())
        true.append(head_pose(m, size).angles())
    got, true = np.degrees(got), np.degrees(true)
    assert np.corrcoef(got[:, 0], true[:, 0])[0, 1] > 0.9
    assert 0.15 < np.polyfit(true[:, 0], got[:, 0], 1)[0] < 1.5
    assert np.abs(got[:, 1]).max() < 1e-6
    assert np.corrcoef(got[:, 2], true[:, 2])[0, 1] > 0.9
    assert np.abs(got[:, 2] - true[:, 2]).max() < 3.0


def test_calls_that_do_not_measure_are_counted_and_hold_the_last_reading():
    """With ``every=3`` the first of each three calls measures; :meth:`NoseTurn.skip` stands for a call that
    does not (the tracker skips building the frame's map), so measuring and skipping keep the same rhythm."""
    turn, M = NoseTurn(frames=31, every=3), _frame_map()
    pattern = []
    for _ in range(9):
        pattern.append(turn.due)
        if turn.due:
            turn(_nose(0.02), M)
        else:
            turn.skip()
    assert pattern == [True, False, False] * 3
    d = 0.08
    got = turn(_nose(0.02 + d), M)                 # the tenth call measures
    assert abs(got - np.arcsin(d / NOSE_DEPTH)) < 0.015, got
    assert not turn.due and turn.skip() == got and turn.skip() == got and turn.due
