"""The parts of the face each ARKit blendshape moves, and the regression held to them: known answers."""

from __future__ import annotations

import numpy as np

from facepuppet.capture.curves import POINT_NAMES
from facepuppet.pipeline.examples.regions import movable, point_region, regional_fit
from facepuppet.pipeline.examples.window import lowest_window


def test_point_regions_follow_the_curves():
    assert point_region("eye_left_upper:2") == "eye"
    assert point_region("brow_right:0") == "brow"
    assert point_region("lip_lower_inner:3") == "lip"
    assert point_region("nostril_left:1") == "nostril"
    assert point_region("chin:0") is None


def test_movable_by_blendshape_and_point():
    names = ("eye_left_upper:0", "brow_left:0", "lip_upper_outer:0", "nostril_left:0", "ear:0")
    got = movable([("eyeBlinkLeft", "eyeBlinkRight"), ("jawOpen",), ("noseSneerLeft",), ("browInnerUp",),
                   ("cheekSquintLeft",), ("somethingElse",)], names)
    expect = np.array([[1, 0, 0, 0, 1],
                       [0, 0, 1, 0, 1],
                       [0, 0, 1, 1, 1],
                       [0, 1, 0, 0, 1],
                       [1, 0, 0, 0, 1],
                       [1, 1, 1, 1, 1]], bool)               # unknown points and unknown blendshapes: all
    np.testing.assert_array_equal(got, expect)


def test_regional_fit_recovers_offset_and_displacements_exactly(rng):
    """Frames that are exactly c + X B with B zero outside each group's points: both come back."""
    P, D, F = len(POINT_NAMES), 3, 60
    groups = [("jawOpen",), ("mouthSmileLeft", "mouthSmileRight"), ("eyeBlinkLeft", "eyeBlinkRight")]
    allowed = movable(groups, POINT_NAMES)
    B = rng.normal(size=(3, P, D)) * allowed[:, :, None]
    c = rng.normal(size=(P, D))
    X = rng.uniform(0.2, 1.0, size=(F, 3))
    Y = c + np.einsum("fg,gpd->fpd", X, B)
    got_b, got_c = regional_fit(X, Y, allowed, 0.0, intercept=True)
    np.testing.assert_allclose(got_b, B, atol=1e-9)
    np.testing.assert_allclose(got_c, c, atol=1e-9)
    no_c, zero = regional_fit(X, Y - c, allowed, 0.0)
    np.testing.assert_allclose(no_c, B, atol=1e-9)
    assert not zero.any()


def test_lowest_window_over_the_whole_clip():
    cost = np.array([5.0, 1.0, 0.2, 0.1, 9.0, 0.0, 0.0, 0.0, 3.0])
    usable = np.ones(9, bool)
    assert lowest_window(cost, usable, 3) == (5, 8)
    usable[6] = False
    assert lowest_window(cost, usable, 3) == (1, 4)
    assert lowest_window(cost, np.zeros(9, bool), 3) is None
    assert lowest_window(cost, usable, 20) is None
