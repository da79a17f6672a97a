"""The eye search's place along the eye: the midpoint of the eye's opening, whatever the makeup and gaze."""

import cv2
import numpy as np

from facepuppet.capture.color.eye_anchors import (
    OPENING,
    OPENING_TABLE,
    dark_centres,
    darkness,
    eye_centres,
    eye_opening_centres,
)

SKIN = (205, 150, 120)
CHEEKS = np.array([[10, 70, 30, 85], [90, 70, 110, 85]], dtype=np.int64)
UNIT = 48.0
WINDOW = (14, 7)


def _face(eyes, *, iris_dx=0.0, wing=0, pale=None, closed=False, rng=None, open_half=4.0):
    """A crop (100, 120, 3) of flat skin with two eyes (centre x, y, half width) and the matching contrast C:
    each eye an almond opening (white) between a dark lash line above and a fainter lower lid, a dark iris
    ``iris_dx`` pixels off the centre, an eyeliner ``wing`` pixels long beyond the outer corner, and, for the
    eye ``pale``, a pale grey patch beyond its outer corner; the opening ``2 open_half`` pixels tall in its
    middle. Closed eyes show only the lash line."""
    crop = np.empty((100, 120, 3), np.float32)
    crop[:] = SKIN
    C = np.zeros((100, 120), np.float32)
    for k, (cx, cy, hw) in enumerate(eyes):
        out = -1 if k == 0 else 1                              # the right eye is on the image's left
        xs = np.arange(int(cx - hw), int(cx + hw) + 1)
        half_h = open_half * np.sqrt(np.clip(1 - ((xs - cx) / hw) ** 2, 0, 1))
        for x, hh in zip(xs, half_h, strict=True):
            top, bottom = int(round(cy - hh)), int(round(cy + hh))
            if not closed and bottom > top:
                crop[top:bottom + 1, x] = (232, 230, 228)
            crop[top - 1, x] = (40, 35, 35)                   # lash line
            C[top - 1, x] = 1.0
            if not closed:
                C[bottom + 1, x] = 0.6                         # lower lid
        if not closed:
            cv2.circle(crop, (int(round(cx + iris_dx)), int(round(cy))), 3, (70, 60, 55), -1)
            cv2.circle(C, (int(round(cx + iris_dx)), int(round(cy))), 3, 0.8, -1)
        if wing:
            x0 = int(round(cx + out * hw))
            for j in range(wing):
                x, y = x0 + out * j, int(round(cy - 4 - 0.4 * j))
                crop[y - 1:y + 1, x] = (30, 25, 25)
                C[y - 1:y + 1, x] = 1.0
        if pale == k:
            x0 = int(round(cx + out * (hw + 1)))
            xa, xb = sorted((x0, x0 + out * 8))
            crop[int(cy) - 2:int(cy) + 3, xa:xb] = (225, 222, 220)
    if rng is not None:
        crop += rng.normal(0, 2.0, crop.shape)
    return np.clip(crop + 0.5, 0, 255).astype(np.uint8), C


EYES = ((36.0, 40.0, 12.0), (84.0, 40.0, 12.0))
ANCHORS = np.array([[37.0, 38.0], [83.0, 38.0]])


def _search(crop, C, anchors=ANCHORS):
    return eye_opening_centres(C, crop, CHEEKS, anchors, *WINDOW, UNIT, OPENING_TABLE, True)


def _dark_mean_shift(crop, anchors=ANCHORS):
    """The mean shift of the darkness under the cheeks' median luma (the search's height and fallback place)."""
    luma = crop.astype(float) @ [0.299, 0.587, 0.114]
    skin = np.median(np.concatenate([luma[y0:y1, x0:x1].ravel() for x0, y0, x1, y1 in CHEEKS]))
    D = darkness(crop, skin, OPENING["dark_low"][0], OPENING["dark_high"][0])
    return dark_centres(D, anchors, *WINDOW, int(round(OPENING["dark_above"][0] * UNIT)))


def test_centre_is_the_midpoint_of_the_opening_not_of_the_makeup_or_the_iris(rng):
    for iris_dx, wing in ((4.0, 0), (0.0, 8)):
        crop, C = _face(EYES, iris_dx=iris_dx, wing=wing, rng=rng)
        ok, found = _search(crop, C)
        assert ok
        np.testing.assert_allclose(found[:, 0], [36.0, 84.0], atol=0.6)
        # The height found is the darkness mean shift's ...
        ok, mean_shift = _dark_mean_shift(crop)
        np.testing.assert_allclose(found[:, 1], mean_shift[:, 1], atol=1e-9)
    # ... whose place along the eye, as the contrast's, the wings pull outward.
    crop, C = _face(EYES, wing=8, rng=rng)
    ok, mean_shift = eye_centres(C, ANCHORS, *WINDOW)
    assert ok and mean_shift[0, 0] < 35.0 and mean_shift[1, 0] > 85.0
    ok, mean_shift = _dark_mean_shift(crop)
    assert ok and mean_shift[0, 0] < 35.0 and mean_shift[1, 0] > 85.0
    np.testing.assert_allclose(_search(crop, C)[1][:, 0], [36.0, 84.0], atol=0.6)


def test_gaze_does_not_move_the_centre(rng):
    centres = [_search(*_face(EYES, iris_dx=dx, rng=rng))[1][:, 0] for dx in (-5.0, 0.0, 5.0)]
    np.testing.assert_allclose(centres, [[36.0, 84.0]] * 3, atol=0.6)


def test_found_from_an_expected_place_a_few_pixels_off(rng):
    crop, C = _face(EYES, wing=6, rng=rng)
    for dx in (-5.0, 5.0):
        ok, found = _search(crop, C, ANCHORS + [dx, 0.0])
        assert ok
        np.testing.assert_allclose(found[:, 0], [36.0, 84.0], atol=0.8)


def test_an_opening_wider_than_the_other_is_cut_at_its_outer_end(rng):
    crop, C = _face(EYES, pale=1, rng=rng)
    ok, found = _search(crop, C)
    assert ok
    # The pale patch widens the left eye's opening by 8 px; cut to 1.15 times the right eye's width, the centre
    # moves out by at most 0.075 of the width (24 px): under 2 px instead of 4.
    assert abs(found[0, 0] - 36.0) < 0.6
    assert 84.0 <= found[1, 0] < 84.0 + 0.5 * 0.15 * 24 + 0.6
    crop, C = _face(EYES, rng=rng)
    assert abs(_search(crop, C)[1][1, 0] - 84.0) < 0.6


def test_closed_eyes_keep_the_mean_shift(rng):
    crop, C = _face(EYES, closed=True, rng=rng)
    ok, found = _search(crop, C)
    ok2, mean_shift = _dark_mean_shift(crop)
    assert ok and ok2
    np.testing.assert_allclose(found, mean_shift, atol=1e-9)
    # No feature intensity at all: not found, as the mean shift.
    assert not _search(crop, np.zeros_like(C))[0]


def _wall(crop, x0, x1, rng):
    """``crop`` with a light grey wall (colourless and light, as an eye's white) filling columns x0:x1 from top
    to bottom."""
    out = crop.copy()
    out[:, x0:x1] = np.clip(rng.normal((196, 196, 200), 2.0, out[:, x0:x1].shape) + 0.5, 0, 255).astype(np.uint8)
    return out


def test_the_wall_beside_a_turned_heads_far_eye_is_not_its_opening(rng):
    # A head turned to its left: the far (left) eye a little narrower and 4 px from the face's edge, beyond which
    # the wall fills the crop. Its columns run on under the eye window; under an eye's white lies the cheek.
    eyes = ((38.0, 40.0, 12.0), (82.0, 40.0, 10.5))
    crop, C = _face(eyes, rng=rng)
    anchors = np.array([[38.0, 38.0], [86.0, 38.0]])          # the layout's far eye: a little outward of it
    for image in (crop, _wall(crop, 97, 120, rng)):
        ok, found = _search(image, C, anchors)
        assert ok
        np.testing.assert_allclose(found[:, 0], [38.0, 82.0], atol=0.8)
    # Mirrored: the head turned to its right, the far eye the right one (the image's left).
    crop, C = _face(((38.0, 40.0, 10.5), (82.0, 40.0, 12.0)), rng=rng)
    anchors = np.array([[34.0, 38.0], [82.0, 38.0]])
    ok, found = _search(_wall(crop, 0, 24, rng), C, anchors)
    assert ok
    np.testing.assert_allclose(found[:, 0], [38.0, 82.0], atol=0.8)


def test_a_pale_patch_under_the_inner_corner_keeps_the_eyes_columns(rng):
    # A lit nose bridge or cheek under the eye's inner corner, as pale as the wall and running as far down: the
    # background never lies inward of an eye, so the white above it still counts.
    crop, C = _face(EYES, rng=rng)
    lit = crop.copy()
    for x0, x1 in ((42, 50), (70, 78)):                      # under each eye's inner end
        lit[43:80, x0:x1] = np.clip(rng.normal((222, 220, 218), 2.0, (37, x1 - x0, 3)) + 0.5, 0, 255)
    ok, found = _search(crop, C)
    ok_lit, found_lit = _search(lit, C)
    assert ok and ok_lit
    # Its top rows lie in the eye window and count as opening (as a pale lower lid would): the place may move a
    # little inward, never outward (with those columns left out it moves ~3 px outward).
    moved = (found_lit[:, 0] - found[:, 0]) * [-1.0, 1.0]         # outward positive
    assert np.all(moved <= 0.3) and np.all(moved >= -1.0), moved


def test_an_eye_opened_wide_is_still_read_by_its_opening(rng):
    # Opened 0.25 face units (12 px) tall, its white runs down a column far less than a wall's: the opening's
    # extent, not the mean shift drawn to the iris looking aside, places it.
    crop, C = _face(EYES, open_half=6.0, iris_dx=5.0, rng=rng)
    ok, found = _search(crop, C)
    assert ok
    np.testing.assert_allclose(found[:, 0], [36.0, 84.0], atol=0.6)


def _lit(crop, gains):
    """The crop under a light of the colour ``gains`` (R, G, B)."""
    return np.clip(crop.astype(np.float32) * np.float32(gains) + 0.5, 0, 255).astype(np.uint8)


def test_an_eye_in_a_warm_light_is_placed_by_its_white_not_its_eyeliner(rng):
    # A warm lamp tints the eyes' white with the skin: against the cheeks' chroma it no longer passes for an
    # opening, and an eyeliner's wing draws the mean shift outward. In the colours the crop would have in a white
    # light (each side's cheek brought to an average skin's chromaticity) the white is found again.
    crop, C = _face(EYES, wing=8, rng=rng)
    for gains in ((0.91, 0.665, 0.455), (0.8, 0.6, 0.4)):     # a warm lamp in a dim room
        ok, found = _search(_lit(crop, gains), C)
        assert ok
        np.testing.assert_allclose(found[:, 0], [36.0, 84.0], atol=0.6)
