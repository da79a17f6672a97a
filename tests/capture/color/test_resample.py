"""The face crop by area (:mod:`facepuppet.capture.color.resample`): known answers of the averaged warp and of the
noise estimate, when each crop is taken, and a large face in a dark, noisy room found and followed."""

import cv2
import numpy as np
import pytest
from composites import followed, performer_clip

from facepuppet.capture.color.resample import (
    AHEAD_MARGIN,
    NOISE_EVERY,
    NOISE_OFF,
    NOISE_ON,
    FaceCrops,
    area_crop,
    block_size,
    noise_ratio,
    read_ahead,
)

SIZE = (125, 134)
CHEEKS = np.array([[10, 70, 50, 110], [75, 70, 115, 110]], dtype=np.int64)


def _matrix(scale, roll, centre=(640.0, 400.0)):
    """A crop matrix (2, 3) of ``scale`` crop pixels per image pixel and ``roll`` radians putting image point
    ``centre`` at the crop's middle."""
    c, s = scale * np.cos(roll), scale * np.sin(roll)
    R = np.array([[c, -s], [s, c]])
    return np.hstack([R, (np.array(SIZE) / 2.0 - R @ centre)[:, None]])


def _plain(rgb, A):
    return cv2.warpAffine(rgb, A, SIZE, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)


@pytest.mark.parametrize("scale, roll", [(0.46, 0.0), (0.3, 0.3), (0.2, -0.2), (0.12, 0.1)])
def test_the_crop_by_area_of_a_linear_ramp_is_the_warp_of_it(scale, roll):
    # The mean of a linear function over a block is its value at the block's centre, and a bilinear warp of it is
    # exact: averaged first or not, the crop samples the same ramp (one level per pixel, unquantised), so a slip
    # of the blocks' centres by a tenth of a pixel would show.
    y, x = np.mgrid[0:1600, 0:1600].astype(np.float32)
    ramp = np.dstack([x, y, x + 0.5 * y])
    A = _matrix(scale, roll, centre=(800.0, 800.0))             # the crop inside the image (no border)
    n = block_size(A)
    assert n == int(1.0 / scale)
    assert np.abs(area_crop(ramp, A, SIZE, n) - _plain(ramp, A)).max() < 0.05


def test_the_crop_by_area_takes_the_noise_down_by_the_block_side():
    rng = np.random.default_rng(0)
    rgb = np.clip(120.0 + rng.normal(0.0, 12.0, (800, 1280, 3)), 0, 255).astype(np.uint8)
    for scale in (0.45, 0.3):
        A = _matrix(scale, 0.1)
        n = block_size(A)
        plain, area = _plain(rgb, A).std(), area_crop(rgb, A, SIZE, n).std()
        # The bilinear warp between samples of independent noise keeps about 2/3 of it; the blocks' means 1/n.
        assert 0.5 * 12.0 < plain < 0.85 * 12.0
        assert area < 1.2 * plain / n


def test_noise_ratio_is_the_noise_over_the_level_and_blind_to_shading():
    rng = np.random.default_rng(1)
    y, x = np.mgrid[0:400, 0:600].astype(np.float64)
    shade = 60.0 + 0.2 * x + 0.1 * y                        # a plane: the level 60-160
    grey = np.dstack([shade] * 3)
    eye = np.eye(2, 3)
    boxes = np.array([[50, 50, 250, 350], [300, 50, 550, 350]], dtype=np.int64)
    level = shade[50:350, 50:550].mean()
    assert noise_ratio(grey.astype(np.uint8), eye, boxes) < 0.01
    for sigma in (3.0, 10.0, 20.0):
        noisy = np.clip(grey + rng.normal(0.0, sigma, (400, 600, 1)), 0, 255).astype(np.uint8)
        assert noise_ratio(noisy, eye, boxes) == pytest.approx(sigma / level, rel=0.15)
    # V is the largest channel: noise in one channel over a flat other two is seen where that channel is highest.
    one = np.dstack([np.clip(150.0 + rng.normal(0.0, 10.0, (400, 600)), 0, 255), np.full((400, 600), 40.0),
                     np.full((400, 600), 40.0)]).astype(np.uint8)
    assert noise_ratio(one, eye, boxes) == pytest.approx(10.0 / 150.0, rel=0.15)
    # Rectangles of a crop at half the image's scale, mapped back (crop to image: x 2): the same image regions.
    double = np.array([[2.0, 0.0, 0.0], [0.0, 2.0, 0.0]])
    assert noise_ratio(noisy, double, boxes // 2) == noise_ratio(noisy, eye, boxes)
    assert noise_ratio(noisy, eye, np.array([[700, 0, 800, 50]], dtype=np.int64)) == 0.0     # outside the frame


def _frame(level, sigma, seed=0):
    rng = np.random.default_rng(seed)
    grey = np.clip(level + rng.normal(0.0, sigma, (800, 1280, 1)), 0, 255).astype(np.uint8)
    return np.repeat(grey, 3, axis=2)


def test_face_crops_averages_only_a_large_face_in_a_noisy_frame():
    clean, noisy = _frame(120.0, 1.0), _frame(120.0, 20.0)
    large, small = _matrix(0.4, 0.0), _matrix(0.8, 0.0)
    crops = FaceCrops(SIZE, CHEEKS)
    assert np.array_equal(crops(clean, large, False), _plain(clean, large)) and not crops.noisy
    assert np.array_equal(crops(noisy, small, False), _plain(noisy, small)) and not crops.noisy
    assert np.array_equal(crops(noisy, large, False), area_crop(noisy, large, SIZE, 2)) and crops.noisy


def test_face_crops_keeps_its_judgement_within_the_band_and_between_judgements_of_a_followed_face():
    A = _matrix(0.4, 0.0)
    between = _frame(120.0, 120.0 * 0.5 * (NOISE_ON + NOISE_OFF))
    crops = FaceCrops(SIZE, CHEEKS)
    assert NOISE_OFF < noise_ratio(between, cv2.invertAffineTransform(A), CHEEKS) < NOISE_ON
    crops(between, A, False)
    assert not crops.noisy
    crops(_frame(120.0, 25.0), A, False)
    assert crops.noisy
    crops(between, A, False)
    assert crops.noisy                      # once noisy, clean again only under NOISE_OFF
    clean = _frame(120.0, 1.0)
    for _ in range(NOISE_EVERY - 1):        # a followed face: judged every NOISE_EVERY-th crop from the last judged
        crops(clean, A, True)
        assert crops.noisy
    crops(clean, A, True)
    assert not crops.noisy
    crops(_frame(120.0, 25.0), A, False)    # a search's crops: each judged
    assert crops.noisy


def test_read_ahead_reads_one_byte_of_each_64_of_the_rows_under_a_crop():
    rng = np.random.default_rng(2)
    rgb = rng.integers(0, 256, (300, 400, 3), dtype=np.uint8)
    flat = rgb.reshape(-1).astype(np.int64)

    def expected(x0, x1, y0, y1):
        return sum(int(flat[y * 1200 + 3 * x0:y * 1200 + 3 * x1:64].sum()) for y in range(y0, y1))

    m = AHEAD_MARGIN
    # Crop pixels to image pixels x 2 from (50, 30): a 60 x 50 crop covers x 50..170, y 30..130.
    inside = np.array([[2.0, 0.0, 50.0], [0.0, 2.0, 30.0]])
    assert read_ahead(rgb, inside, 60, 50) == expected(50 - m, 170 + m, 30 - m, 130 + m)
    # Past the frame's corner: only the frame's part is read.
    corner = np.array([[2.0, 0.0, 350.0], [0.0, 2.0, -40.0]])
    assert read_ahead(rgb, corner, 60, 50) == expected(350 - m, 400, 0, 60 + m)
    assert read_ahead(rgb, np.array([[1.0, 0.0, 500.0], [0.0, 1.0, 0.0]]), 60, 50) == 0


@pytest.mark.parametrize("who", ["performer_c", "performer_b_exaggerated"])
def test_a_large_face_in_a_dark_noisy_room_is_found_and_followed(assets, face_landmarker, who):
    """The performer (an eye distance of 100-110 px, about twice the crop's) in a light a third as bright with a
    cheap sensor's noise (Gaussian, 12 levels, new in every frame): found within the first frames and followed at
    its size near MediaPipe's curves of the frames as filmed (with bilinear crops of the noisy frames, performer_c
    is found in none of the 60 frames and performer_b is followed off her face, NME 0.26)."""
    frames, ref, _ = performer_clip(assets, face_landmarker, who)
    rng = np.random.default_rng(3)

    def dark(rgb, curves):
        return np.clip(rgb / 3.0 + rng.normal(0.0, 12.0, rgb.shape), 0, 255).astype(np.uint8)

    nme, size = followed(frames, ref, dark, who, settle=10)
    assert nme < 0.08 and 0.85 < size < 1.2, (who, nme, size)
