"""A reflection on a lens found and filled in, on drawn face crops: the white of the eye is no reflection, a
bright colourless band across the eye and the skin below it is, and it is filled from its surroundings."""

import cv2
import numpy as np

from facepuppet.capture.color.face import CROP_EXTENT, FEATURE_BOXES, box_in_crop
from facepuppet.capture.color.glare import GLARE, glare_mask, without_glare

PX = 48.0
W, H = int(round((CROP_EXTENT[2] - CROP_EXTENT[0]) * PX)), int(round((CROP_EXTENT[3] - CROP_EXTENT[1]) * PX))
CHEEKS = np.array([box_in_crop(FEATURE_BOXES[k], PX) for k in ("cheek_left", "cheek_right")], dtype=np.int64)
EYES = np.array([box_in_crop(FEATURE_BOXES[k], PX) for k in ("eye_right", "eye_left")], dtype=np.int64)
SKIN = (200, 140, 115)


def _at(x, y):
    """Face units -> crop pixels."""
    return (x - CROP_EXTENT[0]) * PX, (y - CROP_EXTENT[1]) * PX


def _face():
    """A skin crop with two open eyes: the white (nearly colourless, brighter than the skin) around a dark iris."""
    crop = np.zeros((H, W, 3), np.uint8)
    crop[:] = SKIN
    for side in (-0.5, 0.5):
        cx, cy = _at(side, 0.0)
        cv2.ellipse(crop, ((cx, cy), (0.5 * PX, 0.2 * PX), 0.0), (232, 228, 225), -1)
        cv2.circle(crop, (int(cx), int(cy)), int(0.09 * PX), (60, 40, 30), -1)
        cv2.ellipse(crop, ((cx, cy), (0.5 * PX, 0.2 * PX), 0.0), (40, 30, 25), 1)
    return crop


def _band(crop):
    """The crop with a bright band (60 % of the way to white) slanting across the right eye, and its mask."""
    m = np.zeros((H, W), np.float32)
    pts = np.array([_at(-0.75, -0.15), _at(-0.6, -0.15), _at(-0.3, 0.3), _at(-0.45, 0.3)], np.int32)
    cv2.fillPoly(m, [pts], 1.0)
    a = (0.6 * m)[..., None]
    return np.clip(crop * (1.0 - a) + 245.0 * a + 0.5, 0, 255).astype(np.uint8), m > 0


def test_the_white_of_the_eye_is_no_reflection():
    crop = _face()
    assert glare_mask(crop, CHEEKS, EYES, PX) is None
    assert without_glare(crop, CHEEKS, EYES, PX) is crop


def test_a_bright_band_across_the_eye_is_found_and_filled_from_its_surroundings():
    face = _face()
    crop, band = _band(face)
    mask = glare_mask(crop, CHEEKS, EYES, PX)
    assert mask is not None
    found = mask > 0
    assert found[band].mean() > 0.95                            # the band (and its edge, grown)
    # Nothing else but the white of the eye the band crosses, which it joins: not the other eye's white.
    touched = band.astype(np.uint8)
    cv2.ellipse(touched, (_at(-0.5, 0.0), (0.5 * PX, 0.2 * PX), 0.0), 1, -1)
    grown = cv2.dilate(touched, np.ones((5, 5), np.uint8)) > 0
    assert not found[~grown].any()
    filled = without_glare(crop, CHEEKS, EYES, PX)
    assert np.array_equal(filled[~found], crop[~found])         # only the reflection's pixels change
    # Filled from around it: on the band's skin, nearer the skin than the reflection was.
    skin = band & (np.abs(face.astype(int) - SKIN).max(axis=2) == 0)
    before = np.abs(crop[skin].astype(float) - SKIN).mean()
    after = np.abs(filled[skin].astype(float) - SKIN).mean()
    assert after < 0.5 * before, (before, after)


def test_a_reflection_too_small_to_be_more_than_an_opening_is_left():
    face = _face()
    cx, cy = _at(-0.5, 0.0)
    crop = face.copy()
    r = int(0.45 * GLARE["tall"][0] * PX)                       # a round highlight shorter than "tall"
    cv2.circle(crop, (int(cx), int(cy)), r, (245, 245, 245), -1)
    assert glare_mask(crop, CHEEKS, EYES, PX) is None
