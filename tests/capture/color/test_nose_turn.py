"""The built-in profile's yaw and pitch (:mod:`facepuppet.capture.color.nose_turn`): known answers."""

import cv2
import numpy as np

from facepuppet.capture.color.nose_turn import (
    MIN_TIP_MATCH,
    NOSE_DEPTH,
    TIP_DEPTH,
    TIP_MISSES,
    TIP_REACH,
    TIP_SEARCH,
    NoseTurn,
    face_to_image,
    tip_detail,
    tip_shift,
    tip_window,
)
from facepuppet.capture.color.tracker import ColorTracker
from facepuppet.capture.color.turn import TURN_FILTER
from facepuppet.capture.pose import HeadPose, default_camera
from facepuppet.filters import OneEuro

UNIT = 100.0          # image pixels per face unit of the drawn faces
ORIGIN = (200.0, 120.0)


def _frame_map(unit=UNIT, origin=ORIGIN):
    """Face units -> image pixels of an upright face, eyes' midpoint at ``origin``."""
    return np.array([[unit, 0.0, origin[0]], [0.0, unit, origin[1]]])


def _nose(axis_x, rng=None, size=(400, 300), down=0.0, scale=1.0):
    """A drawn nose mirror-symmetric about face x = ``axis_x``, ``down`` face units lower than its place: two
    dark nostrils, a bright tip, dark sides, on skin with a light gradient across it (and noise from ``rng``);
    ``scale`` times as many pixels each way (the face frame ``_frame_map(UNIT * scale, ORIGIN * scale)``)."""
    w, h = int(size[0] * scale), int(size[1] * scale)
    yy, xx = np.mgrid[0:h, 0:w].astype(float) / scale
    w /= scale
    u, v = (xx - ORIGIN[0]) / UNIT - axis_x, (yy - ORIGIN[1]) / UNIT - down
    g = 150.0 + 40.0 * (xx / w)                                            # the light's slope: not symmetric
    g -= 70.0 * np.exp(-(((np.abs(u) - 0.12) / 0.05) ** 2 + ((v - 0.78) / 0.03) ** 2))   # nostrils
    g += 50.0 * np.exp(-((u / 0.07) ** 2 + ((v - 0.65) / 0.06) ** 2))                  # the tip's highlight
    g -= 30.0 * np.exp(-(((np.abs(u) - 0.2) / 0.03) ** 2)) * ((v > 0.35) & (v < 0.8))    # the nose's sides
    if rng is not None:
        g += rng.normal(0.0, 4.0, g.shape)
    grey = np.clip(g, 0, 255).astype(np.uint8)
    return np.dstack([grey, (grey * 0.8).astype(np.uint8), (grey * 0.7).astype(np.uint8)])


def test_a_tip_unlike_the_reference_gives_no_reading(rng):
    """After a nose turned d face units (yaw asin(d / k)), a frame whose tip region is noise (detail, but
    nothing like the reference's: a match under MIN_TIP_MATCH) keeps both angles; the nose back at its
    neutral place reads no turn again."""
    turn = NoseTurn(frames=31, every=1)
    M = _frame_map()
    for _ in range(10):
        turn(_nose(0.0), M)
    d = 0.06
    got = turn(_nose(d), M)
    assert abs(got[0] - np.arcsin(d / NOSE_DEPTH)) < 0.01, got
    noise = rng.integers(0, 256, (300, 400, 3), dtype=np.uint8)
    x0, y0, x1, y1 = tip_window()
    reference = np.ascontiguousarray(tip_detail(_nose(0.0), M)[y0:y1, x0:x1])
    assert tip_shift(tip_detail(noise, M), reference)[2] < MIN_TIP_MATCH
    np.testing.assert_array_equal(turn(noise, M), got)
    assert np.abs(turn(_nose(0.0), M)).max() < 0.01


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
        assert np.abs(turn(_nose(0.02), M)).max() < 1e-3
    d = 0.08
    got = turn(_nose(0.02 + d), M)
    assert abs(got[0] - np.arcsin(d / NOSE_DEPTH)) < 0.015, got
    assert abs(got[1]) < 0.01, got                    # moved sideways: no nod
    # a frame with no detail in the nose region keeps the last reading
    np.testing.assert_array_equal(turn(np.full((300, 400, 3), 128, np.uint8), M), got)


def test_a_tip_turned_past_the_search_is_followed_sideways_to_the_reach():
    """A nose facing the camera, then turning step by step to 0.46 face units aside (past TIP_SEARCH from its
    first place, within TIP_REACH): each step is found from the last reading, so the yaw keeps growing as
    asin(d / k) from the neutral; turned back it reads no turn. A nose lowered that far at once is sought only
    TIP_SEARCH from its reference's place (the nod's range), and gives no reading."""
    assert TIP_SEARCH < 0.46 < TIP_REACH
    turn, M = NoseTurn(frames=301, every=1), _frame_map()
    for _ in range(40):
        turn(_nose(0.0), M)
    for d in np.arange(0.04, 0.47, 0.04):
        got = turn(_nose(d), M)
    assert abs(got[0] - np.arcsin(0.44 / NOSE_DEPTH)) < 0.02, got
    for d in np.arange(0.40, -0.01, -0.04):
        got = turn(_nose(d), M)
    assert np.abs(got).max() < 0.02, got
    held = turn(_nose(0.0, down=0.45), M)
    np.testing.assert_array_equal(held, got)


def test_the_tip_is_found_where_it_was_moved():
    """The drawn nose moved (dx, dy) face units from the reference's place is found there to a quarter of a
    sample (0.005 face units), with a match over 0.9; a region without detail gives the shift 0 and match 0."""
    M = _frame_map()
    x0, y0, x1, y1 = tip_window()
    reference = np.ascontiguousarray(tip_detail(_nose(0.0), M)[y0:y1, x0:x1])
    for dx, dy in ((0.0, 0.0), (0.05, -0.03), (-0.11, 0.17), (0.023, 0.061), (0.3, 0.3), (-0.3, -0.29)):
        got = tip_shift(tip_detail(_nose(dx, down=dy), M), reference)
        assert abs(got[0] - dx) < 0.005 and abs(got[1] - dy) < 0.005 and got[2] > 0.9, (dx, dy, got)
        # sought only near a given place (to the search's edge): found there too
        near = tip_shift(tip_detail(_nose(dx, down=dy), M), reference, (0.9 * dx, 0.9 * dy), 0.05)
        assert abs(near[0] - dx) < 0.005 and abs(near[1] - dy) < 0.005, (dx, dy, near)
    # a tip 0.2 face units from where it is sought within 0.05 is not found: the best place there is worse
    got = tip_shift(tip_detail(_nose(0.2), M), reference, (0.0, 0.0), 0.05)
    assert abs(got[0]) <= 0.05 + 1e-9 and got[2] < 0.9, got
    assert tip_shift(tip_detail(np.full((300, 400, 3), 128, np.uint8), M), reference) == (0.0, 0.0, 0.0)


def test_a_face_of_many_pixels_to_a_sample_gives_the_same_detail():
    """The drawn nose filmed with 2.5 and 5 times as many pixels (a sample spanning 5 and 10 pixels: the frame
    halved by pyramid levels before sampling) gives the detail of the face of 2 pixels to a sample (correlation
    over 0.98, found where it is to 0.002 face units), and its moved tip is found where it was moved, to a
    quarter of a sample."""
    x0, y0, x1, y1 = tip_window()
    small = tip_detail(_nose(0.0), _frame_map())
    for scale in (2.5, 5.0):
        M = _frame_map(UNIT * scale, (ORIGIN[0] * scale, ORIGIN[1] * scale))
        big = tip_detail(_nose(0.0, scale=scale), M)
        assert big.shape == small.shape
        assert np.corrcoef(big.ravel(), small.ravel())[0, 1] > 0.98, scale
        # and where the small face's: the pyramid's halving keeps pixel x of the half at pixel 2x of the whole
        assert np.abs(tip_shift(big, np.ascontiguousarray(small[y0:y1, x0:x1]))[:2]).max() < 0.002, scale
        reference = np.ascontiguousarray(big[y0:y1, x0:x1])
        for dx, dy in ((0.05, -0.03), (-0.11, 0.17), (0.023, 0.061)):
            got = tip_shift(tip_detail(_nose(dx, down=dy, scale=scale), M), reference)
            assert abs(got[0] - dx) < 0.005 and abs(got[1] - dy) < 0.005 and got[2] > 0.9, (scale, dx, dy, got)


def test_a_tip_lost_for_long_is_taken_afresh(rng):
    """A nose read turned d (its first tip at 0), then TIP_MISSES frames of smooth texture that match no tip:
    the angles are held meanwhile; the tip is then taken afresh, so the same nose reads no turn (its place is
    the new reference's and the new neutral's), while a nose whose tip was not lost for long still reads d."""
    M = _frame_map()
    smooth = cv2.GaussianBlur(rng.integers(0, 256, (300, 400, 3), dtype=np.uint8), (0, 0), 3.0)
    d = 0.06
    for misses, turned in ((TIP_MISSES, False), (TIP_MISSES - 1, True)):
        turn = NoseTurn(frames=31, every=1)
        for _ in range(10):
            turn(_nose(0.0), M)
        got = turn(_nose(d), M)
        for _ in range(misses):
            np.testing.assert_array_equal(turn(smooth, M), got)
        again = turn(_nose(d), M)
        expected = np.arcsin(d / NOSE_DEPTH) if turned else 0.0
        assert abs(again[0] - expected) < 0.01, (misses, again)


def test_pitch_is_read_against_the_running_neutral():
    """A nose that stays put reads no nod; its tip moved down by d face units from that neutral reads
    asin(d / k), up by d -asin(d / k); a frame with no detail holds the last reading."""
    turn = NoseTurn(frames=31, every=1)
    M = _frame_map()
    for _ in range(20):
        assert np.abs(turn(_nose(0.0, down=0.03), M)).max() < 1e-3
    d = 0.1
    got = turn(_nose(0.0, down=0.03 + d), M)
    assert abs(got[1] - np.arcsin(d / TIP_DEPTH)) < 0.01 and abs(got[0]) < 0.01, got
    assert abs(turn(_nose(0.0, down=0.03 - d), M)[1] + np.arcsin(d / TIP_DEPTH)) < 0.01
    held = turn(np.full((300, 400, 3), 128, np.uint8), M)
    assert abs(held[1] + np.arcsin(d / TIP_DEPTH)) < 0.01


def test_a_mirrored_frame_reads_the_opposite_yaw(assets):
    """performer_a turning its head, and the same frames mirrored left to right: the yaw comes out with the
    opposite sign (the nose's tip and the face frame mirror with the face)."""
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


def _drawn_turns(yaw: float, pitch: float):
    """(got, true) (80, 3) degrees: yaw, pitch and roll of the digital performer (320 x 320, neutral face)
    turning ``yaw`` degrees either way (two sweeps), nodding ``pitch`` (one and a half) and rolling 8, as the
    colour tracker with the built-in profile reads them and as they are."""
    from facepuppet.demo.performer import head_pose, render_performer
    from facepuppet.demo.script import KEY_NAMES

    size = (320, 320)
    phase = np.linspace(0.0, 4.0 * np.pi, 80)
    motion = np.zeros((len(phase), 6))
    motion[:, 0] = np.radians(yaw) * np.sin(phase)
    motion[:, 1] = np.radians(pitch) * np.sin(0.75 * phase + 0.5)
    motion[:, 2] = np.radians(8.0) * np.sin(phase + 1.0)
    tracker = ColorTracker()
    K = default_camera(size)
    got, true = [], []
    for i, m in enumerate(motion):
        f = tracker.track(render_performer(np.zeros(len(KEY_NAMES)), m, size), 33 * i)
        assert f.valid
        got.append(HeadPose(f.rotation, f.translation, K).angles())
        true.append(head_pose(m, size).angles())
    return np.degrees(got), np.degrees(true)


def test_the_drawn_performer_turning_its_head_reads_its_yaw():
    """The digital performer turning its head from side to side: the built-in profile's yaw follows the true
    one, the right way round (the drawn nose is flatter than a real one: it reads under the true turn), no nod
    is read from the turn, and the roll still follows the true one."""
    got, true = _drawn_turns(10.0, 0.0)
    # Measured: yaw r 0.95, slope 0.44; the pitch's spread 0.19 degrees; roll r 1.00, largest error under 1.
    assert np.corrcoef(got[:, 0], true[:, 0])[0, 1] > 0.9
    assert 0.15 < np.polyfit(true[:, 0], got[:, 0], 1)[0] < 1.5
    assert got[:, 1].std() < 0.6
    assert np.corrcoef(got[:, 2], true[:, 2])[0, 1] > 0.9
    assert np.abs(got[:, 2] - true[:, 2]).max() < 3.0


def test_the_drawn_performer_nodding_reads_its_pitch():
    """The digital performer nodding: the built-in profile's pitch (the nose's tip against the eyes) follows
    the true one, the right way round and under it (the drawn nose is flat), and no turn is read from the
    nod; nodding while it turns, both follow theirs."""
    got, true = _drawn_turns(0.0, 10.0)
    # Measured: pitch r 0.92, slope 0.15; the yaw's spread 1.1 degrees. Both: yaw r 0.86, pitch r 0.86.
    assert np.corrcoef(got[:, 1], true[:, 1])[0, 1] > 0.85
    assert 0.07 < np.polyfit(true[:, 1], got[:, 1], 1)[0] < 1.5
    assert got[:, 0].std() < 2.0
    got, true = _drawn_turns(10.0, 10.0)
    assert np.corrcoef(got[:, 0], true[:, 0])[0, 1] > 0.75
    assert np.corrcoef(got[:, 1], true[:, 1])[0, 1] > 0.75
    assert np.corrcoef(got[:, 2], true[:, 2])[0, 1] > 0.9


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
    assert abs(got[0] - np.arcsin(d / NOSE_DEPTH)) < 0.015, got
    assert not turn.due
    np.testing.assert_array_equal(turn.skip(), got)
    np.testing.assert_array_equal(turn.skip(), got)
    assert turn.due


def test_the_turns_filter_follows_a_quick_turn_and_calms_a_still_head(rng):
    """The yaw and pitch's filter (TURN_FILTER) at 30 frames a second: a steady turn of 60 degrees a second lags
    under half a frame after two seconds; white noise of 0.3 degrees on a still head moves the output under a
    quarter as much from frame to frame."""
    dt, speed = 1.0 / 30.0, np.radians(60.0)
    f = OneEuro(TURN_FILTER)
    f.restart(np.zeros(2))
    for i in range(1, 61):
        out = f(np.array([speed * i * dt, 0.0]), dt)
    assert 0.0 < (speed * 60 * dt - out[0]) / (speed * dt) < 0.5
    f = OneEuro(TURN_FILTER)
    f.restart(np.zeros(2))
    noise = np.radians(0.3) * rng.standard_normal((300, 2))
    calm = np.array([f(x, dt) for x in noise])
    assert np.abs(np.diff(calm, axis=0)).mean() < 0.25 * np.abs(np.diff(noise, axis=0)).mean()
