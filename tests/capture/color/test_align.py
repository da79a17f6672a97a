"""The compiled affine ECC alignment: a known motion recovered, OpenCV's findTransformECC matched step for step
(also where the warp reaches past the input), the failures it reports; Eq. 1's branch-free hue and saturation
against the branching one."""

import cv2
import numpy as np

from facepuppet.capture.color.align import blur3, ecc_affine


def _scene(h=46, w=43, seed=0):
    """A smooth random grey image (h, w) float32 in 0..255."""
    rng = np.random.default_rng(seed)
    big = cv2.GaussianBlur(rng.random((h * 3, w * 3)).astype(np.float32), (0, 0), 2.0)
    big = (big - big.min()) / np.ptp(big) * 255.0
    return np.ascontiguousarray(big[h:2 * h, w:2 * w])


def _moved(img, M):
    """``img`` seen through the affine M (2, 3): out(x) = img(M x), replicated edges."""
    h, w = img.shape
    return cv2.warpAffine(img, M, (w, h), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                          borderMode=cv2.BORDER_REPLICATE)


def test_a_known_motion_is_recovered():
    image = _scene()
    truth = np.array([[1.02, 0.03, 1.2], [-0.02, 0.99, -0.8]])
    # The template is the image seen through the motion (template(x) = image(truth x)): the warp found is it.
    template = _moved(image, truth.astype(np.float32))
    ok, rho, M = ecc_affine(blur3(template), image, np.eye(2, 3), 30, 1e-7)
    assert ok and rho > 0.95                 # the edges, where the motion brings in pixels the image lacks
    assert np.abs(M[:, 2] - truth[:, 2]).max() < 0.15 and np.abs(M[:, :2] - truth[:, :2]).max() < 0.01


def test_it_follows_opencvs_steps():
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 2, 1e-3)
    for seed in range(5):
        image = _scene(seed=seed)
        guess = np.array([[1.0, 0.02, 0.5], [-0.01, 0.98, -0.3]], np.float32)
        template = _moved(image, np.array([[0.99, 0.0, 1.0], [0.01, 1.01, 0.6]], np.float32))
        cc, W = cv2.findTransformECC(template, image, guess.copy(), cv2.MOTION_AFFINE, crit, None, 3)
        ok, rho, M = ecc_affine(blur3(template), image, guess.astype(np.float64), 2, 1e-3)
        assert ok
        assert abs(rho - cc) < 1e-5
        assert np.abs(M - W).max() < 1e-4


def test_it_follows_opencvs_steps_where_the_warp_reaches_past_the_input():
    # Shifts of about 5 pixels: the rows and columns at the edges read the padding (beyond it, clamped into it).
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 2, 1e-3)
    for seed in range(5):
        image = _scene(seed=seed)
        guess = np.array([[1.05, 0.03, 4.5], [-0.02, 0.97, -5.0]], np.float32)
        template = _moved(image, np.array([[1.04, 0.02, 5.0], [-0.01, 0.98, -4.4]], np.float32))
        cc, W = cv2.findTransformECC(template, image, guess.copy(), cv2.MOTION_AFFINE, crit, None, 3)
        ok, rho, M = ecc_affine(blur3(template), image, guess.astype(np.float64), 2, 1e-3)
        assert ok
        assert abs(rho - cc) < 1e-5
        assert np.abs(M - W).max() < 1e-4


def test_the_blur_is_opencvs_3x3_gaussian():
    img = _scene(seed=3)
    assert np.abs(blur3(img) - cv2.GaussianBlur(img, (3, 3), 0)).max() < 1e-4


def test_a_flat_crop_fails():
    flat = np.full((20, 24), 100.0, np.float32)
    ok, _, _ = ecc_affine(blur3(flat), flat, np.eye(2, 3), 2, 1e-3)
    assert not ok
    # A crop warped entirely outside the image: no pixel counts.
    ok, _, _ = ecc_affine(blur3(_scene(20, 24)), _scene(20, 24, seed=1), np.array([[1.0, 0, 500], [0, 1, 0]]), 2, 1e-3)
    assert not ok


