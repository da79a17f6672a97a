"""The mouth's rule of §3.2 (Fig. 3): the lip curves moved onto the mouth blob and the opening inside it.

Corners and outer lips come from the blob's outline, inner lips from the mouth opening inside it (dark pixels,
or pixels the blob leaves out between its top and bottom, as teeth), or the lip crease when the mouth is closed.

Conventions: crop pixels, x right, y down; curves (C, 4, 2) in :data:`~facepuppet.capture.curves.CURVE_NAMES`
order; ``unit`` is crop pixels per face unit; ``value`` the HSV value V (0..255).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from facepuppet._util.jit import INNER, KERNEL
from facepuppet.capture.color.blobs import blob_kernel, label8, open_mask
from facepuppet.capture.color.rules.kernels import median_of_boxes, mid_shift, quantile, sample_profile
from facepuppet.capture.curves import CURVE_NAMES

__all__ = ["mouth_outlines"]

_I = {n: i for i, n in enumerate(CURVE_NAMES)}
_LIPS = np.array([_I["lip_upper_outer"], _I["lip_lower_outer"], _I["lip_upper_inner"], _I["lip_lower_inner"]])

#: Bounds (face units) of the lips' middle points around the layout: outer upper, outer lower, inner upper,
#: inner lower (the lower lips move down with the jaw).
LIP_LOW = np.array([-0.15, -0.15, -0.15, -0.15])
LIP_HIGH = np.array([0.15, 0.8, 0.15, 0.8])

# Tuning constants         unit          what it does
MOUTH_NEAR = 0.3           # face units    radius around the layout's mouth centre where the lip blob is preferred
BLOB_MIN_AREA = 3          # pixels        smallest blob that counts (:func:`~.blobs.blob_kernel`)
MOUTH_MIN_COLUMNS = 4      # columns       fewest columns of the mouth blob for the lips to be read
LIP_LEVEL_QUANTILE = 0.75  # quantile      the lips' brightness: this quantile of V over the lip blob
DARK_FRACTION = 0.5        # fraction      pixels darker than this times the lips' or the skin's V are opening
OPENING_OPEN = 3           # pixels        side of the opening (morphology) that clears specks off the opening
OPENING_MIN_AREA = 0.004   # face units^2  smallest opening that counts as an open mouth
OPENING_MIN_WIDTH = 0.1    # face units    narrowest opening that counts as an open mouth


@nb.njit(**INNER)
def _opening(mask: np.ndarray, cols: np.ndarray, top: np.ndarray, bottom: np.ndarray, value: np.ndarray,
             skin: float, unit: float):
    """Top and bottom of the mouth opening per column of the mouth rectangle (the lip crease if closed).

    ``value`` is the HSV value V (0..255) of the rectangle, ``skin`` the cheeks' median V. The opening is
    dark (below half the lips' and the skin's brightness) or left out of the lip blob between its top and
    bottom; its largest 8-connected part counts if it is big and wide enough.
    """
    h, w = mask.shape
    lips = np.empty(h * w)
    n = 0
    for y in range(h):
        for x in range(w):
            if mask[y, x]:
                lips[n] = value[y, x]
                n += 1
    level = quantile(lips[:n], LIP_LEVEL_QUANTILE) if n else skin
    thr = DARK_FRACTION * min(level, skin)
    opening = np.zeros((h, w), np.uint8)
    crease = np.empty(w, np.float32)
    for x in range(w):
        best = np.inf
        arg = -1
        for y in range(h):
            if cols[x] and top[x] + 1 <= y < bottom[x] - 1:
                if value[y, x] < thr or not mask[y, x]:
                    opening[y, x] = 1
                if value[y, x] < best:
                    best = value[y, x]
                    arg = y
        crease[x] = arg + 0.5 if arg >= 0 else (top[x] + bottom[x]) / 2.0
    opening = open_mask(opening, OPENING_OPEN)
    labels, count = label8(opening)
    if count < 2:
        return crease, crease.copy()
    area = np.zeros(count, np.int64)
    xmin = np.full(count, w)
    xmax = np.full(count, -1)
    for y in range(h):
        for x in range(w):
            k = labels[y, x]
            if k:
                area[k] += 1
                xmin[k] = min(xmin[k], x)
                xmax[k] = max(xmax[k], x)
    k = 1 + np.argmax(area[1:])
    if area[k] < OPENING_MIN_AREA * unit * unit or xmax[k] - xmin[k] + 1 < OPENING_MIN_WIDTH * unit:
        return crease, crease.copy()
    otop = crease.copy()
    obot = crease.copy()
    for x in range(w):
        for y in range(h):
            if labels[y, x] == k:
                otop[x] = y
                break
        for y in range(h - 1, -1, -1):
            if labels[y, x] == k:
                obot[x] = y + 1
                break
    return otop, obot


@nb.njit(**KERNEL)
def mouth_outlines(C: np.ndarray, value: np.ndarray, layout: np.ndarray, offset: np.ndarray, out: np.ndarray,
                   boxes: np.ndarray, params: np.ndarray, unit: float, reach: float) -> None:
    """Lips from the mouth blob (§3.2, Fig. 3): corners and outer lips from its outline, inner lips from the
    mouth opening inside it, written into ``out`` (C, 4, 2). ``boxes``: the rectangles in
    :data:`~.outline.BOX_NAMES` order (the mouth is row 4, the cheeks rows 5 and 6). ``offset`` (2,) moves the layout's
    lips (where the mouth was seen at acquisition);
    the corners stay within ``reach`` face units of the layout's.
    """
    x0, y0, x1, y1 = boxes[4]
    lay = layout.copy()
    for c in _LIPS:
        for j in range(4):
            lay[c, j, 0] += offset[0]
            lay[c, j, 1] += offset[1]
    uo, lo, ui, li = _LIPS[0], _LIPS[1], _LIPS[2], _LIPS[3]
    cx = 0.125 * (lay[ui, :, 0].sum() + lay[li, :, 0].sum())
    cy = 0.125 * (lay[ui, :, 1].sum() + lay[li, :, 1].sum())
    sub = np.ascontiguousarray(C[y0:y1, x0:x1])
    found, mask, _, _, _, cols, top, bottom = blob_kernel(sub, params, cx - x0, cy - y0, MOUTH_NEAR * unit,
                                                          BLOB_MIN_AREA)
    if not found:
        return
    xs = np.nonzero(cols)[0]
    if len(xs) < MOUTH_MIN_COLUMNS:
        return
    lx_l, lx_r = lay[uo, 0, 0], lay[uo, 3, 0]
    ly_l, ly_r = lay[uo, 0, 1], lay[uo, 3, 1]
    b = reach * unit
    xl = min(max(xs[0] + x0, lx_l - b), lx_l + b)
    xr = min(max(xs[-1] + 1 + x0, lx_r - b), lx_r + b)
    mid = (top + bottom) / 2.0 + y0
    yl = min(max(mid[xs[0]:xs[0] + 3].mean(), ly_l - b), ly_l + b)
    yr = min(max(mid[max(xs[-1] - 2, 0):xs[-1] + 1].mean(), ly_r - b), ly_r + b)
    for c in _LIPS:
        l0, l1 = lay[c, 0, 0], lay[c, 3, 0]
        # Each curve keeps its end offsets from the outer corners (inner lip ends lie inside the mouth).
        a0, a1 = xl + (l0 - lx_l), xr + (l1 - lx_r)
        for j in range(4):
            out[c, j, 0] = a0 + (lay[c, j, 0] - l0) * (a1 - a0) / max(l1 - l0, 1e-6)
        out[c, 0, 1] = yl + (lay[c, 0, 1] - ly_l)
        out[c, 3, 1] = yr + (lay[c, 3, 1] - ly_r)
    skin = median_of_boxes(value, boxes[5:7])
    itop, ibot = _opening(mask, cols, top, bottom, value[y0:y1, x0:x1], skin, unit)
    # Outer lips: the blob's outline; inner lips: the opening inside it (bounds: fraction of the unit).
    profiles = np.empty((4, len(top)), np.float32)
    for x in range(len(top)):
        profiles[0, x], profiles[1, x], profiles[2, x], profiles[3, x] = top[x], bottom[x], itop[x], ibot[x]
    for i in range(4):
        c = _LIPS[i]
        ok, y = sample_profile(out[c], cols, profiles[i] + y0, x0)
        if ok:
            d = mid_shift(out[c], y)
            for j in (1, 2):
                lo_b, hi_b = lay[c, j, 1] + LIP_LOW[i] * unit, lay[c, j, 1] + LIP_HIGH[i] * unit
                out[c, j, 1] = min(max(out[c, j, 1] + d, lo_b), hi_b)
    for j in (1, 2):
        out[ui, j, 1] = min(max(out[ui, j, 1], out[uo, j, 1]), out[lo, j, 1])
        out[li, j, 1] = min(max(out[li, j, 1], out[ui, j, 1]), out[lo, j, 1])
        # The lower lip keeps at least the layout's thickness (a pale lower lip leaves the blob short of it).
        out[lo, j, 1] = max(out[lo, j, 1], out[li, j, 1] + lay[lo, j, 1] - lay[li, j, 1])
