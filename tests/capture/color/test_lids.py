"""The eyelid model (capture.lids): geometry, learning lids from the look of synthetic eyes, applying it."""

import cv2
import numpy as np
import pytest

from facepuppet.capture.color.lids import (
    EYES,
    PATCH_SIZE,
    apply_lid_model,
    eye_geometry,
    eye_patch,
    fit_lid_model,
    lid_offsets,
)
from facepuppet.capture.curves import CURVE_NAMES

SPAN = 24.0
CENTRES = (np.array([40.0, 30.0]), np.array([80.0, 30.0]))


def _curves(up: float, lo: float) -> np.ndarray:
    """Curves (C, 4, 2) in crop pixels: two eyes of SPAN with lid middles ``up``/``lo`` spans off the centre
    line (down positive); the right eye's curves run to the left as in the vocabulary, the left's to the right."""
    c = np.zeros((len(CURVE_NAMES), 4, 2))
    for eye, m in enumerate(CENTRES):
        d = np.array([SPAN / 2, 0.0]) * (1 if eye == 1 else -1)
        for k, o in zip(EYES[eye], (up, lo), strict=True):
            c[k] = [m - d, m - d / 3 + [0, o * SPAN], m + d / 3 + [0, o * SPAN], m + d]
    return c


def _eye_image(up: float, lo: float, rng) -> np.ndarray:
    """Crop (60, 120, 3) uint8: grey skin, and each eye's sclera and iris showing between the lids."""
    img = np.full((60, 120), 170.0, np.float32)
    for m in CENTRES:
        x = np.arange(120)[None, :] - m[0]
        y = np.arange(60)[:, None] - m[1]
        shape = np.clip(1 - (2 * x / SPAN) ** 2, 0, None)            # lids meet at the corners
        inside = (y > up * SPAN * shape / 0.75) & (y < lo * SPAN * shape / 0.75)
        img[inside] = 235.0                                           # sclera
        img[inside & (np.hypot(x, y) < 0.22 * SPAN)] = 60.0           # iris
        lash = np.abs(y - up * SPAN * shape / 0.75) < 1.0
        img[lash & (np.abs(x) < SPAN / 2)] = 40.0
    img = cv2.GaussianBlur(img, (0, 0), 0.8) + rng.normal(0, 4, img.shape)
    return np.repeat(np.clip(img, 0, 255).astype(np.uint8)[..., None], 3, axis=2)


def test_geometry_of_an_eye():
    c = _curves(-0.1, 0.08)
    for eye in (0, 1):
        m, s, n = eye_geometry(c, eye)
        np.testing.assert_allclose(m, CENTRES[eye])
        assert s == pytest.approx(SPAN)
        np.testing.assert_allclose(n, [0.0, 1.0], atol=1e-12)          # down in the image, for both eyes
        np.testing.assert_allclose(lid_offsets(c, eye), [-0.1, 0.08])


def test_learnt_lids_are_read_back_from_unseen_eyes(rng):
    xs, ys = [], []
    for _ in range(150):
        up, lo = -rng.uniform(0.0, 0.2), rng.uniform(0.05, 0.12)
        img = _eye_image(up, lo, rng)
        for eye in (0, 1):
            xs.append(eye_patch(img, CENTRES[eye], SPAN, mirror=eye == 1))
            ys.append((up, lo))
    model = fit_lid_model(np.array(xs), np.array(ys), alpha=1.0)
    errs = []
    for up, lo in ((-0.18, 0.1), (-0.05, 0.07), (-0.01, 0.11)):    # wide open, half shut, shut
        img = _eye_image(up, lo, rng)
        curves = _curves(-0.1, 0.09)                                 # the rules' guess, wrong
        apply_lid_model(curves, img, model)
        for eye in (0, 1):
            errs.append(lid_offsets(curves, eye) - (up, lo))
            np.testing.assert_allclose(curves[EYES[eye][0], [0, 3]], _curves(up, lo)[EYES[eye][0], [0, 3]])
    assert np.abs(errs).max() < 0.025, np.round(errs, 3)


def test_upper_lid_never_below_the_lower():
    model = {"coef": np.zeros((2, 128)), "intercept": np.array([0.2, 0.1])}
    curves = _curves(-0.1, 0.1)
    apply_lid_model(curves, np.full((60, 120, 3), 100, np.uint8), model)
    for eye in (0, 1):
        up, lo = lid_offsets(curves, eye)
        assert lo == pytest.approx(0.1) and up == pytest.approx(0.1 - 0.02)


def test_too_small_an_eye_is_left_alone():
    assert eye_patch(np.zeros((20, 20, 3), np.uint8), np.array([10.0, 10.0]), 4.0, mirror=False) is None
    with pytest.raises(ValueError, match="offsets"):
        fit_lid_model(np.zeros((5, 128)), np.zeros((4, 2)))


def test_patch_is_grey_normalised_and_mirrored(rng):
    img = rng.integers(0, 256, size=(40, 60, 3), dtype=np.uint8)
    c = np.array([30.0, 20.0])
    a = eye_patch(img, c, 40.0, mirror=False).reshape(PATCH_SIZE[::-1])
    b = eye_patch(img, c, 40.0, mirror=True).reshape(PATCH_SIZE[::-1])
    np.testing.assert_allclose(a, b[:, ::-1])
    assert abs(a.mean()) < 1e-9 and 0.9 < a.std() <= 1.0
    grey = np.round(img @ np.array([0.299, 0.587, 0.114])).astype(np.uint8)      # BT.601 luma
    g = eye_patch(np.repeat(grey[..., None], 3, axis=2), c, 40.0, mirror=False).reshape(PATCH_SIZE[::-1])
    np.testing.assert_allclose(a, g, atol=0.1)           # up to rounding of the resampled bytes
