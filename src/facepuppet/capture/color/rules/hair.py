"""Facial hair at the mouth blob's edges: a moustache above the lips and a beard below them, told from the lips
by their colour.

Eq. 1's intensity rises on dark hair as on the lips, so the mouth's blob (§3.2) takes in a moustache above the
upper lip and a beard or the chin's shade below the lower lip, and the outer lips would be drawn along the
hair's edges. The lips are redder than the skin around them (Cr of YCrCb above the cheeks'), dark hair and
shade on the skin less red (a darker pixel has less chroma): in each column of the blob, a run at its top
(bottom) whose Cr lies :data:`HAIR_CR` or more under the cheeks' median Cr, with lip at least as red as the
cheeks next to it (within :data:`HAIR_GAP`, the edge's blur and the chroma's subsampling) for
:data:`HAIR_LIP` or more, is hair: the blob's top (bottom) moves to the lip. A column without red lip next to
the run (pale lips, an open mouth's dark inside at the blob's edge, grey footage) keeps its blob.

Conventions: rectangle pixels (the mouth rectangle's), x right, y down; Cr as OpenCV's 8-bit YCrCb
(128 + 0.713 (R - Y)); ``unit`` crop pixels per face unit.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from facepuppet._util.jit import INNER
from facepuppet.capture.color.rules.kernels import median

__all__ = ["HAIR_CR", "HAIR_LIP", "HAIR_GAP", "red_chroma", "skin_red", "hair_trim"]

# Tuning constants   unit          what it does
HAIR_CR = 8.0        # Cr levels     how much less red than the cheeks a pixel of hair (or shade) at the edge is
HAIR_LIP = 0.04      # face units    least run of lip (as red as the cheeks or redder) next to the hair
HAIR_GAP = 0.05      # face units    farthest the lip's run may start beyond the hair's end


@nb.njit(**INNER)
def red_chroma(rgb: np.ndarray, x0: int, y0: int, x1: int, y1: int) -> np.ndarray:
    """Cr (8-bit YCrCb, float32) of the rectangle (x0, y0, x1, y1) of ``rgb`` (H, W, 3) uint8, (y1 - y0, x1 - x0)."""
    out = np.empty((max(y1 - y0, 0), max(x1 - x0, 0)), np.float32)
    for y in range(y0, y1):
        for x in range(x0, x1):
            r, g, b = float(rgb[y, x, 0]), float(rgb[y, x, 1]), float(rgb[y, x, 2])
            out[y - y0, x - x0] = 128.0 + 0.713 * (r - (0.299 * r + 0.587 * g + 0.114 * b))
    return out


@nb.njit(**INNER)
def skin_red(rgb: np.ndarray, boxes: np.ndarray) -> float:
    """Median Cr of the pixels of the rectangles ``boxes`` (K, 4) of ``rgb`` together (the cheeks)."""
    n = 0
    for k in range(len(boxes)):
        n += max(boxes[k, 2] - boxes[k, 0], 0) * max(boxes[k, 3] - boxes[k, 1], 0)
    vals = np.empty(max(n, 1))
    i = 0
    for k in range(len(boxes)):
        cr = red_chroma(rgb, boxes[k, 0], boxes[k, 1], boxes[k, 2], boxes[k, 3])
        for v in cr.ravel():
            vals[i] = v
            i += 1
    return median(vals[:i]) if i else 128.0


@nb.njit(**INNER)
def _lip_after(cr: np.ndarray, x: int, start: int, step: int, stop: int, lip: float, gap: int, least: int) -> bool:
    """Whether a run of ``least`` pixels of Cr >= ``lip`` starts within ``gap`` pixels of ``start`` going ``step``
    down column ``x`` of ``cr``, before ``stop`` (exclusive)."""
    y = start
    for _ in range(gap + 1):
        if (y - stop) * step >= 0:
            return False
        if cr[y, x] >= lip:
            n = 0
            while (y - stop) * step < 0 and cr[y, x] >= lip:
                n += 1
                if n >= least:
                    return True
                y += step
            return False
        y += step
    return False


@nb.njit(**INNER)
def hair_trim(cr: np.ndarray, cols: np.ndarray, top: np.ndarray, bottom: np.ndarray, skin: float, unit: float):
    """The blob's column profile ``top``, ``bottom`` (W,) with hair at its top and bottom left out (module
    docstring); ``cr`` (H, W) the rectangle's Cr, ``cols`` (W,) bool the columns holding the blob, ``skin`` the
    cheeks' median Cr. Returns (top, bottom) (W,) float32 and per column whether hair was left out at the top and
    at the bottom, (W,) bool each."""
    hair_lvl, lip = skin - HAIR_CR, skin
    least = max(int(HAIR_LIP * unit + 0.5), 1)
    gap = int(HAIR_GAP * unit + 0.5)
    otop, obot = top.copy(), bottom.copy()
    above = np.zeros(len(cols), np.bool_)
    below = np.zeros(len(cols), np.bool_)
    for x in range(len(cols)):
        if not cols[x]:
            continue
        a, b = int(top[x]), int(bottom[x])
        y = a
        while y < b and cr[y, x] < hair_lvl:
            y += 1
        if y - a >= least and _lip_after(cr, x, y, 1, b, lip, gap, least):
            otop[x] = y
            above[x] = True
        y = b - 1
        while y >= int(otop[x]) and cr[y, x] < hair_lvl:
            y -= 1
        if b - 1 - y >= least and _lip_after(cr, x, y, -1, int(otop[x]) - 1, lip, gap, least):
            obot[x] = y + 1
            below[x] = True
    return otop, obot, above, below
