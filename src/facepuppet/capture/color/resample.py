"""The face crop taken from the frame (§3.1's rectangles are read on it): a bilinear warp, or, where the face is
large in a noisy frame, the warp of the face's region first averaged over blocks of image pixels.

A crop of ``px`` pixels per face unit samples a face of eye distance ``unit`` image pixels at k = ``px / unit``
crop pixels per image pixel; a bilinear warp reads only the 2 x 2 image pixels nearest each crop pixel, so for
k of 1/2 and less it keeps most of each image pixel's sensor noise (a face twice the crop's size in a dim room:
the eye search finds eyes in the noise). Averaging the face's region over blocks of n x n image pixels first,
n = floor(1 / k) (OpenCV's ``INTER_AREA`` at a whole factor), takes the noise's standard deviation down n times;
the warp then samples the blocks at n k (1/2 to 1) crop pixels a block. It softens thin edges (lids, lip
borders) a little on clean footage, so it is done only where the noise is a sizeable share of the skin's level
(:class:`FaceCrops`).

Conventions: RGB uint8 frames (H, W, 3); crop matrices (2, 3) map image pixels to crop pixels; rectangles
(x0, y0, x1, y1) int64, end exclusive.
"""

from __future__ import annotations

import cv2
import numba as nb
import numpy as np

from facepuppet._util.jit import INNER, KERNEL

__all__ = ["NOISE_ON", "NOISE_OFF", "NOISE_STRIDE", "NOISE_EVERY", "AHEAD_MARGIN", "FaceCrops", "area_crop",
           "block_size", "noise_ratio", "read_ahead"]

#: Noise ratio (:func:`noise_ratio`) above which a frame is taken for noisy, and below which for clean again
#: once noisy (the band keeps a frame near the bar from switching between the two crops). Measured on the
#: shared clips' cheeks: 0.002-0.005 as filmed and dimmed, 0.035-0.08 with Gaussian noise of 12 levels in
#: their own or a side light, 0.10-0.17 with that noise in a light a third as bright.
NOISE_ON = 0.1
NOISE_OFF = 0.08
NOISE_STRIDE = 3            # image pixels   between the pixels the noise is estimated at, each way
NOISE_EVERY = 8             # crops          of a followed face between two judgements of the noise
AHEAD_MARGIN = 8            # image pixels   :func:`read_ahead` reads beyond the crop's region each way


def block_size(A: np.ndarray) -> int:
    """The side n (>= 1) of the image pixel blocks a crop of crop matrix ``A`` (2, 3) averages: floor(1 / k), k
    the crop pixels per image pixel (the similarity's scale)."""
    (a, b, _), (c, d, _) = np.asarray(A).tolist()
    k = abs(a * d - b * c) ** 0.5
    return max(int(1.0 / max(k, 1e-9)), 1)


@nb.njit(**INNER)
def _bounds(Ainv: np.ndarray, x0: float, y0: float, x1: float, y1: float) -> tuple[float, float, float, float]:
    """(x_lo, y_lo, x_hi, y_hi): the image box bounding the crop rectangle (x0, y0, x1, y1) mapped by ``Ainv``
    (2, 3: crop pixels to image pixels)."""
    x_lo, y_lo, x_hi, y_hi = np.inf, np.inf, -np.inf, -np.inf
    for cx in (x0, x1):
        for cy in (y0, y1):
            x = Ainv[0, 0] * cx + Ainv[0, 1] * cy + Ainv[0, 2]
            y = Ainv[1, 0] * cx + Ainv[1, 1] * cy + Ainv[1, 2]
            x_lo, x_hi, y_lo, y_hi = min(x_lo, x), max(x_hi, x), min(y_lo, y), max(y_hi, y)
    return x_lo, y_lo, x_hi, y_hi


@nb.njit(**KERNEL)
def noise_ratio(rgb: np.ndarray, Ainv: np.ndarray, boxes: np.ndarray) -> float:
    """The sensor noise's standard deviation over the mean level, of the HSV value V = max(R, G, B) in the image
    regions bounding the crop rectangles ``boxes`` (N, 4) int64 of a crop whose inverse crop matrix is ``Ainv``
    (2, 3: crop pixels to image pixels); 0 where they hold no pixel with its 3 x 3 neighbourhood in the image.

    The noise by Immerkaer's estimate (1996): sigma = sqrt(pi / 2) / 6 * mean |V * N| with the mask
    N = [[1, -2, 1], [-2, 4, -2], [1, -2, 1]] (the difference of two Laplacians, blind to planes and to most of a
    smooth shading), taken every :data:`NOISE_STRIDE` pixels each way.
    """
    H, W = rgb.shape[0], rgb.shape[1]
    total, level, n = 0.0, 0.0, 0
    for b in range(boxes.shape[0]):
        x_lo, y_lo, x_hi, y_hi = _bounds(Ainv, float(boxes[b, 0]), float(boxes[b, 1]), float(boxes[b, 2]),
                                         float(boxes[b, 3]))
        x0, x1 = max(int(np.floor(x_lo)), 1), min(int(np.ceil(x_hi)), W - 1)
        y0, y1 = max(int(np.floor(y_lo)), 1), min(int(np.ceil(y_hi)), H - 1)
        for y in range(y0, y1, NOISE_STRIDE):
            for x in range(x0, x1, NOISE_STRIDE):
                r = 0.0
                for dy in range(-1, 2):
                    for dx in range(-1, 2):
                        p = rgb[y + dy, x + dx]
                        v = max(p[0], p[1], p[2])
                        if dx == 0 and dy == 0:
                            r += 4.0 * v
                            level += v
                        elif dx == 0 or dy == 0:
                            r -= 2.0 * v
                        else:
                            r += v
                total += abs(r)
                n += 1
    if n == 0:
        return 0.0
    sigma = np.sqrt(np.pi / 2.0) / 6.0 * total / n
    return sigma / max(level / n, 1.0)


@nb.njit(**KERNEL)
def read_ahead(rgb: np.ndarray, Ainv: np.ndarray, w: int, h: int) -> int:
    """Read the image region under a crop of ``w`` x ``h`` pixels (``Ainv`` (2, 3): crop pixels to image pixels)
    row by row, one byte of each 64, grown by :data:`AHEAD_MARGIN` pixels each way; the sum of the bytes read.

    A warp reads a frame a few pixels a row in an irregular order, so that each cache line of a frame held in
    memory (a clip decoded ahead, a camera's frame written by another core) comes from memory on its own; read in
    row order first, the lines stream in together and the warps that follow find them in the cache. ``rgb``
    (H, W, 3) uint8, C-contiguous.
    """
    H, W = rgb.shape[0], rgb.shape[1]
    x_lo, y_lo, x_hi, y_hi = _bounds(Ainv, 0.0, 0.0, float(w), float(h))
    x0, x1 = max(int(x_lo) - AHEAD_MARGIN, 0), min(int(x_hi) + AHEAD_MARGIN, W)
    y0, y1 = max(int(y_lo) - AHEAD_MARGIN, 0), min(int(y_hi) + AHEAD_MARGIN, H)
    flat = rgb.reshape(-1)
    total = 0
    for y in range(y0, y1):
        row = y * W * 3
        for i in range(row + 3 * x0, row + 3 * x1, 64):
            total += flat[i]
    return total


def area_crop(rgb: np.ndarray, A: np.ndarray, size: tuple[int, int], n: int) -> np.ndarray:
    """The crop (h, w, 3) uint8 of crop matrix ``A`` (2, 3) and ``size`` (w, h) from the face's region of ``rgb``
    first averaged over blocks of ``n`` x ``n`` pixels, then warped (bilinear, the border replicated as in the
    plain warp)."""
    A = np.asarray(A, dtype=np.float64)
    w, h = size
    H, W = rgb.shape[:2]
    Ainv = cv2.invertAffineTransform(A)
    xs, ys = np.array([0, w, 0, w]), np.array([0, 0, h, h])
    X, Y = Ainv[0, 0] * xs + Ainv[0, 1] * ys + Ainv[0, 2], Ainv[1, 0] * xs + Ainv[1, 1] * ys + Ainv[1, 2]
    x0, y0 = max(int(X.min()) - n, 0), max(int(Y.min()) - n, 0)
    dw, dh = (min(int(X.max()) + 2 * n, W) - x0) // n, (min(int(Y.max()) + 2 * n, H) - y0) // n
    if n < 2 or dw < 2 or dh < 2:
        return cv2.warpAffine(rgb, A, size, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    small = cv2.resize(rgb[y0:y0 + n * dh, x0:x0 + n * dw], (dw, dh), interpolation=cv2.INTER_AREA)
    # A block (u, v) has its centre at image pixel (n u + (n - 1) / 2 + x0, n v + (n - 1) / 2 + y0).
    B = np.array([[n, 0.0, 0.5 * (n - 1) + x0], [0.0, n, 0.5 * (n - 1) + y0]])
    A_small = np.hstack([A[:, :2] @ B[:, :2], (A[:, :2] @ B[:, 2] + A[:, 2])[:, None]])
    return cv2.warpAffine(small, A_small, size, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)


class FaceCrops:
    """Takes the face crops of one tracker: by area (:func:`area_crop`) while the frame is noisy and the face is
    sampled over blocks of 2 x 2 image pixels or more (:func:`block_size`), else by a bilinear warp.

    Whether the frame is noisy: :func:`noise_ratio` on the image regions of the crop's ``cheeks`` over
    :data:`NOISE_ON` (:data:`NOISE_OFF` once noisy), judged on every crop of a search for the face (each candidate
    sees its own cheeks) and, while a face is followed, on every :data:`NOISE_EVERY`-th crop counted from the last
    one judged (the light and the camera's gain change slowly).

    Parameters
    ----------
    size : (int, int)
        Width and height of the crop, pixels.
    cheeks : (N, 4) int64
        The cheeks' rectangles of the crop (x0, y0, x1, y1), crop pixels.
    """

    def __init__(self, size: tuple[int, int], cheeks: np.ndarray):
        self.size = size
        self.cheeks = np.ascontiguousarray(cheeks, dtype=np.int64)
        self.noisy = False
        self._wait = 0          # followed crops until the noise is judged again

    def __call__(self, rgb: np.ndarray, A: np.ndarray, followed: bool) -> np.ndarray:
        """The face crop (h, w, 3) uint8 of crop matrix ``A`` (2, 3) from the RGB frame ``rgb``; ``followed``:
        whether it is a followed face's."""
        n = block_size(A)
        if n >= 2:
            if not followed or self._wait <= 0:
                ratio = noise_ratio(rgb, cv2.invertAffineTransform(A), self.cheeks)
                self.noisy = ratio > (NOISE_OFF if self.noisy else NOISE_ON)
                self._wait = NOISE_EVERY
            self._wait -= 1
            if self.noisy:
                return area_crop(rgb, A, self.size, n)
        return cv2.warpAffine(rgb, A, self.size, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
