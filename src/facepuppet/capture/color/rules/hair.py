"""Facial hair at the mouth blob's edges: a moustache above the lips and a beard below them, told from the lips
by their colour.

Eq. 1's intensity rises on dark hair as on the lips, so the mouth's blob (§3.2) takes in a moustache above the
upper lip and a beard or the chin's shade below the lower lip, and the outer lips would be drawn along the
hair's edges. The lips are redder than the skin around them (Cr of YCrCb above the cheeks'), dark hair and
shade on the skin less red (a darker pixel has less chroma). In each column of the blob, the rows from its top
(bottom) to the first run of lip (:data:`HAIR_LIP` or more of pixels at least as red as the cheeks' median Cr)
are hair, and the blob's top (bottom) moves to the lip, if

- they are :data:`HAIR_LIP` or more and their mean Cr lies :data:`HAIR_CR` or more under the cheeks';
- no run of :data:`HAIR_LIP` or more of pixels less than :data:`HAIR_CR` under the cheeks lies in them but
  next to the lip (the blur of the lip's edge): sparse strands leave only specks of skin between them, a pale
  lip makes a run (and so does a blob's edge that is hardly less red than the cheeks: such a column keeps its
  blob);
- a moustache's lip starts above :data:`HAIR_LINE` under the layout's line between the lips, a beard's lip
  ends :data:`BEARD_LINE` or more under it: a moustache lies over the upper lip, a beard under the lower one.
  An open mouth's pale upper lip with the dark opening under it, over a red lower lip, is no moustache, and its
  dark opening with a pale lower lip, under a red upper lip, no beard.

A column without such lip (pale lips, an open mouth's dark inside alone, grey footage) keeps its blob.

Conventions: rectangle pixels (the mouth rectangle's), x right, y down; Cr as OpenCV's 8-bit YCrCb
(128 + 0.713 (R - Y)); ``unit`` crop pixels per face unit.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from facepuppet._util.jit import INNER

__all__ = ["HAIR_CR", "HAIR_LIP", "HAIR_LINE", "BEARD_LINE", "GREY_CR", "is_grey", "red_chroma", "hair_trim"]

# Tuning constants   unit          what it does
HAIR_CR = 8.0        # Cr levels     how much less red than the cheeks a pixel of hair (or shade) at the edge is
HAIR_LIP = 0.04      # face units    least run of lip (as red as the cheeks or redder) next to the hair
HAIR_LINE = 0.15     # face units    how far below the layout's lips' line a moustache may end
BEARD_LINE = 0.08    # face units    least depth under the layout's lips' line of a beard's start (the lower lip's end)
GREY_CR = 8.0        # Cr levels     footage whose cheeks are less red than this (Cr - 128) is grey: no colour to read


@nb.njit(**INNER)
def is_grey(skin_cr: float) -> bool:
    """Whether footage whose cheeks' median Cr is ``skin_cr`` (8-bit YCrCb) is grey (monochrome, infrared)."""
    return skin_cr - 128.0 < GREY_CR


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
def _lip_run(cr: np.ndarray, x: int, start: int, step: int, stop: int, lip: float, least: int) -> int:
    """The first pixel of the first run of ``least`` pixels of Cr >= ``lip`` along column ``x`` of ``cr`` from
    ``start`` going ``step`` (1 down, -1 up), before ``stop`` (exclusive); -1 if there is none."""
    n = 0
    y = start
    while (y - stop) * step < 0:
        n = n + 1 if cr[y, x] >= lip else 0
        if n >= least:
            return y - step * (least - 1)
        y += step
    return -1


@nb.njit(**INNER)
def _mean(cr: np.ndarray, x: int, a: int, b: int) -> float:
    """Mean of column ``x`` of ``cr`` over rows ``a`` .. ``b - 1``."""
    total = 0.0
    for y in range(a, b):
        total += cr[y, x]
    return total / max(b - a, 1)


@nb.njit(**INNER)
def _longest_run(cr: np.ndarray, x: int, a: int, b: int, level: float) -> int:
    """The longest run of pixels of Cr >= ``level`` in column ``x`` of ``cr`` over rows ``a`` .. ``b - 1``."""
    best = n = 0
    for y in range(a, b):
        n = n + 1 if cr[y, x] >= level else 0
        best = max(best, n)
    return best


@nb.njit(**INNER)
def hair_trim(cr: np.ndarray, cols: np.ndarray, top: np.ndarray, bottom: np.ndarray, skin: float, line: float,
              unit: float):
    """The blob's column profile ``top``, ``bottom`` (W,) with hair at its top and bottom left out (module
    docstring); ``cr`` (H, W) the rectangle's Cr, ``cols`` (W,) bool the columns holding the blob, ``skin`` the
    cheeks' median Cr, ``line`` the y of the layout's line between the lips. Returns (top, bottom) (W,) float32
    and per column whether hair was left out at the top and at the bottom, (W,) bool each."""
    least = max(int(HAIR_LIP * unit + 0.5), 1)
    slack = HAIR_LINE * unit
    below_line = BEARD_LINE * unit
    otop, obot = top.copy(), bottom.copy()
    above = np.zeros(len(cols), np.bool_)
    below = np.zeros(len(cols), np.bool_)
    for x in range(len(cols)):
        if not cols[x]:
            continue
        a, b = int(top[x]), int(bottom[x])
        y = _lip_run(cr, x, a, 1, b, skin, least)
        if y - a >= least and y <= line + slack and _mean(cr, x, a, y) <= skin - HAIR_CR and \
                _longest_run(cr, x, a, y - least, skin - HAIR_CR) < least:
            otop[x] = y
            above[x] = True
        a = int(otop[x])
        y = _lip_run(cr, x, b - 1, -1, a - 1, skin, least)
        if y >= 0 and b - 1 - y >= least and y >= line + below_line and _mean(cr, x, y + 1, b) <= skin - HAIR_CR and \
                _longest_run(cr, x, y + 1 + least, b, skin - HAIR_CR) < least:
            obot[x] = y + 1
            below[x] = True
    return otop, obot, above, below
