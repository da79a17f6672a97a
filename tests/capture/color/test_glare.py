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


def _reference_mask(crop, cheeks, eyes, unit):
    """The reflection's mask built from OpenCV's own operations (YCrCb conversion, means, comparison,
    connected components, dilation), as :func:`glare_mask` defines it."""
    h, w = crop.shape[:2]
    (ex0, ey0, ex1, ey1), (fx0, fy0, fx1, fy1) = eyes.tolist()
    x0, y0 = max(min(ex0, fx0), 0), max(min(ey0, fy0), 0)
    x1, y1 = min(max(ex1, fx1), w), min(int(max(ey1, fy1) + GLARE["below"][0] * unit), h)
    n, total = 0, np.zeros(3)
    for cx0, cy0, cx1, cy1 in cheeks.tolist():
        box = crop[cy0:cy1, cx0:cx1]
        total += np.asarray(cv2.mean(cv2.cvtColor(box, cv2.COLOR_RGB2YCrCb))[:3]) * (box.size // 3)
        n += box.size // 3
    ys, cr, cb = (total / n - (0.0, 128.0, 128.0)).tolist()
    s2 = cr * cr + cb * cb
    part = cv2.cvtColor(np.ascontiguousarray(crop[y0:y1, x0:x1]), cv2.COLOR_RGB2YCrCb)
    least = min(GLARE["tall"][0], GLARE["wide"][0]) * unit
    lit = cv2.compare(part[..., 0], (1.0 + GLARE["lift"][0]) * ys, cv2.CMP_GT) > 0
    px = part.astype(np.float32)
    pale = (px[..., 1] - 128.0) * np.float32(cr) + (px[..., 2] - 128.0) * np.float32(cb) < np.float32(
        GLARE["chroma"][0] * s2)
    bright = lit & pale
    if lit.sum() < least or bright.sum() < least:
        return None
    _, labels, stats, _ = cv2.connectedComponentsWithStats(bright[::2, ::2].astype(np.uint8), connectivity=8)
    big = ((stats[:, cv2.CC_STAT_HEIGHT] > 0.5 * GLARE["tall"][0] * unit)
           | (stats[:, cv2.CC_STAT_WIDTH] > 0.5 * GLARE["wide"][0] * unit))
    big[0] = False
    if not big.any():
        return None
    keep = np.repeat(np.repeat(big[labels], 2, axis=0), 2, axis=1)[:y1 - y0, :x1 - x0] & bright
    mask = np.zeros((h, w), np.uint8)
    mask[y0:y1, x0:x1][keep] = 255
    g = max(int(round(GLARE["grow"][0] * unit)), 1)
    return cv2.dilate(mask, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * g + 1, 2 * g + 1)))


def test_the_mask_is_the_one_opencvs_operations_give():
    """On drawn faces with bright patches of random size, place and tint, and with noise, the mask is, pixel
    for pixel, the one built from OpenCV's conversion, means, comparison and connected components."""
    rng = np.random.default_rng(3)
    found = 0
    for _ in range(60):
        crop = _face().astype(int)
        for _ in range(rng.integers(1, 4)):
            x, y = int(rng.integers(10, W - 10)), int(rng.integers(20, H // 2))
            tint = rng.integers(150, 256) + rng.integers(-25, 25, 3)
            crop[y:y + rng.integers(3, 30), x:x + rng.integers(3, 35)] = tint
        crop = np.clip(crop + rng.integers(-30, 30, crop.shape), 0, 255).astype(np.uint8)
        want, got = _reference_mask(crop, CHEEKS, EYES, PX), glare_mask(crop, CHEEKS, EYES, PX)
        assert (want is None) == (got is None)
        if want is not None:
            found += 1
            assert np.array_equal(want, got)
    assert 10 < found < 60                                      # both outcomes were tried


def test_the_filling_is_the_whole_crops_inpainting(monkeypatch):
    """Inpainting around the mask gives the pixels inpainting the whole crop gives, masks at the crop's
    edges and reaches of several sizes included."""
    import facepuppet.capture.color.glare as glare

    rng = np.random.default_rng(4)
    for _ in range(40):
        h, w = int(rng.integers(40, 140)), int(rng.integers(40, 140))
        crop = cv2.GaussianBlur(rng.integers(0, 256, (h, w, 3)).astype(np.uint8), (5, 5), 0)
        mask = np.zeros((h, w), np.uint8)
        for _ in range(rng.integers(1, 4)):
            y, x = int(rng.integers(-5, h)), int(rng.integers(-5, w))
            mask[max(y, 0):y + rng.integers(1, 25), max(x, 0):x + rng.integers(1, 25)] = 255
        unit = float(rng.uniform(10.0, 120.0))
        monkeypatch.setattr(glare, "glare_mask", lambda *a, m=mask: m)
        monkeypatch.setattr(glare, "without_veil", lambda c, u: c)     # random levels: no face's black
        whole = cv2.inpaint(crop, mask, max(GLARE["radius"][0] * unit, 1.0), cv2.INPAINT_TELEA)
        assert np.array_equal(without_glare(crop, CHEEKS, EYES, unit), whole)
