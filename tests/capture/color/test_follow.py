"""The follow state's evidence rules and the search area around a face, on known numbers."""

import numpy as np

from facepuppet.capture.color.config import FollowConfig
from facepuppet.capture.color.detect import AROUND, search_area
from facepuppet.capture.color.face import FaceFrame
from facepuppet.capture.color.follow import OWN_LIKENESS, UNIT_JUMP, FollowState

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
