"""The eye search's mean shift on the darkness under the skin's luma: the complexion does not move it, and brows
close above do not lift it."""

import cv2
import numpy as np
import pytest

from facepuppet.capture.color.config import ColorTrackerConfig
from facepuppet.capture.color.eye_anchors import (
    OPENING,
    OPENING_TABLE,
    dark_centres,
    darkness,
    eye_centres,
    eye_opening_centres,
    without_long_runs,
)
from facepuppet.capture.color.face import CROP_EXTENT, FEATURE_BOXES, box_in_crop
from facepuppet.capture.color.profile import GENERIC_ANCHORS
from facepuppet.capture.color.tracker import ColorTracker

PX = ColorTrackerConfig().measure.px
WINDOW = tuple(int(round(v * PX)) for v in ColorTrackerConfig().measure.eye_window)
ANCHORS = (GENERIC_ANCHORS - CROP_EXTENT[:2]) * PX
CHEEKS = np.array([box_in_crop(FEATURE_BOXES[k], PX) for k in ("cheek_right", "cheek_left")], dtype=np.int64)
#: Complexions: skin, iris (the skin's own hue, darker), lashes and hair (near black).
LIGHT = dict(skin=(205, 150, 120), iris=(70, 50, 42), lash=(30, 18, 15), hair=(45, 30, 25))
#: A dark complexion: the iris as coloured as the skin, lashes and hair near black and saturated, which sets the
#: contrast C's scale and leaves the iris faint in it.
DARK = dict(skin=(110, 60, 44), iris=(44, 24, 17), lash=(14, 3, 2), hair=(16, 3, 2))


def _face(tone, eyes, *, hair=True, brow_gap=None, rng=None):
    """A face crop (the tracker's size, uint8 RGB) of flat skin with two eyes at ``eyes`` (2, 2) crop pixels:
    each a white almond opening 23 px wide, a dark iris of radius 4 px at its centre, a lash line along its upper
    lid; with ``hair``, the hair beside the face from 16 px outward of the anchors (just outside the eye
    windows); with ``brow_gap``, a brow 4 px thick that many pixels above the opening's top."""
    w, h = ColorTracker().crop_size
    crop = np.empty((h, w, 3), np.float32)
    crop[:] = tone["skin"]
    for (cx, cy) in eyes:
        xs = np.arange(int(round(cx)) - 11, int(round(cx)) + 12)
        for x in xs:
            half = 4.0 * np.sqrt(max(1.0 - ((x - cx) / 11.5) ** 2, 0.0))
            top, bottom = int(round(cy - half)), int(round(cy + half))
            crop[top:bottom + 1, x] = (235, 230, 225)
            crop[top - 1:top + 1, x] = tone["lash"]
        cv2.circle(crop, (int(round(cx)), int(round(cy))), 4, tone["iris"], -1)
        if brow_gap is not None:
            y0 = int(round(cy - 4 - brow_gap - 4))
            crop[y0:y0 + 4, int(cx) - 14:int(cx) + 15] = tone["hair"]
    if hair:
        crop[:, :int(round(ANCHORS[0, 0] - 16))] = tone["hair"]
        crop[:, int(round(ANCHORS[1, 0] + 16)):] = tone["hair"]
    if rng is not None:
        crop += rng.normal(0.0, 2.0, crop.shape)
    return np.clip(crop + 0.5, 0, 255).astype(np.uint8)


def _contrast(crop):
    return ColorTracker().intensity(crop)


def test_darkness_is_a_smoothstep_under_the_skins_luma():
    grey = np.array([[[v, v, v] for v in (200, 140, 100, 70, 40, 0)]], dtype=np.uint8)   # luma = v
    D = darkness(grey, 200.0, 0.3, 0.8)
    # (200 - v) / 200: 0, 0.3 (start), 0.5 (t = 0.4), 0.65 (t = 0.7), 0.8 (full), 1.0.
    t = np.array([0.0, 0.0, 0.4, 0.7, 1.0, 1.0])
    np.testing.assert_allclose(D[0], t * t * (3 - 2 * t), atol=2e-3)


# The true eyes lie 3 px inward of the anchors and 1 px under them: a face frame a little too large, as the
# tracker meets it when its eye search has been pulled outward.
EYES = ANCHORS[:2] + [[3.0, 1.0], [-3.0, 1.0]]


def _found(tone, rng):
    crop = _face(tone, EYES, rng=rng)
    ok, found = eye_opening_centres(_contrast(crop), crop, CHEEKS, ANCHORS, *WINDOW, PX, OPENING_TABLE, True)
    assert ok
    return found


@pytest.mark.parametrize("tone", [LIGHT, DARK], ids=["light", "dark"])
def test_eyes_found_on_any_complexion_beside_the_hair(tone, rng):
    found = _found(tone, rng)
    np.testing.assert_allclose(found[:, 0], EYES[:, 0], atol=1.0)
    # The height: between the lash line (4 to 5 px up) and the iris's centre.
    assert np.all((found[:, 1] > EYES[:, 1] - 5.0) & (found[:, 1] < EYES[:, 1] + 0.5))


def test_the_complexion_does_not_move_the_eyes_found(rng):
    """The darkness is measured against the skin's own luma: the same face on a dark complexion (its iris as
    coloured as its skin) gives the same centres as on a light one."""
    np.testing.assert_allclose(_found(DARK, rng), _found(LIGHT, rng), atol=0.5)


def test_brows_close_above_do_not_lift_the_eye(rng):
    crop = _face(LIGHT, EYES, hair=False, brow_gap=3, rng=rng)
    D = darkness(crop, 0.299 * 205 + 0.587 * 150 + 0.114 * 120, 0.3, 0.8)
    above = int(round(OPENING["dark_above"][0] * PX))
    ok, found = dark_centres(D, ANCHORS, *WINDOW, above)
    assert ok
    clear = _face(LIGHT, EYES, hair=False, rng=rng)
    ok, alone = dark_centres(darkness(clear, 0.299 * 205 + 0.587 * 150 + 0.114 * 120, 0.3, 0.8), ANCHORS,
                             *WINDOW, above)
    np.testing.assert_allclose(found, alone, atol=0.5)
    # A window reaching as far up as down takes the brow in.
    ok, sym = dark_centres(D, ANCHORS, *WINDOW, WINDOW[1])
    assert np.all(sym[:, 1] < alone[:, 1] - 1.0)


def test_long_dark_runs_across_are_left_out_and_short_ones_kept():
    D = np.zeros((5, 40), np.float32)
    D[1, 2:30] = 1.0                        # a rim's line, 28 px long
    D[3, 5:15] = 0.9                        # an eye's blob's row, 10 px long
    D[3, 20] = 0.4                          # under the level: kept whatever its run
    out = without_long_runs(D, 0.5, 24)
    assert not out[1].any()
    np.testing.assert_array_equal(out[3], D[3])
    np.testing.assert_array_equal(D[1, 2:30], 1.0)      # the input is left as it was


def test_the_darkness_is_not_used_without_dark(rng):
    crop = _face(DARK, EYES, rng=rng)
    C = _contrast(crop)
    _, with_c = eye_opening_centres(C, crop, CHEEKS, ANCHORS, *WINDOW, PX, OPENING_TABLE, False)
    ok, by_c = eye_centres(C, ANCHORS, *WINDOW)
    assert ok
    # Without ``dark`` the height is the mean shift of C's (the opening only moves the place along the eye).
    np.testing.assert_allclose(with_c[:, 1], by_c[:, 1], atol=1e-9)
