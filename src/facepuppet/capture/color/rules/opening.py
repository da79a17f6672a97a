"""The mouth's opening inside the lip blob (§3.2, Fig. 3): where the inner lips lie, and hair over the lips.

The opening is what lies between the inner lips: the mouth's dark inside, teeth, and pixels the lip blob leaves
out between its top and bottom; a tongue the colour of the lips is not told from them here (the lips' thickness
bounds it, :mod:`.mouth`). Hair over the upper lip is as dark as the opening: a dark run at the blob's top with
lip below it is hair when it is no redder for its brightness than :data:`HAIR_REDNESS` times the cheeks (a
mouth's dark inside is red; on grey footage the brightness alone decides).

Conventions: rectangle pixels (the mouth rectangle's), x right, y down; ``unit`` crop pixels per face unit;
``value`` the HSV value V (0..255), saturation 0..1, Cr as OpenCV's 8-bit YCrCb.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from facepuppet._util.jit import INNER
from facepuppet.capture.color.blobs import label8, open_mask
from facepuppet.capture.color.rules.hair import is_grey
from facepuppet.capture.color.rules.kernels import quantile

__all__ = ["OPENING_MIN_WIDTH", "TEETH_SATURATION", "mouth_opening", "saturation", "teeth_end", "redness"]

# Tuning constants         unit          what it does
LIP_LEVEL_QUANTILE = 0.9   # quantile      the lips' brightness: this quantile of V over the lip blob
LIP_LEVEL_FLOOR = 0.6      # fraction      least lips' brightness, as a share of the skin's V
DARK_FRACTION = 0.65       # fraction      pixels darker than this times the lips' or the skin's V are opening
OPENING_OPEN = 3           # pixels        side of the opening (morphology) that clears specks off the opening
OPENING_MIN_AREA = 0.004   # face units^2  smallest opening that counts as an open mouth
OPENING_MIN_WIDTH = 0.1    # face units    narrowest opening that counts as an open mouth
HAIR_SLACK = 0.1           # face units    below the layout's lips' line hair over a closed mouth may end
HAIR_MIN = 0.04            # face units    least height of a dark run at the blob's top (hair) and of the lip below it
HAIR_REDNESS = 1.5         # ratio         a dark run is hair if no redder for its brightness than this times the cheeks
TEETH_LEVEL = 0.8          # fraction      pixels brighter than this times the skin's V just beyond the blob are teeth
TEETH_SATURATION = 0.75    # fraction      teeth are less saturated than this times the skin's saturation
TEETH_GAP = 0.1            # face units    farthest beyond the blob such a run may start (the blob's blurred edge)
TEETH_MAX = 0.45           # face units    tallest run of teeth the opening takes in above or below the blob
TEETH_SPLIT = 0.08         # face units    longest break inside a run of teeth (the line between two rows of teeth)


@nb.njit(**INNER)
def mouth_opening(mask: np.ndarray, cols: np.ndarray, top: np.ndarray, bottom: np.ndarray, value: np.ndarray,
                  sat: np.ndarray, skin: float, sat_max: float, line: float, unit: float, cr: np.ndarray,
                  skin_cr: float):
    """Top and bottom of the mouth opening per column of the mouth rectangle (the lip crease if closed), and
    where the lips start at the top (below hair over the upper lip; else the blob's top), and whether each
    column holds lip (not only dark pixels).

    ``value`` is the HSV value V (0..255) of the rectangle, ``sat`` its saturation (0..1), ``cr`` its Cr
    (:func:`~.hair.red_chroma`), ``skin`` and ``skin_cr`` the cheeks' median V and Cr, ``line`` the y of the
    layout's line between the lips (rectangle pixels); footage whose cheeks are grey (:func:`~.hair.is_grey`)
    has no colour to read. The opening is dark
    (below :data:`DARK_FRACTION` of the lips' brightness, or of the skin's if lower), left out of the lip blob
    between its top and bottom, or teeth just beyond the blob (brighter than :data:`TEETH_LEVEL` of the skin
    and less saturated than ``sat_max``); its largest 8-connected part counts if it is big and wide enough,
    with the parts stacked above and below it, from the first dark pixel under the lips' top (a band under the
    upper lip too thin for the morphology, above a tongue).
    """
    h, w = mask.shape
    grey = is_grey(skin_cr)
    skin_red = (skin_cr - 128.0) / max(skin, 1.0)
    lips = np.empty(h * w)
    n = 0
    for y in range(h):
        for x in range(w):
            if mask[y, x]:
                lips[n] = value[y, x]
                n += 1
    level = quantile(lips[:n], LIP_LEVEL_QUANTILE) if n else skin
    # A blob that is all opening (pale lips) has the opening's own level: the lips are taken to be at least
    # LIP_LEVEL_FLOOR of the skin's brightness.
    thr = DARK_FRACTION * min(max(level, LIP_LEVEL_FLOOR * skin), skin)
    opening = np.zeros((h, w), np.uint8)
    crease = np.empty(w, np.float32)
    # Hair above the lips (a moustache) is dark as the opening and joins the lip blob at its top: a dark run at
    # the blob's top with lip below it and more blob below that is not the opening, and the lips start under it.
    teeth = TEETH_LEVEL * skin
    most = int(TEETH_MAX * unit + 0.5)
    edge = int(TEETH_GAP * unit + 0.5)
    split = int(TEETH_SPLIT * unit + 0.5)
    lip_top = top.copy()
    lit = np.zeros(w, np.bool_)
    hair_min = max(int(HAIR_MIN * unit + 0.5), 1)
    for x in range(w):
        if not cols[x]:
            continue
        n_lit = 0
        for y in range(h):
            if mask[y, x] and value[y, x] >= thr:
                n_lit += 1
        lit[x] = n_lit >= hair_min
        y = int(top[x])
        if y < bottom[x] and value[y, x] >= thr:
            y += 1                                   # the blob's blurred edge
        start = y
        while y < bottom[x] and mask[y, x] and value[y, x] < thr:
            y += 1
        end = y
        while y < bottom[x] and mask[y, x] and value[y, x] >= thr:
            y += 1
        # (lip below the dark run down to the blob's bottom: a closed mouth under hair if the run ends above
        # where the layout puts the lips' line; else the lips may be pale and the run the opening). Hair is no
        # redder for its brightness than HAIR_REDNESS times the cheeks, which a mouth's dark inside above a
        # tongue is (on grey footage the value alone decides).
        below = y < bottom[x] - 1 or end <= line + HAIR_SLACK * unit
        hairy = grey or redness(cr, value, x, start, end) <= HAIR_REDNESS * skin_red
        if end - start >= hair_min and y - end >= hair_min and below and hairy and \
                teeth_end(value[:, x], sat[:, x], int(top[x]) - 1, -1, teeth, sat_max, edge, most, split) < 0:
            lip_top[x] = end                         # (teeth above the dark run: it is the opening)
    for x in range(w):
        best = np.inf
        arg = -1
        for y in range(h):
            if cols[x] and lip_top[x] + 1 <= y < bottom[x] - 1:
                if value[y, x] < thr or not mask[y, x]:
                    opening[y, x] = 1
                if value[y, x] < best:
                    best = value[y, x]
                    arg = y
        crease[x] = arg + 0.5 if arg >= 0 else (lip_top[x] + bottom[x]) / 2.0
        if cols[x] and lip_top[x] == top[x]:
            # Teeth just beyond the blob (a pale lip left out of it): the opening reaches the lip past them.
            for step in (-1, 1):
                start = int(top[x]) - 1 if step < 0 else int(bottom[x])
                end = teeth_end(value[:, x], sat[:, x], start, step, teeth, sat_max, edge, most, split)
                if end >= 0:
                    for y in range(min(start, end), max(start, end) + 1):
                        opening[y, x] = 1
    opening = open_mask(opening, OPENING_OPEN)
    labels, count = label8(opening)
    if count < 2:
        return crease, crease.copy(), lip_top, lit
    area = np.zeros(count, np.int64)
    xmin = np.full(count, w)
    xmax = np.full(count, -1)
    seen = np.zeros(count, np.int64)                 # pixels of each part that are dark or teeth
    for y in range(h):
        for x in range(w):
            k = labels[y, x]
            if k:
                area[k] += 1
                if value[y, x] < thr or (value[y, x] > teeth and sat[y, x] < sat_max):
                    seen[k] += 1
                xmin[k] = min(xmin[k], x)
                xmax[k] = max(xmax[k], x)
    k = 1 + np.argmax(area[1:])
    if area[k] < OPENING_MIN_AREA * unit * unit or xmax[k] - xmin[k] + 1 < OPENING_MIN_WIDTH * unit:
        return crease, crease.copy(), lip_top, lit
    # Parts of the opening that a tongue (lip-coloured) or a band of teeth splits apart lie above and below
    # each other: every large enough part across the same columns as the largest, mostly dark or teeth (not a
    # lip's highlight the blob left out), is the opening too.
    take = np.zeros(count, np.bool_)
    for j in range(1, count):
        overlap = min(xmax[j], xmax[k]) - max(xmin[j], xmin[k]) + 1
        take[j] = j == k or (area[j] >= OPENING_MIN_AREA * unit * unit and 2 * seen[j] >= area[j]
                             and overlap >= 0.5 * min(xmax[j] - xmin[j] + 1, xmax[k] - xmin[k] + 1))
    otop = crease.copy()
    obot = crease.copy()
    for x in range(w):
        for y in range(h):
            if labels[y, x] > 0 and take[labels[y, x]]:
                otop[x] = y
                break
        for y in range(h - 1, -1, -1):
            if labels[y, x] > 0 and take[labels[y, x]]:
                obot[x] = y + 1
                break
        # A thin dark band under the upper lip (the mouth's inside in its shade, too thin for the morphology to
        # keep) above the parts taken: the opening starts at it.
        if cols[x] and obot[x] > otop[x]:
            for y in range(int(lip_top[x]) + 1, int(otop[x])):
                if value[y, x] < thr:
                    otop[x] = y
                    break
    return otop, obot, lip_top, lit


@nb.njit(**INNER)
def redness(cr: np.ndarray, value: np.ndarray, x: int, a: int, b: int) -> float:
    """Mean over rows ``a`` .. ``b - 1`` of column ``x`` of the chroma Cr - 128 over the value V: how red a pixel
    is for its brightness (a dark pixel has less chroma)."""
    total = 0.0
    for y in range(a, b):
        total += (cr[y, x] - 128.0) / max(value[y, x], 1.0)
    return total / max(b - a, 1)


@nb.njit(**INNER)
def saturation(rgb: np.ndarray, x0: int, y0: int, x1: int, y1: int) -> np.ndarray:
    """HSV saturation (0..1) of the rectangle (x0, y0, x1, y1) of ``rgb`` (H, W, 3) uint8, (y1 - y0, x1 - x0)."""
    out = np.zeros((max(y1 - y0, 0), max(x1 - x0, 0)), np.float32)
    for y in range(y0, y1):
        for x in range(x0, x1):
            r, g, b = np.int64(rgb[y, x, 0]), np.int64(rgb[y, x, 1]), np.int64(rgb[y, x, 2])
            hi = max(r, g, b)
            out[y - y0, x - x0] = (hi - min(r, g, b)) / hi if hi > 0 else 0.0
    return out


@nb.njit(**INNER)
def teeth_end(column: np.ndarray, sat: np.ndarray, start: int, step: int, level: float, sat_max: float, gap: int,
               most: int, split: int) -> int:
    """The last pixel of a run of teeth from ``start`` going ``step`` (-1 up, 1 down): pixels brighter than
    ``level`` and less saturated than ``sat_max`` (``column`` V, ``sat`` saturation), starting within ``gap``
    pixels (the blob's blurred edge), broken nowhere by more than ``split`` other pixels (the line between the
    upper and the lower teeth), ended within ``most`` pixels by another pixel (the lip) inside the column;
    -1 if there is no such run."""
    y = start
    for _ in range(gap):
        if 0 <= y < len(column) and not (column[y] > level and sat[y] < sat_max):
            y += step
    if not 0 <= y < len(column) or not (column[y] > level and sat[y] < sat_max):
        return -1
    n = 0
    last = -1
    miss = 0
    while 0 <= y < len(column) and n <= most:
        if column[y] > level and sat[y] < sat_max:
            last = y
            miss = 0
        else:
            miss += 1
            if miss > split:
                break
        y += step
        n += 1
    if last < 0 or n > most or not 0 <= y < len(column):
        return -1
    return last
