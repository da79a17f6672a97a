"""Glasses' rims found and filled in on drawn face crops (known answers: what was drawn where)."""

import cv2
import numpy as np
import pytest

from facepuppet.capture.color.rims import RIM_CHECK_EVERY, RIM_REUSE, RIMS, Rims, rim_mask, without_rims

UNIT = 48.0                         # crop pixels per face unit, the tracker's
SIZE = (125, 134)                   # crop width, height
EYES_Y = 41                         # the eye centres' row
SKIN = (196, 150, 130)
#: The eye rectangles (x0, y0, x1, y1) around the eye centres at x = 38 and 86.
EYE_BOXES = np.array([[24, 33, 52, 50], [72, 33, 100, 50]])


def _face(brow_thickness=6):
    """A crop of skin with two dark eyes (iris ellipses) and two arched brows, and the eye centres' x."""
    img = np.zeros((SIZE[1], SIZE[0], 3), np.float32) + SKIN
    xs = (38, 86)
    for x in xs:
        cv2.ellipse(img, (x, EYES_Y), (11, 5), 0, 0, 360, (235, 235, 235), -1, cv2.LINE_AA)     # the white
        cv2.circle(img, (x, EYES_Y), 5, (60, 40, 30), -1, cv2.LINE_AA)                          # iris
        cv2.ellipse(img, (x, EYES_Y - 16), (14, 4), 0, 200, 340, (90, 60, 45), brow_thickness, cv2.LINE_AA)
    return img, xs


def _glasses(img, xs, thickness=2, outline=True):
    """Dark rims drawn on ``img``: a lens outline around each eye (0.76 x 0.54 face units) and the bridge, or with
    ``outline`` False only the lenses' top bars and the bridge (browline glasses). Returns their mask."""
    mask = np.zeros(img.shape[:2], np.uint8)
    hw, hh = int(0.38 * UNIT), int(0.27 * UNIT)
    for x in xs:
        if outline:
            cv2.rectangle(mask, (x - hw, EYES_Y - hh + 3), (x + hw, EYES_Y + hh + 3), 255, thickness)
        else:
            cv2.line(mask, (x - hw, EYES_Y - hh + 3), (x + hw, EYES_Y - hh + 3), 255, thickness)
    bridge_y = EYES_Y if outline else EYES_Y - hh + 3
    cv2.line(mask, (xs[0] + hw, bridge_y), (xs[1] - hw, bridge_y), 255, thickness)
    img[mask > 0] = 28.0
    return mask


def _u8(img):
    return np.clip(img + 0.5, 0, 255).astype(np.uint8)


@pytest.mark.parametrize("outline", [True, False], ids=["lens outlines", "browline bars"])
def test_rims_are_found_and_filled_with_the_skin_around_them(outline):
    img, xs = _face()
    bare = _u8(img)
    drawn = _glasses(img, xs, outline=outline)
    crop = _u8(img)
    mask, y0 = rim_mask(crop, EYE_BOXES, UNIT)
    assert mask is not None
    found = np.zeros(crop.shape[:2], bool)
    found[y0:y0 + mask.shape[0]] = mask > 0
    rim = drawn > 0
    # Every rim pixel is found (the mask is grown by a pixel for the blurred edge).
    assert found[rim].mean() > 0.99
    # ... and the eyes are not taken: the irises' and whites' middles keep their pixels.
    for x in xs:
        assert not found[EYES_Y - 3:EYES_Y + 4, x - 3:x + 4].any()
    out, worn = without_rims(crop, EYE_BOXES, UNIT)
    assert worn and out is not crop
    # Where the rims were, the crop shows about the face under them (skin, or a brow the bar ran along).
    err = np.abs(out.astype(int) - bare.astype(int)).max(axis=2)
    assert np.median(err[rim]) < 20
    assert np.array_equal(out[~found], crop[~found])
    # The eyes are as they were.
    for x in xs:
        assert np.array_equal(out[EYES_Y - 5:EYES_Y + 6, x - 10:x + 11], crop[EYES_Y - 5:EYES_Y + 6, x - 10:x + 11])


def test_a_face_without_glasses_is_left_as_it_is():
    crop = _u8(_face()[0])
    assert rim_mask(crop, EYE_BOXES, UNIT)[0] is None
    out, worn = without_rims(crop, EYE_BOXES, UNIT)
    assert out is crop and not worn


def test_thin_brows_and_winged_lash_lines_are_no_rims():
    # A thin arched brow wider than a lens (0.9 face units) and a lash line with an eyeliner's wing: thin, dark and
    # long, but flatter than a lens and apart from each other.
    img = np.zeros((SIZE[1], SIZE[0], 3), np.float32) + SKIN
    for x in (38, 86):
        cv2.ellipse(img, (x, EYES_Y - 16), (int(0.45 * UNIT), 6), 0, 190, 350, (70, 50, 40), 2, cv2.LINE_AA)
        cv2.ellipse(img, (x, EYES_Y), (12, 4), 0, 180, 360, (30, 25, 25), 2, cv2.LINE_AA)
        wing = 1 if x > 60 else -1
        cv2.line(img, (x + wing * 12, EYES_Y), (x + wing * 20, EYES_Y - 5), (30, 25, 25), 2, cv2.LINE_AA)
    assert rim_mask(_u8(img), EYE_BOXES, UNIT)[0] is None


def test_the_band_searched_is_around_the_eyes():
    # Rims drawn far below the eyes (where a mouth or a collar would be) are outside the band searched.
    img, xs = _face()
    shifted = np.zeros_like(img) + SKIN
    _glasses(shifted, xs)
    low = int(RIMS["below"][0] * UNIT) + 30
    img[low:] = shifted[:SIZE[1] - low]
    assert rim_mask(_u8(img), EYE_BOXES, UNIT)[0] is None


def test_an_eye_touching_the_lens_is_kept():
    # The upper lash line (a thin dark arc) runs up into the lens's top bar: it joins the rim's line, but lies
    # inside the outline, deeper than a rim's thickness from its outside.
    img, xs = _face()
    drawn = _glasses(img, xs)
    for x in xs:
        cv2.ellipse(img, (x, EYES_Y + 2), (12, 12), 0, 200, 340, (30, 25, 25), 2, cv2.LINE_AA)
    crop = _u8(img)
    lash = (np.abs(crop.astype(int) - _u8(_face()[0]).astype(int)).max(axis=2) > 60) & (drawn == 0)
    mask, y0 = rim_mask(crop, EYE_BOXES, UNIT)
    found = np.zeros(crop.shape[:2], bool)
    found[y0:y0 + mask.shape[0]] = mask > 0
    assert found[drawn > 0].mean() > 0.9
    # Only the lash line's pixels next to the bar (within the ring's reach of the outline's outside, grown by a
    # pixel: about 4 px inside the bar's inner edge here) may be taken.
    deep = lash & (cv2.dilate((drawn > 0).astype(np.uint8), np.ones((11, 11), np.uint8)) == 0)
    assert deep.sum() > 10 and not found[deep].any()


def test_faint_rims_are_left_as_they_are():
    # Light rims (a metal or clear frame, 30 % darker than the skin) barely light Eq. 1's darkness: left alone.
    img, xs = _face()
    drawn = _glasses(img, xs)
    img[drawn > 0] = np.array(SKIN, np.float32) * 0.7
    assert rim_mask(_u8(img), EYE_BOXES, UNIT)[0] is None


def test_a_followed_face_is_looked_at_now_and_then_until_it_shows_rims():
    img, xs = _face()
    bare = _u8(img)
    _glasses(img, xs)
    worn = _u8(img)
    rims = Rims()
    # A face followed without glasses is looked at in its first frame and then every RIM_CHECK_EVERY frames;
    # glasses put on in between are taken out from the next look on, then in every frame.
    assert rims(bare, EYE_BOXES, UNIT, followed=True) is bare
    for _ in range(RIM_CHECK_EVERY - 1):
        assert rims(worn, EYE_BOXES, UNIT, followed=True) is worn
    for _ in range(3 * RIM_REUSE):
        out = rims(worn, EYE_BOXES, UNIT, followed=True)
        assert out is not worn and np.array_equal(out, without_rims(worn, EYE_BOXES, UNIT)[0])
    # A search's candidate is looked at afresh, whatever the followed face showed; a face just found at once.
    rims.restart()
    assert rims(bare, EYE_BOXES, UNIT, followed=False) is bare
    assert not np.array_equal(rims(worn, EYE_BOXES, UNIT, followed=False), worn)
    assert not np.array_equal(rims(worn, EYE_BOXES, UNIT, followed=True), worn)
