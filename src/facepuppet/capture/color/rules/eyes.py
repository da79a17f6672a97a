"""The eyes' rule of §3.2: each eyelid curve moved onto the eye blob's edges.

Conventions: crop pixels, x right, y down; curves (C, 4, 2) in :data:`~facepuppet.capture.curves.CURVE_NAMES`
order; ``unit`` is crop pixels per face unit (the eye-centre distance).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from facepuppet._util.jit import INNER, KERNEL
from facepuppet.capture.color.blobs import blob_kernel
from facepuppet.capture.color.rules.kernels import MIN_COLUMNS, median, mid_shift, mid_y, sample_profile
from facepuppet.capture.curves import CURVE_NAMES

__all__ = ["eye_outlines"]

_I = {n: i for i, n in enumerate(CURVE_NAMES)}
_LID_UP = np.array([_I["eye_right_upper"], _I["eye_left_upper"]])
_LID_LO = np.array([_I["eye_right_lower"], _I["eye_left_lower"]])

# Tuning constants      unit         what it does
EYE_NEAR = 0.25         # face units   radius around the layout's eye centre where the eye blob is preferred
BLOB_MIN_AREA = 3       # pixels       smallest blob that counts (:func:`~.blobs.blob_kernel`)
LOWER_LID_STEP = 0.08   # face units   farthest the lower lid's middle moves up or down from the layout's
UPPER_LID_UP = 0.1      # face units   farthest the upper lid's middle moves up from the layout's
UPPER_LID_DOWN = 0.2    # face units   farthest the upper lid's middle moves down (a blink) from the layout's
LID_GAP = 0.02          # face units   least gap the upper lid keeps above the lower one
LASH_LEVEL = 0.5        # C            least contrast C of the lash line's pixels
THIN_EYE = 0.5          # fraction     of the layout's eye height under which the blob is the lash line alone
LASH_MAX = 0.1          # face units   longest bright run from the blob's top that is lash line, not iris


@nb.njit(**INNER)
def _lash(C: np.ndarray, mask: np.ndarray, cols: np.ndarray, top: np.ndarray, unit: float) -> float:
    """Thickness (rows) of the lash line at the top of an eye blob, where the white of the eye shows below it.

    In each column the bright run from the blob's top is measured; runs shorter than ``LASH_MAX * unit`` are the
    lash line over the sclera (longer ones reach into the iris). Their median, or 0 when fewer than three
    columns show it.
    """
    h, w = mask.shape
    runs = np.empty(w)
    n = 0
    for x in range(w):
        if not cols[x]:
            continue
        run = float(h)
        for r in range(h):
            if r >= top[x] and not (mask[r, x] and C[r, x] > LASH_LEVEL):
                run = r - top[x]
                break
        if 0 < run < LASH_MAX * unit:
            runs[n] = run
            n += 1
    return median(runs[:n]) if n >= MIN_COLUMNS else 0.0


@nb.njit(**KERNEL)
def eye_outlines(C: np.ndarray, layout: np.ndarray, out: np.ndarray, boxes: np.ndarray, params: np.ndarray,
                 unit: float) -> None:
    """Both eyes' lids (§3.2) written into ``out`` (C, 4, 2): the lower lid onto the eye blob's bottom edge, the
    upper lid onto the lower edge of the lash line at its top, each by one shift of its middle control points.
    A blob whose median height over its columns is under :data:`THIN_EYE` of the layout's eye height (upper to
    lower lid) is the lash line alone (a closing eye, or an eye whose white and iris are no darker than the
    skin, as on a dark complexion): its bottom is not the lower lid, which stays the layout's.

    ``C``: (H, W) float32 contrast C; ``layout``: (C, 4, 2) the layout placed on the crop; ``boxes``: the
    rectangles in :data:`~.outline.BOX_NAMES` order (the eyes are rows 0 and 1); ``params``: the eye blob's
    :meth:`~facepuppet.capture.color.blobs.BlobConfig.as_array`; ``unit``: crop pixels per face unit.
    """
    for side in range(2):
        x0, y0, x1, y1 = boxes[side]
        up, lo = _LID_UP[side], _LID_LO[side]
        ex = 0.125 * (layout[up, :, 0].sum() + layout[lo, :, 0].sum())
        ey = 0.125 * (layout[up, :, 1].sum() + layout[lo, :, 1].sum())
        sub = np.ascontiguousarray(C[y0:y1, x0:x1])
        found, mask, _, _, _, cols, top, bottom = blob_kernel(sub, params, ex - x0, ey - y0, EYE_NEAR * unit,
                                                              BLOB_MIN_AREA)
        if not found:
            continue
        ok, y = sample_profile(out[lo], cols, bottom + y0, x0)
        thick = median((bottom - top)[cols].astype(np.float64)) if cols.any() else 0.0
        height = mid_y(layout[lo]) - mid_y(layout[up])
        if ok and thick >= THIN_EYE * height:
            d = min(max(mid_shift(out[lo], y), -LOWER_LID_STEP * unit), LOWER_LID_STEP * unit)
            out[lo, 1, 1] += d
            out[lo, 2, 1] += d
        # The lid curve is the lower edge of the lash line (the landmark convention), not the blob's top.
        ok, y = sample_profile(out[up], cols, top + _lash(sub, mask, cols, top, unit) + y0, x0)
        if ok:
            d = min(max(mid_shift(out[up], y), -UPPER_LID_UP * unit), UPPER_LID_DOWN * unit)
            for j in (1, 2):
                # The upper lid may not cross the lower one.
                out[up, j, 1] = min(out[up, j, 1] + d, out[lo, j, 1] - LID_GAP * unit)
