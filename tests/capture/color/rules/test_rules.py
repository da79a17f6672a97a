"""The compiled per-frame kernels against OpenCV and the numpy forms of the same maths."""

import cv2
import numpy as np
import pytest

from facepuppet.capture.color.blobs import close_mask, ellipse_kernel, label8, open_mask
from facepuppet.capture.color.eye_anchors import eye_centres
from facepuppet.capture.color.profile import GENERIC_MOUTH_REACH
from facepuppet.capture.color.rules import BLOB_PARAMS, OUTLINE_PARTS, outline_features
from facepuppet.capture.color.rules.kernels import interp, median, quantile, quantile_pair, sort_order
from facepuppet.capture.color.transform import (
    DEFAULT_WEIGHTS,
    GREY_CONTRAST,
    GREY_SPREAD,
    LipHue,
    contrast,
    feature_intensity,
    lip_hue_table,
    transform,
)
from facepuppet.capture.curves import CURVE_NAMES


@pytest.mark.parametrize("size", range(1, 10))
def test_ellipse_kernel_is_opencvs(size):
    assert np.array_equal(ellipse_kernel(size), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size)))


def test_morphology_and_labels_match_opencv():
    rng = np.random.default_rng(3)
    for _ in range(50):
        h, w = rng.integers(2, 40, 2)
        m = (cv2.GaussianBlur(rng.random((h, w)), (0, 0), 1.5) > 0.5).astype(np.uint8)
        for size in (3, 5):
            k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size))
            assert np.array_equal(close_mask(m, size), cv2.morphologyEx(m, cv2.MORPH_CLOSE, k))
            assert np.array_equal(open_mask(m, size), cv2.morphologyEx(m, cv2.MORPH_OPEN, k))
        labels, n = label8(m)
        n_cv, labels_cv = cv2.connectedComponents(m, connectivity=8)
        assert n == n_cv
        # The same partition: each of our labels maps onto exactly one of OpenCV's.
        pairs = {(a, b) for a, b in zip(labels.ravel(), labels_cv.ravel(), strict=True)}
        assert len(pairs) == n
        # Numbered in the raster order of each part's first pixel.
        flat = labels.ravel()
        firsts = [np.flatnonzero(flat == k)[0] for k in range(1, n)]
        assert firsts == sorted(firsts)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_median_and_quantile_by_selection_equal_the_sorted_forms(dtype):
    # quantile_pair: both quantiles of one selection, the same values as two quantile calls on float64 data.
    rng = np.random.default_rng(5)
    for n in [*range(1, 30), 479, 480, 920]:
        for a in (rng.random(n), rng.integers(0, 4, n), rng.integers(0, 256, n)):  # ties and grey levels too
            a = a.astype(dtype)
            d = np.sort(a)
            assert median(a) == 0.5 * (d[(n - 1) // 2] + d[n // 2])
            assert np.isclose(median(a), np.median(a.astype(np.float64)))
            for q in (0.0, 0.5, 0.75, 0.97, 1.0):
                pos = q * (n - 1)
                i = min(int(pos), max(n - 2, 0))
                assert quantile(a, q) == float(d[i]) + (pos - i) * float(d[min(i + 1, n - 1)] - d[i])
                assert np.isclose(quantile(a, q), np.quantile(a.astype(np.float64), q))
            a64 = a.astype(np.float64)
            for lo, hi in ((0.5, 0.97), (0.0, 1.0), (0.3, 0.3), (0.75, 0.76)):
                assert quantile_pair(a, lo, hi) == (quantile(a64, lo), quantile(a64, hi))


def test_interp_and_order_equal_numpys():
    rng = np.random.default_rng(8)
    for n in range(2, 40):
        xp = np.cumsum(rng.uniform(0.1, 2.0, n))
        fp = rng.normal(size=n)
        # Inside, outside, and on the sample points themselves.
        x = np.concatenate([rng.uniform(xp[0] - 3, xp[-1] + 3, 50), xp, [xp[0] - 1, xp[-1] + 1]])
        assert np.array_equal(interp(x, xp, fp), np.interp(x, xp, fp))
        a = rng.integers(0, 5, n).astype(float) + rng.choice([0.0, 0.5], n)      # ties too
        assert np.array_equal(sort_order(a), np.argsort(a, kind="stable"))


def test_outline_parts_not_read_keep_the_layout():
    """Each part moves only its own curves; the parts not asked for keep the layout's."""
    C, raw, value, layout, offset, boxes, params, unit, reach = _scene_inputs()
    every = outline_features(C, raw=raw, value=value, layout=layout, mouth_offset=offset, boxes=boxes,
                             blob_params=params, unit=unit, mouth_reach=reach)
    for part, curves in (("eyes", _EYE_CURVES), ("brows", _BROW_CURVES), ("mouth", _LIP_CURVES)):
        got = outline_features(C, raw=raw, value=value, layout=layout, mouth_offset=offset, boxes=boxes,
                               blob_params=params, unit=unit, mouth_reach=reach, parts=(part,))
        mine = np.isin(np.arange(len(layout)), curves)
        np.testing.assert_array_equal(got[mine], every[mine])
        np.testing.assert_array_equal(got[~mine], layout[~mine])
        assert not np.array_equal(got[mine], layout[mine]), part               # the scene moves every part
    assert OUTLINE_PARTS == ("eyes", "brows", "mouth")
    with pytest.raises(ValueError, match=r"unknown outline parts \['nose'\]"):
        outline_features(C, raw=raw, value=value, layout=layout, mouth_offset=offset, boxes=boxes,
                         blob_params=params, unit=unit, mouth_reach=reach, parts=("eyes", "nose"))


def test_feature_intensity_is_eq1_then_contrast():
    rng = np.random.default_rng(1)
    crop = cv2.GaussianBlur(rng.integers(0, 256, (40, 50, 3)).astype(np.uint8), (0, 0), 1.0)
    table = lip_hue_table(LipHue())
    skin = np.array([[0, 0, 10, 10], [40, 30, 50, 40]], dtype=np.int64)
    feats = np.array([[10, 10, 30, 20]], dtype=np.int64)
    raw, C, value, _ = feature_intensity(crop, DEFAULT_WEIGHTS.astype(float), table, 0.12, skin, feats)
    ref = transform(crop, DEFAULT_WEIGHTS, table, 0.12)
    assert np.allclose(raw, ref, atol=1e-5)
    assert np.array_equal(value, crop.max(axis=2))
    low = np.median(np.concatenate([ref[0:10, 0:10].ravel(), ref[30:40, 40:50].ravel()]))
    feat = ref[10:20, 10:30].max()
    assert np.allclose(C, contrast(ref, low + 0.15 * (feat - low), low + 0.75 * (feat - low)), atol=1e-4)


def test_the_eyes_contrast_rises_on_a_crop_without_colour():
    """A grey crop (R = G = B): C is as on any crop, and the eye search's C takes GREY_CONTRAST's fractions of
    the way from the skin level to the feature level; a crop whose max - min of R, G, B is 5 everywhere (between
    GREY_SPREAD's ends), fractions interpolated between the two; a crop in colour, or one transformed without
    ``grey_contrast`` (a candidate of the search for the face), gives C itself."""
    rng = np.random.default_rng(2)
    grey = cv2.GaussianBlur(rng.integers(0, 250, (40, 50)).astype(np.uint8), (0, 0), 1.0)
    crop = np.repeat(grey[..., None], 3, axis=2)
    table = lip_hue_table(LipHue())
    skin = np.array([[0, 0, 10, 10], [40, 30, 50, 40]], dtype=np.int64)
    feats = np.array([[10, 10, 30, 20]], dtype=np.int64)

    def expected(raw, share):
        low = np.median(np.concatenate([raw[0:10, 0:10].ravel(), raw[30:40, 40:50].ravel()]))
        feat = raw[10:20, 10:30].max()
        lo = 0.15 + share * (GREY_CONTRAST[0] - 0.15)
        hi = 0.75 + share * (GREY_CONTRAST[1] - 0.75)
        return contrast(raw, low + lo * (feat - low), low + hi * (feat - low))

    w = DEFAULT_WEIGHTS.astype(float)
    raw, C, _, eyes = feature_intensity(crop, w, table, 0.12, skin, feats, grey_contrast=True)
    assert np.allclose(C, expected(raw, 0.0), atol=1e-4)
    assert np.allclose(eyes, expected(raw, 1.0), atol=1e-4)
    assert eyes.sum() < C.sum()
    tinted = crop.copy()
    tinted[..., 0] += 5                                       # max - min = 5: share (8 - 5) / (8 - 3)
    share = (GREY_SPREAD[1] - 5.0) / (GREY_SPREAD[1] - GREY_SPREAD[0])
    raw, C, _, eyes = feature_intensity(tinted, w, table, 0.12, skin, feats, grey_contrast=True)
    assert np.allclose(C, expected(raw, 0.0), atol=1e-4)
    assert np.allclose(eyes, expected(raw, share), atol=1e-4)
    _, C2, _, eyes2 = feature_intensity(crop, w, table, 0.12, skin, feats)
    assert np.array_equal(eyes2, C2)
    warm = np.clip(crop * np.array([1.0, 0.7, 0.55]), 0, 255).astype(np.uint8)     # R - B 0.45 of R
    _, C3, _, eyes3 = feature_intensity(warm, w, table, 0.12, skin, feats, grey_contrast=True)
    assert np.array_equal(eyes3, C3)


def test_contrast_is_not_scaled_to_a_lone_speck():
    """Eq. 1 with w = (1, 0, 0, 0) reads I = (V - G) / V: skin (200, 150, 120) at 0.25, a faint feature
    (100, 60, 50) at 0.40 over a 6 x 6 patch, and one pure red speck at 1.0. Scaled to the speck, C would
    leave the feature at about 0.02; the feature level is capped at twice the brightest 3 x 3 mean's height
    above the skin (0.25 + 2 * 0.15 = 0.55), where C keeps the feature visible."""
    crop = np.zeros((20, 30, 3), np.uint8)
    crop[:] = (200, 150, 120)
    crop[7:13, 8:14] = (100, 60, 50)
    crop[3, 25] = (255, 0, 0)
    table = lip_hue_table(LipHue())
    skin = np.array([[0, 14, 30, 20]], dtype=np.int64)
    feats = np.array([[0, 0, 30, 14]], dtype=np.int64)
    raw, C, _, _ = feature_intensity(crop, np.array([1.0, 0.0, 0.0, 0.0]), table, 0.12, skin, feats)
    np.testing.assert_allclose([raw[0, 0], raw[10, 10], raw[3, 25]], [0.25, 0.4, 1.0], atol=1e-6)
    low, feat = 0.25, 0.55
    t = (0.4 - (low + 0.15 * (feat - low))) / (0.6 * (feat - low))
    np.testing.assert_allclose(C[10, 10], t * t * (3 - 2 * t), atol=1e-5)
    assert C[10, 10] > 0.5 and C[0, 0] == 0.0 and C[3, 25] == 1.0


def test_eye_centres_find_two_bright_spots():
    C = np.zeros((60, 100), np.float32)
    cv2.circle(C, (30, 25), 4, 1.0, -1)
    cv2.circle(C, (71, 27), 4, 1.0, -1)
    ok, eyes = eye_centres(C, np.array([[27.0, 22.0], [74.0, 30.0]]), 12, 8)
    assert ok
    assert np.allclose(eyes, [[30, 25], [71, 27]], atol=0.2)
    ok, _ = eye_centres(np.zeros_like(C), np.array([[27.0, 22.0], [74.0, 30.0]]), 12, 8)
    assert not ok


def test_ycrcb_and_skin_fraction_match_opencv_and_the_skin_model():
    from facepuppet.capture.color.face import SkinModel, skin_probability
    from facepuppet.capture.color.transform import skin_fraction, ycrcb_u8

    rng = np.random.default_rng(4)
    rgb = rng.integers(0, 256, (5000, 3)).astype(np.uint8)
    ref = cv2.cvtColor(rgb[None], cv2.COLOR_RGB2YCrCb)[0]
    assert np.array_equal(np.array([ycrcb_u8(int(r), int(g), int(b)) for r, g, b in rgb]), ref)
    crop = rng.integers(60, 230, (50, 60, 3)).astype(np.uint8)
    boxes = np.array([[0, 0, 20, 20], [30, 10, 50, 30]], dtype=np.int64)
    model = SkinModel()
    mask = skin_probability(np.concatenate([crop[0:20, 0:20], crop[10:30, 30:50]], axis=1), model)
    assert skin_fraction(crop, boxes, model.table()) == pytest.approx((mask > 0).mean())


def test_snake_fields_are_opencvs_blur_and_central_differences():
    from facepuppet.capture.color.snakes import snake_fields

    img = np.random.default_rng(5).random((37, 52)).astype(np.float32)
    for blur in (0, 3, 5):
        b = cv2.GaussianBlur(img, (blur, blur), 0) if blur > 1 else img
        ix = cv2.Sobel(b, cv2.CV_32F, 1, 0, ksize=1, scale=0.5)
        iy = cv2.Sobel(b, cv2.CV_32F, 0, 1, ksize=1, scale=0.5)
        mag = ix * ix + iy * iy
        ref = np.dstack([b, ix, iy, cv2.Sobel(mag, cv2.CV_32F, 1, 0, ksize=1, scale=0.5),
                         cv2.Sobel(mag, cv2.CV_32F, 0, 1, ksize=1, scale=0.5)])
        assert np.allclose(snake_fields(img, blur), ref, atol=1e-6)


def test_move_boxes_rounds_shifts_scales_the_mouth_and_clips_to_the_crop():
    from facepuppet.capture.color.rules import move_boxes

    boxes = np.array([[10, 10, 20, 20], [0, 0, 5, 5], [90, 40, 100, 50]], dtype=np.int64)
    moved = np.array([True, False, True])
    out = move_boxes(boxes, moved, 2, np.array([2.4, -1.6]), np.array([0.3, 0.2]), 1.0, np.zeros(2), 96, 48)
    assert out.tolist() == [[12, 8, 22, 18], [0, 0, 5, 5], [93, 39, 96, 48]]
    # The mouth box scaled 1.5 about the eyes' midpoint (50, 10), then moved: only the mouth's size changes.
    boxes[2] = (40, 20, 60, 30)
    out = move_boxes(boxes, moved, 2, np.array([2.4, -1.6]), np.array([0.3, 0.2]), 1.5, np.array([50.0, 10.0]), 96, 48)
    assert out.tolist() == [[12, 8, 22, 18], [0, 0, 5, 5], [38, 24, 68, 39]]


def test_two_point_similarity_is_the_least_squares_one():
    from facepuppet.capture.color.face import similarity_from_points, similarity_of_pairs

    src = np.array([[10.0, 20.0], [40.0, 24.0]])
    dst = np.array([[13.0, 18.0], [44.0, 29.0]])
    assert np.allclose(similarity_of_pairs(src, dst), similarity_from_points(src, dst))


def _scene():
    """A blank face crop as the generic tracker sees it: layout, rectangles and blob options in crop pixels."""
    from facepuppet.capture.color.tracker import ColorTracker

    t = ColorTracker()
    w, h = t.crop_size
    return t.layout_in_crop, t.feature_boxes, BLOB_PARAMS, (h, w), t.config.measure.px


_EYE_CURVES = [CURVE_NAMES.index(n) for n in CURVE_NAMES if n.startswith("eye_")]
_BROW_CURVES = [CURVE_NAMES.index(n) for n in CURVE_NAMES if n.startswith("brow_")]
_LIP_CURVES = [CURVE_NAMES.index(n) for n in CURVE_NAMES if n.startswith("lip_")]


def _scene_inputs():
    """:func:`outline_features`' arguments for a drawn face whose features all sit a few pixels off the
    layout: dark eyes and lips in C, brow bands in Eq. 1's intensity and the HSV value."""
    layout, boxes, params, (h, w), px = _scene()
    C = np.zeros((h, w), np.float32)
    raw = np.zeros((h, w), np.float32)
    value = np.full((h, w), 200, np.uint8)
    for curves in (_EYE_CURVES[:2], _EYE_CURVES[2:]):
        pts = layout[curves].reshape(-1, 2)
        (xa, ya), (xb, yb) = pts.min(axis=0), pts.max(axis=0)
        cv2.ellipse(C, (int((xa + xb) / 2), int((ya + yb) / 2) + 3), (int((xb - xa) / 2), int(yb - ya) + 3),
                    0, 0, 360, 1.0, -1)
    for c in _BROW_CURVES:
        xa, xb = int(layout[c, :, 0].min()), int(layout[c, :, 0].max())
        y = int(layout[c, :, 1].mean()) - 4
        cv2.rectangle(raw, (xa, y), (xb, y + 6), 1.0, -1)
        cv2.rectangle(value, (xa, y), (xb, y + 6), 120, -1)
    pts = layout[_LIP_CURVES].reshape(-1, 2)
    (xa, ya), (xb, yb) = pts.min(axis=0), pts.max(axis=0)
    cv2.ellipse(C, (int((xa + xb) / 2), int((ya + yb) / 2) + 3), (int((xb - xa) / 2) + 2, int(yb - ya) + 2),
                0, 0, 360, 1.0, -1)
    return C, raw, value, layout, np.zeros(2), boxes, params, px, 0.12


def test_brow_curve_tilts_with_a_slanted_brow():
    """A brow band drawn slanting down to the outside: the brow curve's ends follow the band's slant (the
    layout's ends are level); a level band leaves the curve level."""
    from facepuppet.capture.color.rules import BOX_NAMES
    from facepuppet.capture.curves import CURVE_NAMES

    layout, boxes, params, (h, w), px = _scene()
    c = CURVE_NAMES.index("brow_left")
    x0, y0, x1, y1 = boxes[BOX_NAMES.index("brow_left")]
    for slope in (0.0, 0.3):
        raw = np.zeros((h, w), np.float32)
        xa, xb = x0 + 3, x1 - 3
        ya = 0.5 * (y0 + y1) - 0.5 * slope * (xb - xa)
        cv2.line(raw, (xa, int(round(ya))), (xb, int(round(ya + slope * (xb - xa)))), 1.0, thickness=5)
        C = np.zeros((h, w), np.float32)
        out = outline_features(C, raw=raw, value=np.zeros((h, w), np.uint8), layout=layout, boxes=boxes,
                               blob_params=params, unit=px, mouth_reach=GENERIC_MOUTH_REACH)
        rise = (out[c, 3, 1] - out[c, 0, 1]) - (layout[c, 3, 1] - layout[c, 0, 1])
        run = out[c, 3, 0] - out[c, 0, 0]
        # The excess over the 0.1 tilt floor is followed (one pixel of rounding in the drawn band).
        assert abs(rise - max(slope - 0.1, 0.0) * run) < 1.5, (slope, rise, run)


def _closed_mouth(top_of, crease_of, bottom_of):
    """The rules run on a closed mouth's blob drawn on the layout: rows ``top_of(layout, px)`` to
    ``bottom_of(layout, px, crease)`` of C lit over the mouth's width, a dark crease at row
    ``crease_of(layout)``. Returns (out, layout, crease, top, bottom)."""
    layout, boxes, params, (h, w), px = _scene()
    uo = CURVE_NAMES.index("lip_upper_outer")
    xl, xr = int(layout[uo, 0, 0]), int(layout[uo, 3, 0])
    crease = crease_of(layout)
    top, bottom = top_of(layout, px, crease), bottom_of(layout, px, crease)
    C = np.zeros((h, w), np.float32)
    cv2.rectangle(C, (xl, top), (xr, bottom), 1.0, -1)
    value = np.full((h, w), 200, np.uint8)
    value[crease, xl:xr] = 60                                          # the crease between the lips
    out = outline_features(C, raw=np.zeros((h, w), np.float32), value=value, layout=layout, boxes=boxes,
                           blob_params=params, unit=px, mouth_reach=GENERIC_MOUTH_REACH)
    return out, layout, crease, top, bottom


def test_lower_outer_lip_keeps_the_layouts_thickness():
    """A mouth blob whose lower lip is pale (the blob ends 2 px below the crease): the lower outer lip stays
    the layout's lip thickness below the lower inner one instead of on the blob's bottom."""
    uo, lo, li = (CURVE_NAMES.index(n) for n in ("lip_upper_outer", "lip_lower_outer", "lip_lower_inner"))
    out, layout, crease, _, bottom = _closed_mouth(lambda lay, px, c: int(lay[uo, 1, 1]) + 4,
                                                   lambda lay: int(lay[li, 1, 1]) + 2,
                                                   lambda lay, px, c: c + 2)
    for j in (1, 2):
        assert out[lo, j, 1] - out[li, j, 1] >= layout[lo, j, 1] - layout[li, j, 1] - 1e-9
    assert out[lo, 1, 1] > bottom + 4                                  # not on the blob's bottom


def test_upper_outer_lip_keeps_the_layouts_thickness():
    """A mouth blob whose upper lip is pale at the top (the blob starts 3 px above the crease): the upper outer
    lip stays at least the layout's lip thickness above the upper inner one instead of on the blob's top."""
    uo, ui, lo = (CURVE_NAMES.index(n) for n in ("lip_upper_outer", "lip_upper_inner", "lip_lower_outer"))
    out, layout, crease, top, _ = _closed_mouth(lambda lay, px, c: c - 3,
                                                lambda lay: int(round(_mid(lay[ui])[1])),
                                                lambda lay, px, c: int(round(_mid(lay[lo])[1])))
    for j in (1, 2):
        assert out[ui, j, 1] - out[uo, j, 1] >= layout[ui, j, 1] - layout[uo, j, 1] - 1e-9
    assert _mid(out[uo])[1] < top                                      # above the blob's top


def test_closed_columns_is_opencvs_vertical_closing_and_median_level_numpys():
    from facepuppet.capture.color.rules.brows import closed_columns, median_level

    rng = np.random.default_rng(6)
    for _ in range(100):
        h, w = rng.integers(3, 30, 2)
        value = rng.integers(0, 256, (h, w)).astype(np.uint8)
        ref = cv2.morphologyEx(value, cv2.MORPH_CLOSE, np.ones((3, 1), np.uint8))
        x0, y0 = rng.integers(0, w), rng.integers(0, h)
        x1, y1 = rng.integers(x0 + 1, w + 1), rng.integers(y0 + 1, h + 1)
        assert np.array_equal(closed_columns(value, x0, x1, y0, y1), ref[y0:y1, x0:x1])
        block = rng.integers(0, 256, rng.integers(1, 9, 2)).astype(float)
        assert median_level(block) == np.median(block)


def _brow_behind_glasses(px, brow_top, ends):
    """Eq. 1's intensity and the HSV value of a crop with a faint brow band (its top row per column
    ``brow_top``, 0.12 face units thick, columns ``ends``, 15 % darker than the forehead) and a glasses' rim
    one pixel thick 9 pixels below the band's top, dark in the value and bright in Eq. 1's intensity (the
    brow is not: a blond brow on pale skin)."""
    h, w = int(2.8 * px), int(2.6 * px)
    value = np.full((h, w), 220, np.uint8)
    raw = np.zeros((h, w), np.float32)
    thick = int(round(0.12 * px))
    for x in range(w):
        top = brow_top[x]
        if ends[0] <= x < ends[1]:
            value[top:top + thick, x] = 187
        value[top + 9, x] = 60
        raw[top + 8:top + 10, x] = 1.0
    return raw, value


def test_brow_curve_on_a_faint_brow_above_a_glasses_rim_and_out_to_its_ends():
    """A faint brow band with a glasses' rim below it that holds the blob: the brow curve goes onto the band's
    upper edge (``BROW_DEPTH`` below it), not onto the rim; a band wider than the layout's brow (a turned head's
    near side) stretches the curve's ends out to the band's; a band no wider leaves the layout's ends."""
    from facepuppet.capture.color.rules.brows import BROW_DEPTH
    from facepuppet.capture.curves import CURVE_NAMES, bezier_points

    layout, boxes, params, (h, w), px = _scene()
    c = CURVE_NAMES.index("brow_left")
    lo, hi = layout[c, 0, 0], layout[c, 3, 0]
    # The band follows the layout's brow 3 pixels higher (level beyond its ends).
    pts = bezier_points(layout[c], 64)
    brow_top = np.round(np.interp(np.arange(w) + 0.5, pts[:, 0], pts[:, 1])).astype(int) - 3
    for extra in (0, 8):
        ends = (int(round(lo)) - extra, int(round(hi)) + extra)
        raw, value = _brow_behind_glasses(px, brow_top, ends)
        C = np.zeros((h, w), np.float32)
        out = outline_features(C, raw=raw, value=value, layout=layout, boxes=boxes, blob_params=params, unit=px,
                               mouth_reach=GENERIC_MOUTH_REACH)
        # Without the brow band the rim holds the curve (the blob's top): the case the edge search mends.
        plain = outline_features(C, raw=raw, value=np.full((h, w), 220, np.uint8), layout=layout, boxes=boxes,
                                 blob_params=params, unit=px, mouth_reach=GENERIC_MOUTH_REACH)
        for curve, depth in ((plain, 8.0), (out, BROW_DEPTH * px)):
            p = bezier_points(curve[c], 32)
            off = p[:, 1] - brow_top[np.clip(p[:, 0].astype(int), 0, w - 1)]
            assert abs(np.median(off) - depth) < 1.0, (extra, np.median(off), depth)
        assert out[c, 0, 0] == pytest.approx(ends[0], abs=2.0), (extra, out[c, 0, 0], ends)
        assert out[c, 3, 0] == pytest.approx(ends[1], abs=2.0), (extra, out[c, 3, 0], ends)


def _mid(curve):
    """(x, y) of a curve's middle, B(1/2)."""
    from facepuppet.capture.curves import bezier_points

    return bezier_points(curve, 3)[1]


def _open_mouth_scene(glossy: bool):
    """C and V of a wide-open mouth drawn on the layout: a dark opening (high in C, V 30) 0.3 face units tall
    from the layout's crease down; pale lips (low in C) unless ``glossy``, where both lips are bands high in C
    and the lower one is cut by a 3-pixel highlight (low in C) a pixel below the opening."""
    from facepuppet.capture.curves import CURVE_NAMES

    layout, boxes, params, (h, w), px = _scene()
    uo, lo, ui = (CURVE_NAMES.index(n) for n in ("lip_upper_outer", "lip_lower_outer", "lip_upper_inner"))
    xl, xr = int(layout[uo, 0, 0]) + 3, int(layout[uo, 3, 0]) - 3
    top = int(round(_mid(layout[ui])[1]))
    bottom = top + int(round(0.3 * px))
    C = np.zeros((h, w), np.float32)
    value = np.full((h, w), 200, np.uint8)
    thick_u = _mid(layout[ui])[1] - _mid(layout[uo])[1]
    lower = int(round(0.16 * px))
    if glossy:
        C[int(top - thick_u):top, xl:xr] = 1.0                       # upper lip
        C[bottom:bottom + lower, xl:xr] = 1.0                         # lower lip ...
        C[bottom + 1:bottom + 4, xl + 4:xr - 4] = 0.0                 # ... and its highlight
    C[top:bottom, xl:xr] = 1.0
    value[top:bottom, xl:xr] = 30
    out = outline_features(C, raw=np.zeros((h, w), np.float32), value=value, layout=layout, boxes=boxes,
                           blob_params=params, unit=px, mouth_reach=GENERIC_MOUTH_REACH)
    return out, layout, top, bottom, lower, px


def test_open_mouth_with_pale_lips_keeps_the_lips_outside_the_opening():
    """Only the dark opening is high in C (pale lips): the inner lips trace the opening's top and bottom, and
    the outer lips lie the lips' thickness (the layout's at least) beyond them, not on it."""
    from facepuppet.capture.curves import CURVE_NAMES

    out, layout, top, bottom, _, px = _open_mouth_scene(glossy=False)
    uo, lo, ui, li = (CURVE_NAMES.index(n) for n in ("lip_upper_outer", "lip_lower_outer", "lip_upper_inner",
                                                     "lip_lower_inner"))
    assert abs(_mid(out[ui])[1] - top) < 2.0 and abs(_mid(out[li])[1] - bottom) < 2.0
    thick_u = _mid(layout[ui])[1] - _mid(layout[uo])[1]
    thick_l = _mid(layout[lo])[1] - _mid(layout[li])[1]
    assert _mid(out[ui])[1] - _mid(out[uo])[1] >= thick_u - 1e-6
    assert _mid(out[lo])[1] - _mid(out[li])[1] >= thick_l - 1e-6


def test_glossy_lower_lip_is_not_cut_off_the_mouth():
    """The lower lip's highlight (low in C) cuts it off the blob: the lower outer lip steps over the gap to the
    lip's lower edge instead of stopping at the opening."""
    from facepuppet.capture.curves import CURVE_NAMES

    out, layout, top, bottom, lower, px = _open_mouth_scene(glossy=True)
    lo, li = CURVE_NAMES.index("lip_lower_outer"), CURVE_NAMES.index("lip_lower_inner")
    assert abs(_mid(out[li])[1] - bottom) < 2.0
    assert abs(_mid(out[lo])[1] - (bottom + lower)) < 2.0, (_mid(out[lo])[1], bottom, lower)


def _teeth_scene(split: int, teeth_v: float, teeth_s: float):
    """A smile drawn on the layout, teeth showing below a pale upper lip: skin of HSV value 190 and saturation
    0.35; the upper lip skin-coloured (nothing in C); a band of teeth 0.2 face units tall from the layout's
    upper inner lip down, of value ``teeth_v`` and saturation ``teeth_s`` times the skin's, cut across its middle
    by a line ``split`` pixels tall (the skin's saturation, value 120: neither teeth nor dark); below it the
    lower lip, the only part high in C. Returns the curves and the teeth's top and bottom rows."""
    layout, boxes, params, (h, w), px = _scene()
    uo, ui = CURVE_NAMES.index("lip_upper_outer"), CURVE_NAMES.index("lip_upper_inner")
    xl, xr = int(layout[uo, 0, 0]) + 3, int(layout[uo, 3, 0]) - 3
    top = int(round(_mid(layout[ui])[1]))
    bottom = top + int(round(0.2 * px))
    hsv = np.empty((h, w, 3), np.uint8)
    hsv[...] = (5, round(0.35 * 255), 190)
    hsv[top:bottom, xl:xr] = (15, round(teeth_s * 0.35 * 255), round(teeth_v * 190))
    mid = (top + bottom) // 2
    hsv[mid - split // 2:mid - split // 2 + split, xl:xr] = (5, round(0.35 * 255), 120)
    lower = int(round(0.16 * px))
    hsv[bottom:bottom + lower, xl:xr] = (175, 150, 150)
    rgb = cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB)
    C = np.zeros((h, w), np.float32)
    C[bottom:bottom + lower, xl:xr] = 1.0
    value = np.ascontiguousarray(cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV)[..., 2])
    out = outline_features(C, raw=np.zeros((h, w), np.float32), value=value, layout=layout, boxes=boxes,
                           blob_params=params, unit=px, mouth_reach=GENERIC_MOUTH_REACH, rgb=rgb)
    return out, top, bottom


@pytest.mark.parametrize("split, teeth_v, teeth_s", [(2, 1.0, 0.3),       # white teeth in two rows
                                                     (0, 0.85, 0.7)])     # one row, in shade and tinted
def test_teeth_below_a_pale_upper_lip_are_the_mouth_opening(split, teeth_v, teeth_s):
    """Only the lower lip is high in C: the teeth above it (unsaturated, brighter than the lips though darker
    than the skin, their rows split by a line) are the opening, so the upper inner lip lies at the teeth's top,
    not on the lower lip, and the upper outer lip above it."""
    out, top, bottom = _teeth_scene(split, teeth_v, teeth_s)
    uo, ui = CURVE_NAMES.index("lip_upper_outer"), CURVE_NAMES.index("lip_upper_inner")
    assert abs(_mid(out[ui])[1] - top) < 2.0, (_mid(out[ui])[1], top, bottom)
    assert _mid(out[uo])[1] < _mid(out[ui])[1] - 1.0


def test_mouth_corners_lie_on_the_line_where_the_lips_meet():
    """A closed mouth whose blob reaches farther below the lips' dark meeting line than above it (a heavy lower
    lip): the corners lie on that line (the darkest row of the blob's end columns), not halfway down the blob."""
    layout, boxes, params, (h, w), px = _scene()
    uo = CURVE_NAMES.index("lip_upper_outer")
    xl, xr = int(layout[uo, 0, 0]) + 1, int(layout[uo, 3, 0]) - 1
    line = int(round(0.5 * (layout[uo, 0, 1] + layout[uo, 3, 1])))
    C = np.zeros((h, w), np.float32)
    C[line - 2:line + 9, xl:xr] = 1.0
    value = np.full((h, w), 200, np.uint8)
    value[line - 2:line + 9, xl:xr] = 120
    value[line, xl:xr] = 60
    out = outline_features(C, raw=np.zeros((h, w), np.float32), value=value, layout=layout, boxes=boxes,
                           blob_params=params, unit=px, mouth_reach=GENERIC_MOUTH_REACH)
    assert out[uo, 0, 1] == pytest.approx(line + 0.5, abs=1.0), (out[uo, 0, 1], line)
    assert out[uo, 3, 1] == pytest.approx(line + 0.5, abs=1.0), (out[uo, 3, 1], line)


def _tongue_scene(band_rgb, grey=False, height=0.5):
    """An open mouth drawn on the layout: skin (RGB 200, 150, 130), a mouth blob (C = 1) from the layout's upper
    outer lip ``height`` face units down; in it a dark band 0.08 face units tall at the top, of ``band_rgb``, and
    below it a lip-coloured tongue (RGB 185, 95, 100) to the blob's bottom. ``grey`` turns the picture grey.
    Returns the curves, the layout, the band's top and bottom rows, the blob's bottom row and px."""
    layout, boxes, params, (h, w), px = _scene()
    uo = CURVE_NAMES.index("lip_upper_outer")
    xl, xr = int(layout[uo, 0, 0]) + 3, int(layout[uo, 3, 0]) - 3
    top = int(round(_mid(layout[uo])[1]))
    band, bottom = top + int(round(0.08 * px)), top + int(round(height * px))
    rgb = np.empty((h, w, 3), np.uint8)
    rgb[...] = (200, 150, 130)
    rgb[top:bottom, xl:xr] = (185, 95, 100)
    rgb[top:band, xl:xr] = band_rgb
    if grey:
        rgb[...] = cv2.cvtColor(cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY), cv2.COLOR_GRAY2RGB)
    C = np.zeros((h, w), np.float32)
    C[top:bottom, xl:xr] = 1.0
    value = np.ascontiguousarray(cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV)[..., 2])
    out = outline_features(C, raw=np.zeros((h, w), np.float32), value=value, layout=layout, boxes=boxes,
                           blob_params=params, unit=px, mouth_reach=GENERIC_MOUTH_REACH, rgb=rgb)
    return out, layout, top, band, bottom, px


@pytest.mark.parametrize("band_rgb, hair", [((70, 20, 25), False),       # the mouth's dark red inside
                                            ((60, 45, 35), True)])       # dark brown hair
def test_dark_band_at_the_mouths_top_is_hair_only_if_not_red(band_rgb, hair):
    """A dark band at the top of the mouth blob over lip-coloured rows: hair over the lips (the lips start under
    it) where it is no redder for its brightness than the skin; the opening (the upper inner lip at its top)
    where it is red, as a mouth's inside is."""
    out, _, top, band, _, _ = _tongue_scene(band_rgb, height=0.3)
    ui = CURVE_NAMES.index("lip_upper_inner")
    if hair:
        assert _mid(out[ui])[1] >= band - 1.0, (_mid(out[ui])[1], top, band)
    else:
        assert abs(_mid(out[ui])[1] - top) < 2.0, (_mid(out[ui])[1], top, band)


@pytest.mark.parametrize("grey", [False, True])
def test_open_mouths_lower_lip_is_no_thicker_than_its_bound(grey):
    """A mouth open wide (the blob twice the layout's height) whose opening is dark only in a band at its top,
    a lip-coloured tongue below: the inner lower lip lies LOWER_THICKNESS of the layout's lower lip above the
    outer one, not on the tongue's top. On grey footage (the tongue and the chin's shade are not told from the
    lips) it stays near the dark band."""
    from facepuppet.capture.color.rules.mouth import LOWER_THICKNESS

    out, layout, top, band, bottom, px = _tongue_scene((70, 20, 25), grey=grey)
    lo, li = CURVE_NAMES.index("lip_lower_outer"), CURVE_NAMES.index("lip_lower_inner")
    thick = LOWER_THICKNESS * (_mid(layout[lo])[1] - _mid(layout[li])[1])
    assert abs(_mid(out[lo])[1] - bottom) < 2.0
    if grey:
        assert _mid(out[li])[1] < band + 0.1 * px < _mid(out[lo])[1] - thick, (_mid(out[li])[1], band, px)
    else:
        assert _mid(out[lo])[1] - _mid(out[li])[1] == pytest.approx(thick, abs=0.5)
        assert _mid(out[li])[1] > band + 0.1 * px


def test_thin_dark_band_under_the_upper_lip_starts_the_opening():
    """An open mouth drawn on the layout: upper lip, a dark band 2 px tall under it (too thin to survive the
    opening's morphology), a lip-coloured tongue, a dark cavity low in the mouth, the lower lip; all one blob in
    C. The upper inner lip lies on the band, not on the cavity's top."""
    layout, boxes, params, (h, w), px = _scene()
    uo = CURVE_NAMES.index("lip_upper_outer")
    ui = CURVE_NAMES.index("lip_upper_inner")
    xl, xr = int(layout[uo, 0, 0]) + 3, int(layout[uo, 3, 0]) - 3
    top = int(round(_mid(layout[uo])[1]))
    band = top + int(round(0.1 * px))
    cavity, lower, bottom = band + int(round(0.2 * px)), band + int(round(0.35 * px)), band + int(round(0.5 * px))
    rgb = np.empty((h, w, 3), np.uint8)
    rgb[...] = (200, 150, 130)
    rgb[top:bottom, xl:xr] = (185, 95, 100)
    rgb[band:band + 2, xl:xr] = (70, 20, 25)
    rgb[cavity:lower, xl:xr] = (50, 15, 20)
    C = np.zeros((h, w), np.float32)
    C[top:bottom, xl:xr] = 1.0
    value = np.ascontiguousarray(cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV)[..., 2])
    out = outline_features(C, raw=np.zeros((h, w), np.float32), value=value, layout=layout, boxes=boxes,
                           blob_params=params, unit=px, mouth_reach=GENERIC_MOUTH_REACH, rgb=rgb)
    assert abs(_mid(out[ui])[1] - band) < 1.5, (_mid(out[ui])[1], band, cavity)


@pytest.mark.parametrize("share", [0.3, 1.0])
def test_lower_lid_off_a_lash_line_alone(share):
    """Each eye's blob drawn from the layout's upper lid down ``share`` of the layout's eye height, 3 px below
    its lower lid when ``share`` is 1: a full eye moves the lower lid onto the blob's bottom; a blob
    under THIN_EYE of the height is the lash line alone, and the lower lid stays the layout's."""
    from facepuppet.capture.color.rules.eyes import THIN_EYE

    layout, boxes, params, (h, w), px = _scene()
    C = np.zeros((h, w), np.float32)
    lows = []
    for up, lo in (("eye_right_upper", "eye_right_lower"), ("eye_left_upper", "eye_left_lower")):
        u, lo_ = CURVE_NAMES.index(up), CURVE_NAMES.index(lo)
        xa, xb = int(layout[u, :, 0].min()) + 2, int(layout[u, :, 0].max()) - 2
        ya, yb = _mid(layout[u])[1], _mid(layout[lo_])[1]
        bottom = int(round(yb + 3)) if share == 1.0 else int(round(ya + share * (yb - ya)))
        C[int(round(ya)):bottom, xa:xb] = 1.0
        lows.append((lo_, bottom))
    out = outline_features(C, raw=np.zeros((h, w), np.float32), value=np.full((h, w), 200, np.uint8), layout=layout,
                           boxes=boxes, blob_params=params, unit=px, mouth_reach=GENERIC_MOUTH_REACH)
    for lo_, bottom in lows:
        if share < THIN_EYE:
            assert _mid(out[lo_])[1] == pytest.approx(_mid(layout[lo_])[1], abs=1e-9)
        else:
            assert abs(_mid(out[lo_])[1] - bottom) < 1.0, (_mid(out[lo_])[1], bottom)
