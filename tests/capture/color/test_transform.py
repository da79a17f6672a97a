"""Eq. 1 colour transform and the contrast C on hand-computed pixels (paper §3.1)."""

import cv2
import numba as nb
import numpy as np
import pytest

from facepuppet.capture.color.transform import (
    LipHue,
    channels,
    contrast,
    hsv_hue_saturation,
    lip_hue_table,
    transform,
)

# (R, G, B) -> (M, K, V, hue in degrees, saturated?) computed by hand:
# M = (max - G) / max, K = 1 - max / 255, V = max / 255, hue by the HSV hexcone formula.
PIXELS = [
    ((200, 100, 50), (100 / 200, 1 - 200 / 255, 200 / 255, 20.0, True)),   # hue 60 * (G - B) / (max - min)
    ((180, 60, 80), (120 / 180, 1 - 180 / 255, 180 / 255, 350.0, True)),   # 360 + 60 * (60 - 80) / 120
    ((128, 128, 128), (0.0, 1 - 128 / 255, 128 / 255, 0.0, False)),       # grey: no hue
    ((0, 0, 0), (0.0, 1.0, 0.0, 0.0, False)),                               # black: M taken as 0
]


def _g(hue_deg, saturated):
    lip = LipHue()
    if not saturated:
        return 0.0
    d = (hue_deg - lip.centre + 180.0) % 360.0 - 180.0
    return float(np.exp(-0.5 * (d / lip.width) ** 2))


def _image():
    return np.array([[p for p, _ in PIXELS]], dtype=np.uint8)


def test_channels_match_hand_computed_values():
    got = channels(_image(), lip_hue_table(LipHue()))
    for k, (_, (m, kk, v, hue, sat)) in enumerate(PIXELS):
        np.testing.assert_allclose(got[:, 0, k], [m, kk, v, _g(hue, sat)], atol=2e-3)


def test_lip_hue_is_high_on_lip_red_and_low_on_skin_orange():
    g = channels(_image(), lip_hue_table(LipHue()))[3, 0]
    assert g[1] > 0.95 and g[0] < 0.2


@pytest.mark.parametrize("weights", [(0.9, 0.2, -0.8, 0.5), (1.0, 0.0, -1.0, 0.0), (0.3, 0.7, -0.2, 1.2)])
def test_transform_is_eq1(weights):
    img = _image()
    expected = np.array([
        weights[0] * m + weights[1] * kk + weights[2] * v + weights[3] * _g(hue, sat)
        for _, (m, kk, v, hue, sat) in PIXELS
    ])
    got = transform(img, np.array(weights), lip_hue_table(LipHue()))
    assert got.shape == (1, len(PIXELS)) and got.dtype == np.float32
    np.testing.assert_allclose(got[0], expected, atol=3e-3)


def test_transform_brightens_lips_and_darkens_skin_with_negative_w3():
    skin, lip = (225, 175, 150), (170, 70, 85)
    img = np.array([[skin, lip]], dtype=np.uint8)
    out = transform(img, np.array([0.9, 0.2, -0.8, 0.5]), lip_hue_table(LipHue()))[0]
    assert out[1] > out[0] + 0.3


def test_contrast_maps_skin_to_zero_features_to_one_and_pushes_mid_tones_apart():
    x = np.array([[0.0, 0.2, 0.35, 0.5, 0.65, 0.8, 1.0]], dtype=np.float32)
    y = contrast(x, 0.2, 0.8)
    t = (x - 0.2) / 0.6
    np.testing.assert_allclose(y, np.clip(t, 0, 1) ** 2 * (3 - 2 * np.clip(t, 0, 1)), atol=1e-6)
    assert y[0, 0] == 0.0 and y[0, 1] == 0.0 and y[0, -1] == 1.0 and y[0, -2] == 1.0
    assert y[0, 3] == pytest.approx(0.5)
    assert y[0, 2] < 0.25 and y[0, 4] > 0.75            # amplified away from the middle
    assert np.all(np.diff(y[0]) >= 0)


def test_contrast_in_place():
    x = np.linspace(0, 1, 11, dtype=np.float32)[None]
    out = contrast(x, 0.1, 0.9, out=x)
    assert out is x


def test_greyscale_image_leaves_only_the_value_terms():
    """On a grey image M = 0 and G(H) = 0 (no saturation), so Eq. 1 is w2 K + w3 V = w2 + (w3 - w2) V."""
    v = np.arange(0, 256, 5, dtype=np.uint8)
    grey = np.repeat(np.tile(v, (4, 1))[..., None], 3, axis=2)
    w = np.array([0.9, 0.2, -0.8, 0.5], dtype=np.float32)
    out = transform(grey, w, lip_hue_table(LipHue()))
    np.testing.assert_allclose(out, w[1] + (w[2] - w[1]) * np.tile(v, (4, 1)) / 255.0, atol=1e-5)


def test_generic_weights_go_over_to_the_dark_skins_as_the_skin_darkens():
    """dark_skin_weights: the given weights at and above DARK_SKIN's upper level, DARK_WEIGHTS at and under its
    lower, halfway between them halfway up; feature_intensity with ``dark`` reads the skin's level as the median
    V over the skin rectangles: on bright skin it is the call without ``dark`` to the bit, on dark skin the call
    with DARK_WEIGHTS."""
    from facepuppet.capture.color.transform import (
        DARK_SKIN,
        DARK_WEIGHTS,
        DEFAULT_WEIGHTS,
        dark_skin_weights,
        feature_intensity,
    )

    lo, hi = DARK_SKIN
    np.testing.assert_allclose(dark_skin_weights(DEFAULT_WEIGHTS, DARK_WEIGHTS, hi + 30), DEFAULT_WEIGHTS, atol=1e-7)
    np.testing.assert_allclose(dark_skin_weights(DEFAULT_WEIGHTS, DARK_WEIGHTS, lo - 30), DARK_WEIGHTS, atol=1e-7)
    np.testing.assert_allclose(dark_skin_weights(DEFAULT_WEIGHTS, DARK_WEIGHTS, 0.5 * (lo + hi)),
                               0.5 * (DEFAULT_WEIGHTS + DARK_WEIGHTS), atol=1e-7)
    rng = np.random.default_rng(3)
    table = lip_hue_table(LipHue())
    skin_boxes = np.array([[0, 0, 20, 10], [30, 0, 50, 10]], np.int64)
    feature_boxes = np.array([[0, 20, 50, 30]], np.int64)
    for skin, weights in (((220, 170, 150), DEFAULT_WEIGHTS), ((80, 60, 48), DARK_WEIGHTS)):
        crop = np.clip(np.array(skin) + rng.normal(0, 4, (30, 50, 3)), 0, 255).astype(np.uint8)
        crop[20:, 10:40] = (40, 20, 25)                                          # a dark feature below
        got = feature_intensity(crop, DEFAULT_WEIGHTS.astype(float), table, 0.12, skin_boxes, feature_boxes,
                                dark=DARK_WEIGHTS)
        want = feature_intensity(crop, weights.astype(float), table, 0.12, skin_boxes, feature_boxes)
        for a, b in zip(got, want, strict=True):
            np.testing.assert_array_equal(a, b)


def test_only_the_generic_profile_has_dark_weights(tmp_path):
    """A profile of the generic weights and no network goes over to DARK_WEIGHTS on dark skin, saved and loaded
    again too; a trained one (a network) or one of other weights keeps its own."""
    from dataclasses import replace

    from facepuppet.capture.color.profile import default_profile, load_profile, save_profile
    from facepuppet.capture.color.transform import DARK_WEIGHTS

    generic = default_profile()
    np.testing.assert_array_equal(generic.dark_weights, DARK_WEIGHTS)
    save_profile(tmp_path / "generic.npz", generic)
    np.testing.assert_array_equal(load_profile(tmp_path / "generic.npz").dark_weights, DARK_WEIGHTS)
    assert replace(generic, weights=np.array([0.5, 0.3, -0.9, 0.3])).dark_weights is None
    assert replace(generic, net={"w0": np.zeros((11, 10))}).dark_weights is None


def test_the_value_median_reads_only_the_boxes_parts_inside_the_crop():
    """value_median: the median V of the rectangles' pixels inside the crop (a box partly outside counts its
    inside part; one wholly outside none); with no pixel at all, DARK_SKIN's upper level."""
    from facepuppet.capture.color.transform import DARK_SKIN, value_median

    crop = np.zeros((20, 30, 3), np.uint8)
    crop[:, :10] = (100, 20, 30)            # V 100 on the left third
    crop[:, 10:] = (30, 200, 40)            # V 200 elsewhere
    inside_left = np.array([[-5, -5, 10, 10]], np.int64)             # its inside part: 10 x 10 px of V 100
    assert value_median(crop, inside_left) == 100.0
    both = np.array([[-5, 0, 10, 10], [25, 15, 40, 30], [50, 50, 60, 60]], np.int64)  # 100 px of 100, 25 of 200
    assert value_median(crop, both) == 100.0
    assert value_median(crop, np.array([[25, 15, 40, 30]], np.int64)) == 200.0
    assert value_median(crop, np.array([[50, 50, 60, 60]], np.int64)) == DARK_SKIN[1]


@nb.njit(cache=False)
def _hue_saturation(rgb):
    out = np.empty((len(rgb), 2), np.int64)
    for i in range(len(rgb)):
        out[i, 0], out[i, 1] = hsv_hue_saturation(np.int64(rgb[i, 0]), np.int64(rgb[i, 1]), np.int64(rgb[i, 2]))
    return out


def test_hsv_hue_saturation_is_opencvs():
    # Every colour whose channels are multiples of 3, and the greys and primaries' edges, against cv2.cvtColor.
    levels = np.r_[np.arange(0, 256, 3), 1, 2, 254].astype(np.uint8)
    rgb = np.stack(np.meshgrid(levels, levels, levels, indexing="ij"), -1).reshape(-1, 3)
    ref = cv2.cvtColor(rgb[None], cv2.COLOR_RGB2HSV)[0]
    np.testing.assert_array_equal(_hue_saturation(rgb), ref[:, :2].astype(np.int64))
