"""How much a face crop looks like a face: its feature intensity correlated with the layout drawn as a face.

The tracker scores candidate face frames with it when acquiring, crops whose cheeks do not look like skin, and
now and then the followed crop.
"""

from __future__ import annotations

import cv2
import numba as nb
import numpy as np

from facepuppet._util.jit import KERNEL
from facepuppet.capture.color.face import box_in_crop
from facepuppet.capture.curves import bezier_points

__all__ = ["FaceTemplate", "TEMPLATE_LINE", "TEMPLATE_BLUR", "TEMPLATE_BOX", "TEMPLATE_SAMPLES", "moved_correlation"]

# Tuning constants                        unit         what it does
TEMPLATE_LINE = 0.06                      # face units   thickness of the template's lines
TEMPLATE_BLUR = 0.05                      # face units   blur (Gaussian sigma) of the template
TEMPLATE_BOX = (-0.95, -0.6, 0.95, 1.7)   # face units   part of the crop the likeness is scored on
TEMPLATE_SAMPLES = 16                     # points       along each curve where it is drawn


class FaceTemplate:
    """The layout drawn as bright features on dark skin: eyes, brows, mouth line and nostrils.

    Parameters
    ----------
    layout_px : (C, 4, 2) float
        The layout placed on an unmoved face crop, crop pixels.
    size : (int, int)
        Width and height of the face crop.
    px : float
        Crop pixels per face unit.
    """

    def __init__(self, layout_px: np.ndarray, size: tuple[int, int], px: float):
        self.size = size
        T = np.zeros(size[::-1], np.float32)
        for curve in layout_px:
            pts = np.round(bezier_points(curve, TEMPLATE_SAMPLES) * 4).astype(np.int32)
            cv2.polylines(T, [pts], False, 1.0, thickness=max(1, int(TEMPLATE_LINE * px)), lineType=cv2.LINE_AA,
                          shift=2)
        #: (H, W) float32 the drawn template.
        self.image = cv2.GaussianBlur(T, (0, 0), TEMPLATE_BLUR * px)
        #: The part of the crop scored, crop pixels.
        self.box = box_in_crop(TEMPLATE_BOX, px)

    def score(self, C: np.ndarray, S_px: np.ndarray) -> float:
        """Correlation (in [-1, 1]) of the feature intensity C (H, W) with the template moved by the similarity
        ``S_px`` (2, 3) in crop pixels (where the eyes put the layout), over :attr:`box`
        (:func:`moved_correlation`)."""
        x0, y0, x1, y1 = self.box
        return float(moved_correlation(C, self.image, np.asarray(S_px, dtype=np.float64), x0, y0, x1, y1))


@nb.njit(**KERNEL)
def moved_correlation(C: np.ndarray, T: np.ndarray, S: np.ndarray, x0: int, y0: int, x1: int, y1: int) -> float:
    """Correlation of ``C`` (H, W) float32 with the image ``T`` (h, w) float32 moved by the affine map ``S`` (2, 3)
    (T's pixels to C's), over C's rectangle [x0, x1) x [y0, y1) (clipped to C).

    T is moved as :func:`cv2.warpAffine` moves it with the map rounded to float32, bilinear, 0 outside T: each
    pixel (x, y) of C reads T at the map's inverse of (x, y). The correlation is the Pearson coefficient of the
    rectangle's pixel pairs, its denominator at least 1e-9; sums in float64.
    """
    h, w = T.shape
    H, W = C.shape
    m00, m01, m02 = np.float32(S[0, 0]), np.float32(S[0, 1]), np.float32(S[0, 2])
    m10, m11, m12 = np.float32(S[1, 0]), np.float32(S[1, 1]), np.float32(S[1, 2])
    d = float(m00) * float(m11) - float(m01) * float(m10)
    d = 1.0 / d if d != 0.0 else 0.0
    a00, a11 = float(m11) * d, float(m00) * d
    a01, a10 = -float(m01) * d, -float(m10) * d
    a02 = -a00 * float(m02) - a01 * float(m12)
    a12 = -a10 * float(m02) - a11 * float(m12)
    n = 0
    sc = st = scc = stt = sct = 0.0
    for y in range(max(y0, 0), min(y1, H)):
        for x in range(max(x0, 0), min(x1, W)):
            X = a00 * x + a01 * y + a02
            Y = a10 * x + a11 * y + a12
            fx0, fy0 = np.floor(X), np.floor(Y)
            ix, iy = int(fx0), int(fy0)
            fx, fy = X - fx0, Y - fy0
            t = 0.0
            if -1 <= ix < w and -1 <= iy < h:
                if 0 <= iy:
                    if 0 <= ix:
                        t += (1.0 - fy) * (1.0 - fx) * T[iy, ix]
                    if ix + 1 < w:
                        t += (1.0 - fy) * fx * T[iy, ix + 1]
                if iy + 1 < h:
                    if 0 <= ix:
                        t += fy * (1.0 - fx) * T[iy + 1, ix]
                    if ix + 1 < w:
                        t += fy * fx * T[iy + 1, ix + 1]
            c = float(C[y, x])
            n += 1
            sc += c
            st += t
            scc += c * c
            stt += t * t
            sct += c * t
    if n == 0:
        return 0.0
    vc = max(scc - sc * sc / n, 0.0)
    vt = max(stt - st * st / n, 0.0)
    return (sct - sc * st / n) / max(np.sqrt(vc * vt), 1e-9)
