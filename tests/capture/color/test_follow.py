"""The follow state's evidence rules and the search area around a face, on known numbers."""

import numpy as np

from facepuppet.capture.color.config import FollowConfig
from facepuppet.capture.color.detect import AROUND, search_area
from facepuppet.capture.color.face import FaceFrame
from facepuppet.capture.color.follow import FRAME_MS, LOST_MEMORY, OWN_LIKENESS, UNIT_GAIN, UNIT_JUMP, FollowState

CFG = FollowConfig()


def _frame(unit=40.0):
    return FaceFrame(np.array([200.0, 150.0]), np.array([unit, 0.0]))


def test_the_face_is_kept_while_its_crop_matches_its_reference():
    state = FollowState(unit_ref=40.0)
    assert state.still_the_face(_frame(), CFG.min_correlation + 0.01, CFG)
    assert not state.still_the_face(_frame(), CFG.min_correlation - 0.01, CFG)
    assert not state.still_the_face(_frame(), None, CFG)                    # the alignment failed


def test_cheeks_no_longer_skin_need_a_closer_match():
    state = FollowState(unit_ref=40.0, skin=False, skin_found=True)
    cc = 0.5 * (CFG.min_correlation + CFG.skinless_correlation)
    assert not state.still_the_face(_frame(), cc, CFG)
    state.skin_found = False                  # never looked like skin to the models: the match alone decides
    assert state.still_the_face(_frame(), cc, CFG)


def test_missed_eyes_and_a_jump_in_size_lose_the_face():
    state = FollowState(unit_ref=40.0, misses=CFG.max_misses + 1)
    assert not state.still_the_face(_frame(), 0.99, CFG)
    state = FollowState(unit_ref=40.0)
    assert not state.still_the_face(_frame(40.0 * UNIT_JUMP[1] * 1.01), 0.99, CFG)
    assert state.still_the_face(_frame(44.0), 0.99, CFG)
    assert abs(state.unit_ref - (40.0 + 0.05 * 4.0)) < 1e-9                 # the slow reference follows


def test_a_face_found_again_must_look_like_itself_at_its_first_check():
    state = FollowState(score_ref=0.5, found_again=True)
    low = OWN_LIKENESS * 0.5 - 0.02                                          # above the least likeness (0.1)
    assert low > CFG.min_followed_score
    assert not state.still_like_a_face(low, CFG)
    state = FollowState(score_ref=0.5)                                       # followed all along: the low bar
    assert state.still_like_a_face(low, CFG)
    assert not state.still_like_a_face(-0.2, CFG)                            # averaged with the last: 0.04


def test_the_search_area_is_the_face_and_its_size_around_it_clipped_to_the_image():
    x0, y0, x1, y1 = search_area(_frame(40.0), (480, 640, 3))
    assert (x0, y0) == (int(200 + AROUND[0] * 40), int(150 + AROUND[1] * 40))
    assert (x1, y1) == (int(200 + AROUND[2] * 40) + 1, int(150 + AROUND[3] * 40) + 1)
    assert search_area(_frame(100.0), (480, 640, 3)) == (0, 0, 521, 480)


def _measured(frame, score=0.5):
    from facepuppet.capture.color.measure import Measurement

    return Measurement(curves=None, frame=frame, eyes_found=True, score=score, correction=np.zeros(4), seen=None)


def test_a_face_just_lost_is_found_again_only_near_where_it_was():
    from facepuppet.capture.color.acquire import LOST_REACH, likeness

    last = _frame(40.0)
    near = FaceFrame(last.origin + [0.9 * LOST_REACH * 40.0, 0.0], last.axis.copy())
    far = FaceFrame(last.origin + [0.0, 1.1 * LOST_REACH * 40.0], last.axis.copy())
    assert likeness(_measured(near), last, 0.3) == 0.5                    # same size: no resize cost
    assert likeness(_measured(far), last, 0.3) == -np.inf
    assert likeness(_measured(far), None, 0.3) == 0.5                     # no face just lost: anywhere


def test_skin_between_the_brows_is_read_in_the_glabella():
    from facepuppet.capture.color.acquire import GLABELLA, skin_between_brows
    from facepuppet.capture.color.face import CROP_EXTENT, SkinModel

    px = 48.0
    w, h = int(round((CROP_EXTENT[2] - CROP_EXTENT[0]) * px)), int(round((CROP_EXTENT[3] - CROP_EXTENT[1]) * px))
    skins = [SkinModel()]
    skin = np.zeros((h, w, 3), np.uint8)
    skin[:] = (200, 140, 115)                                  # inside the generic skin model
    assert skin_between_brows(skin, skins, px)
    # The scene above a skin-coloured object's edge: dark down to the eyes' height, skin below.
    edge = skin.copy()
    edge[:int(round((0.0 - CROP_EXTENT[1]) * px))] = (30, 30, 34)
    assert not skin_between_brows(edge, skins, px)
    # Dark only above the glabella (hair down to the brows): still skin between them.
    fringe = skin.copy()
    fringe[:int(round((GLABELLA[1] - CROP_EXTENT[1]) * px))] = (30, 30, 34)
    assert skin_between_brows(fringe, skins, px)


def test_the_light_gain_is_the_light_transforms_stretch_at_least_one():
    from facepuppet.capture.color.measure import Placement

    place = Placement(np.zeros((3, 2)), np.zeros(2), calibrated=True)
    assert place.light_gain == 1.0
    place.light = np.column_stack([np.diag([2.0, 2.5, 3.0]), np.full(3, -10.0)])
    assert abs(place.light_gain - 2.5) < 1e-12
    place.light = np.diag([0.8, 0.9, 0.7])                  # a bright frame toned down: no more noise than filmed
    assert place.light_gain == 1.0


def test_the_slow_size_reference_follows_in_time_not_in_calls():
    # Every 4th frame of a 30 fps clip (133 ms apart): the reference moves as far as it would in 4 frames.
    state = FollowState(unit_ref=40.0)
    assert state.still_the_face(_frame(44.0), 0.99, CFG, ms=0.0)           # the first: one frame's gain
    assert abs(state.unit_ref - (40.0 + UNIT_GAIN * 4.0)) < 1e-9
    ref = state.unit_ref
    assert state.still_the_face(_frame(44.0), 0.99, CFG, ms=4 * FRAME_MS)
    assert abs(state.unit_ref - (ref + (1.0 - (1.0 - UNIT_GAIN) ** 4) * (44.0 - ref))) < 1e-9
    dense = FollowState(unit_ref=40.0)
    for k in range(5):
        dense.still_the_face(_frame(44.0), 0.99, CFG, ms=k * FRAME_MS)
    assert abs(dense.unit_ref - state.unit_ref) < 1e-9                    # every frame: the same reference


def test_a_lost_face_is_remembered_for_a_time_then_forgotten():
    state = FollowState(frame=_frame(), unit_ref=40.0, score_ref=0.5)
    state.drop(1000.0)
    assert state.frame is None and state.dropped is not None
    lost = state.lost_face(1300.0)
    assert lost.ms == 300.0 and lost.unit == 40.0 and lost.frame is state.dropped
    state.drop(1000.0 + LOST_MEMORY)                                       # still lost, just within memory
    assert state.dropped is not None and state.score_ref == 0.5
    state.drop(1000.0 + LOST_MEMORY + 1.0)
    assert state.dropped is None and state.score_ref is None and state.lost_face(3000.0) is None


def test_a_face_found_again_elsewhere_is_the_face_lost_only_once_it_has_passed_its_checks():
    """A candidate taken beside the face and lost at once leaves the search where the face was lost before it; one
    found about where the face was (behind a passing hand) is the face lost, lost when it was."""
    from facepuppet.capture.color.follow import NEAR, OWN_CHECKS

    state = FollowState(frame=_frame(), unit_ref=40.0, score_ref=0.5)
    state.drop(1000.0)
    first = state.lost_face(1100.0)
    wrong = FaceFrame(np.array([260.0, 110.0]), np.array([30.0, 30.0]))     # turned 45 degrees, up and aside
    state.frame, state.unit_ref, state.found_again = wrong, 55.0, OWN_CHECKS
    state.found(first, 1100.0)
    lost = state.lost_face(1200.0)                                          # lost again before its first check
    assert lost.frame is first.frame and lost.unit == 40.0 and lost.ms == 200.0
    state.drop(1200.0)
    assert state.dropped is first.frame and state.unit_ref == 40.0 and state.lost_face(1500.0).ms == 500.0
    # found again beside the face, lost long after the face was: the whole frame is searched
    last = state.lost_face(1500.0)
    state.frame, state.found_again = wrong, OWN_CHECKS
    state.found(last, 1500.0)
    assert state.lost_face(1000.0 + LOST_MEMORY + 1.0) is None
    # found again about where the face was (moved less than NEAR), lost before its checks: it is the face lost
    state = FollowState(frame=_frame(), unit_ref=40.0, score_ref=0.5)
    state.drop(1000.0)
    last = state.lost_face(1100.0)
    c, s = np.cos(0.9 * NEAR[2]), np.sin(0.9 * NEAR[2])
    near = FaceFrame(np.array([200.0 + 0.9 * NEAR[0] * 40.0, 150.0]), np.array([40.0 * c, 40.0 * s]))
    state.frame, state.found_again = near, OWN_CHECKS
    state.found(last, 1100.0)
    assert state.lost_face(1200.0).frame is near and state.lost_face(1200.0).ms == 0.0
    state.drop(1200.0)
    assert state.dropped is near and state.lost_face(1300.0).ms == 100.0 and state.pending is not None
    # kept through its checks: the face found again is the face now, wherever it is
    last = state.lost_face(1300.0)
    state.frame, state.found_again = wrong, OWN_CHECKS
    state.found(last, 1300.0)
    for _ in range(OWN_CHECKS):
        assert state.still_like_a_face(0.5, CFG)
    assert state.pending is None and state.lost_face(1400.0).frame is wrong
    state.drop(1400.0)
    assert state.dropped is wrong and state.lost_face(1500.0).ms == 100.0


def _textured_scene(seed=3, shape=(480, 640)):
    """A smooth random texture (RGB uint8): the alignment has something to lock on everywhere."""
    import cv2

    rng = np.random.default_rng(seed)
    grey = cv2.GaussianBlur(rng.uniform(0, 255, shape).astype(np.float32), (0, 0), 4.0)
    grey = cv2.normalize(grey, None, 20, 235, cv2.NORM_MINMAX).astype(np.uint8)
    return np.dstack([grey, grey, grey])


def _follower_started():
    """A follower (40 crop pixels a face unit) started on :func:`_textured_scene` with a face of 60 pixels at
    (320, 220): (follower, scene, face frame, px)."""
    from facepuppet.capture.color.face import CROP_EXTENT
    from facepuppet.capture.color.follow import Follower

    px = 40.0
    size = (int(round((CROP_EXTENT[2] - CROP_EXTENT[0]) * px)), int(round((CROP_EXTENT[3] - CROP_EXTENT[1]) * px)))
    scene = _textured_scene()
    start = FaceFrame(np.array([320.0, 220.0]), np.array([60.0, 0.0]))
    follower = Follower(size, px, FollowConfig(iterations=50))
    follower.start(scene, start)
    return follower, scene, start, px


def test_the_follower_refuses_an_alignment_of_the_wrong_size_and_keeps_where_it_was():
    import cv2

    follower, scene, start, px = _follower_started()
    # The scene grown by 8 % about the face's origin: the face is now 8 % bigger, where it was.
    grow = cv2.getRotationMatrix2D((320.0, 220.0), 0.0, 1.08)
    grown = cv2.warpAffine(scene, grow, (640, 480), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    A = start.crop_matrix(px)
    moved = follower.follow(grown, A, (0.8 * start.unit, 1.25 * start.unit))
    assert moved is not None and abs(moved.unit / start.unit - 1.08) < 0.01
    assert np.allclose(moved.origin, start.origin, atol=1.0)
    assert np.allclose(follower.aligned().origin, moved.origin) and abs(follower.aligned().unit - moved.unit) < 1e-9
    # The same move refused by the size asked for: None, and where the face was last aligned is kept.
    follower.start(scene, start)
    assert follower.follow(grown, A, (0.9 * start.unit, 1.05 * start.unit)) is None
    assert follower.correlation is not None                                   # the alignment itself succeeded
    kept = follower.aligned()
    assert np.allclose(kept.origin, start.origin, atol=1e-6) and abs(kept.unit - start.unit) < 1e-6


def test_a_face_stretched_one_way_keeps_the_size_of_the_axis_that_changed_least():
    """A turn stretches one axis of the alignment, a nod shortens the other, a move closer grows both: the face's
    size is what the axis that changed least from the size the last alignment gave it says."""
    import cv2

    from facepuppet.capture.color.face import CROP_EXTENT
    from facepuppet.capture.color.follow import Follower

    px = 40.0
    size = (int(round((CROP_EXTENT[2] - CROP_EXTENT[0]) * px)), int(round((CROP_EXTENT[3] - CROP_EXTENT[1]) * px)))
    scene = _textured_scene()
    start = FaceFrame(np.array([320.0, 220.0]), np.array([60.0, 0.0]))

    def stretched(sx, sy):
        """The scene stretched about the face's origin by sx across and sy down."""
        M = np.array([[sx, 0.0, 320.0 * (1 - sx)], [0.0, sy, 220.0 * (1 - sy)]])
        return cv2.warpAffine(scene, M, (640, 480), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)

    # (stretch across, stretch down, the face grown alike in a frame followed before, the size expected), sizes
    # as ratios of the reference's
    dw, dh = abs(np.log(1.08)), abs(np.log(0.96))
    cases = ((1.2, 1.0, None, 1.0), (1.0, 0.9, None, 1.0), (1.0, 1.15, None, 1.0), (1.1, 1.1, None, 1.1),
             (1.15, 1.05, 1.05, 1.05), (1.08, 0.96, None, np.exp((dh * np.log(1.08) + dw * np.log(0.96)) / (dw + dh))))
    sizes = (0.8 * start.unit, 1.4 * start.unit)
    for sx, sy, grown, expected in cases:
        follower = Follower(size, px, FollowConfig(iterations=50))
        follower.start(scene, start)
        before = start
        if grown is not None:
            before = follower.follow(stretched(grown, grown), start.crop_matrix(px), sizes)
            assert before is not None and abs(before.unit / start.unit - grown) < 0.01
        moved = follower.follow(stretched(sx, sy), before.crop_matrix(px), sizes)
        assert moved is not None, (sx, sy)
        assert abs(moved.unit / start.unit - expected) < 0.01, (sx, sy, grown, moved.unit / start.unit)
        assert abs(moved.roll) < 0.01 and np.allclose(moved.origin, start.origin, atol=1.0)
        # where the face was last aligned is read the same way
        assert abs(follower.aligned().unit - moved.unit) < 1e-6
    # sized by the horizontal axis alone (a trained profile's)
    follower = Follower(size, px, FollowConfig(iterations=50), both_axes=False)
    follower.start(scene, start)
    moved = follower.follow(stretched(1.2, 1.0), start.crop_matrix(px), sizes)
    assert moved is not None and abs(moved.unit / start.unit - 1.2) < 0.01


def test_a_crop_textured_along_one_direction_only_is_no_alignment_not_an_error():
    """A crop whose shading runs only down the frame (a sleeve's edge filling it, a smooth shade over a covered
    lens) leaves the affine's sideways parameters free: the alignment fails (None) and the follower keeps where it
    was."""
    follower, scene, start, px = _follower_started()
    shade = np.repeat(np.linspace(30, 220, 480)[:, None], 640, axis=1).astype(np.uint8)
    rows_only = np.dstack([shade, shade, shade])
    A = start.crop_matrix(px)
    assert follower.follow(rows_only, A) is None and follower.correlation is None
    assert np.allclose(follower.aligned().origin, start.origin)
    assert follower.follow(scene, A) is not None and follower.correlation > 0.99     # the face itself: a match
