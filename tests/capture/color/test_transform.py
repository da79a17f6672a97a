"""Eq. 1 colour transform and the contrast C on hand-computed pixels (paper §3.1)."""

import numpy as np
import pytest

from facepuppet.capture.color.transform import LipHue, channels, contrast, lip_hue_table, transform

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
