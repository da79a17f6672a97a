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

__all__ = ["FaceTemplate", "TEMPLATE_LINE", "TEMPLATE_BLUR", "TEMPLATE_BOX", "TEMPLATE_SAMPLES", "box_correlation"]

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
        ``S_px`` (2, 3) in crop pixels (where the eyes put the layout), over :attr:`box` (:func:`box_correlation`)."""
        T = cv2.warpAffine(self.image, S_px.astype(np.float32), self.size, flags=cv2.INTER_LINEAR)
        return float(box_correlation(C, T, *self.box))


@nb.njit(fastmath={"reassoc", "nsz", "contract"}, **KERNEL)
def box_correlation(C: np.ndarray, T: np.ndarray, x0: int, y0: int, x1: int, y1: int) -> float:
    """Correlation of ``C`` and ``T`` (H, W) float32 over the rectangle [x0, x1) x [y0, y1) (clipped to them): the
    Pearson coefficient of the rectangle's pixel pairs, its denominator at least 1e-9; sums in float64 (free to
    be reordered); 0.0 for an empty rectangle."""
    H, W = C.shape
    xa, xb, ya, yb = max(x0, 0), min(x1, W), max(y0, 0), min(y1, H)
    if xb <= xa or yb <= ya:
        return 0.0
    sc = st = scc = stt = sct = 0.0
    for y in range(ya, yb):
        for x in range(xa, xb):
            c, t = float(C[y, x]), float(T[y, x])
            sc += c
            st += t
            scc += c * c
            stt += t * t
            sct += c * t
    n = float((xb - xa) * (yb - ya))
    vc = max(scc - sc * sc / n, 0.0)
    vt = max(stt - st * st / n, 0.0)
    return (sct - sc * st / n) / max(np.sqrt(vc * vt), 1e-9)
