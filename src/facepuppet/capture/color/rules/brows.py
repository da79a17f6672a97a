"""The brows' rule of §3.2: each brow curve moved onto the brow blob, then onto the brow's upper edge.

On Eq. 1's raw intensity normalised inside the rectangle (forehead skin at the median), the brow curve goes onto
the blob's upper edge, at most half the brow's thickness down (the upper edge is sharp, the lower may merge with
the lid's shadow). Then the brow's upper edge is followed on the HSV value, from that curve up (a glasses' rim
or the lid's shadow may hold the blob's top, a faint brow lies above them), and the curve's ends reach out as
far as the edge goes (a brow on the near side of a turned head is wider than the layout's).

Conventions: crop pixels, x right, y down; curves (C, 4, 2) in :data:`~facepuppet.capture.curves.CURVE_NAMES`
order; ``unit`` is crop pixels per face unit; ``value`` the HSV value V (0..255).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from facepuppet._util.jit import INNER, KERNEL
from facepuppet.capture.color.blobs import blob_kernel
from facepuppet.capture.color.rules.kernels import (
    along,
    interp,
    line_fit,
    median,
    quantile_pair,
    sample_profile,
    sort_order,
)
from facepuppet.capture.curves import CURVE_NAMES

__all__ = ["BROW_DEPTH", "brow_outlines", "brow_edges", "closed_columns", "median_level"]

_I = {n: i for i, n in enumerate(CURVE_NAMES)}
_BROW = np.array([_I["brow_right"], _I["brow_left"]])

# Tuning constants of the blob step (brow_outlines)
#                          unit        what it does
BROW_SKIN_QUANTILE = 0.5   # quantile    of the raw intensity in the rectangle taken as forehead skin (level 0)
BROW_TOP_QUANTILE = 0.97   # quantile    of the raw intensity in the rectangle taken as the brow (level 1)
BROW_NEAR = 0.3            # face units  radius around the layout's brow centre where the brow blob is preferred
BLOB_MIN_AREA = 3          # pixels      smallest blob that counts (:func:`~.blobs.blob_kernel`)
BROW_MIN_WIDTH = 0.4       # fraction    narrowest brow blob, of the rectangle's width
BROW_DEPTH = 0.05          # face units  farthest below its upper edge the brow curve lies
BROW_TILT = 0.5            # slope       largest tilt of the brow curve against the layout's
BROW_TILT_FLOOR = 0.1      # slope       tilts below this are the edge's noise: the layout's slant holds
BROW_THICK = 0.25          # face units  a blob thicker than this is no brow band to tilt the curve by (hair, shadow)
BROW_BLOB_SHIFT = 0.15     # face units  farthest the blob step moves the curve up or down

# Tuning constants of the edge step (brow_edges, on the HSV value)
#                          unit        what it does
EDGE_ROWS = 0.08           # face units  rows averaged above and below the edge
EDGE_UP = 0.2              # face units  how far above the blob's curve the edge is searched
EDGE_MARGIN = 0.2          # face units  columns searched beyond the rectangle on either side
EDGE_MIN_COLUMNS = 6       # columns     fewest columns searched for the edge to be read
EDGE_SMOOTH = 2            # columns     either side of a column its contrast is averaged over
EDGE_MIDDLE_PARTS = 6      # parts       the edge's middle is this fraction (1/parts either side) of the columns
EDGE_FLOOR = 0.05          # fraction    least contrast (of the forehead's value) of the edge's middle to count
EDGE_KEEP = 0.4            # fraction    of the middle's contrast the edge keeps along the brow's extent
BROW_REACH = 0.35          # face units  farthest the curve's ends reach beyond the layout's
BROW_SHIFT = 0.2           # face units  farthest the edge step moves the curve up or down


@nb.njit(**INNER)
def _brow_tilt(b: float) -> float:
    """The tilt a brow curve takes from a measured edge slope ``b`` against the layout's: small tilts are the
    edge's noise (the layout's slant holds), so only the excess over ``BROW_TILT_FLOOR`` counts, at most
    ``BROW_TILT``."""
    return min(max(b - min(max(b, -BROW_TILT_FLOOR), BROW_TILT_FLOOR), -BROW_TILT), BROW_TILT)


@nb.njit(**KERNEL)
def brow_outlines(raw: np.ndarray, layout: np.ndarray, out: np.ndarray, boxes: np.ndarray, params: np.ndarray,
                  unit: float) -> None:
    """Both brow curves (§3.2) written into ``out`` (C, 4, 2): on Eq. 1's intensity ``raw`` (H, W) normalised in
    each brow rectangle (rows 2 and 3 of ``boxes``), the curve onto the blob's upper edge, at most
    :data:`BROW_DEPTH` below it, tilted onto it; ``params`` the brow blob's options, ``unit`` crop pixels per
    face unit."""
    for side in range(2):
        x0, y0, x1, y1 = boxes[2 + side]
        if x1 <= x0 or y1 <= y0:
            continue
        # Brows are often fainter than the eyes and lips the contrast C is scaled to: normalise the raw
        # intensity of Eq. 1 within the rectangle (forehead skin at the median).
        sub = raw[y0:y1, x0:x1]
        lo_v, hi_v = quantile_pair(sub.copy().ravel(), BROW_SKIN_QUANTILE, BROW_TOP_QUANTILE)
        norm = ((sub.astype(np.float64) - lo_v) / max(hi_v - lo_v, 1e-6)).astype(np.float32)
        c = _BROW[side]
        ex = 0.25 * layout[c, :, 0].sum()
        ey = 0.25 * layout[c, :, 1].sum()
        found, _, _, box, _, cols, top, bottom = blob_kernel(norm, params, ex - x0, ey - y0, BROW_NEAR * unit,
                                                             BLOB_MIN_AREA)
        if not found or box[2] - box[0] < BROW_MIN_WIDTH * (x1 - x0):
            continue
        # The brow's upper edge is sharp; its lower edge may merge with the lid's shadow.
        edge = np.minimum(top + BROW_DEPTH * unit, (top + bottom) / 2.0) + y0
        ok, y = sample_profile(out[c], cols, edge, x0)
        if not ok:
            continue
        # The curve is tilted onto the edge (brows slant, a head turned or rolled slants them more): a robust
        # line through the edge's offsets from the curve, over the samples above the blob.
        xs = along(out[c], 0)
        inside = (xs >= box[0] + x0) & (xs <= box[2] + x0)
        r = y - along(out[c], 1)
        b, xm = 0.0, xs.mean()
        thick = median((bottom - top)[cols])
        if inside.sum() >= 4 and thick < BROW_THICK * unit:
            b = line_fit(xs[inside], r[inside])[1]
            b = _brow_tilt(b)
        a = median(r - b * (xs - xm))
        a = min(max(a, -BROW_BLOB_SHIFT * unit), BROW_BLOB_SHIFT * unit)
        for j in range(4):
            out[c, j, 1] += a + b * (out[c, j, 0] - xm)


@nb.njit(**INNER)
def closed_columns(value: np.ndarray, x0: int, x1: int, y0: int, y1: int) -> np.ndarray:
    """``value`` over rows y0..y1 and columns x0..x1 closed along the columns by three pixels (the largest of
    each pixel and its neighbours above and below, then the smallest of those, as OpenCV's closing by a 3 x 1
    element): dark lines one or two pixels thick, a glasses' rim, a wrinkle, take their surroundings' value;
    thicker dark bands, brows, stay. Pixels outside the image take no part. Returns (y1 - y0, x1 - x0) float64.
    """
    h = value.shape[0]
    n = x1 - x0
    ga, gb = max(y0 - 1, 0), min(y1 + 1, h)
    grown = np.empty((gb - ga, n))
    for r in range(ga, gb):
        g = grown[r - ga]
        for x in range(n):
            g[x] = value[r, x0 + x]
        for q in (r - 1, r + 1):
            if 0 <= q < h:
                for x in range(n):
                    g[x] = max(g[x], value[q, x0 + x])
    out = np.empty((y1 - y0, n))
    for y in range(y0, y1):
        o = out[y - y0]
        g0 = grown[y - ga]
        for x in range(n):
            o[x] = g0[x]
        for q in (y - 1, y + 1):
            if ga <= q < gb:
                g = grown[q - ga]
                for x in range(n):
                    o[x] = min(o[x], g[x])
    return out


@nb.njit(**INNER)
def median_level(block: np.ndarray) -> float:
    """Median of a block of whole numbers in 0..255 (8-bit levels), by counting."""
    counts = np.zeros(256, np.int64)
    for v in block.ravel():
        counts[min(max(int(v), 0), 255)] += 1
    n = block.size
    if n == 0:
        return 0.0
    lo_rank, hi_rank = (n - 1) // 2, n // 2
    seen = 0
    lo_v = -1
    for level in range(256):
        seen += counts[level]
        if lo_v < 0 and seen > lo_rank:
            lo_v = level
        if seen > hi_rank:
            return 0.5 * (lo_v + level)
    return float(lo_v)


@nb.njit(**INNER)
def _upper_edge(value: np.ndarray, prior: np.ndarray, x0: int, x1: int, y0: int, y1: int, box: np.ndarray,
                unit: float):
    """The brow's upper edge in columns x0..x1: bright forehead above, darker brow below, on the closed value
    (:func:`closed_columns`), searched in rows y0..y1 from ``EDGE_UP`` face units above the curve ``prior``
    (its row per column) down to it, as one path that moves at most a row per column (dynamic programming).

    Returns (rows, contrast): the edge's row per column (the pixel boundary between the forehead and the brow,
    to a fraction of a row) and its contrast there, the mean value of ``EDGE_ROWS`` face units above minus
    that below over the forehead's value (the median over the rectangle ``box``, within the columns searched).
    """
    h = value.shape[0]
    n = x1 - x0
    s = max(int(round(EDGE_ROWS * unit)), 2)
    ya, yb = max(y0 - s, 0), min(y1 + s, h)
    V = closed_columns(value, x0, x1, ya, yb)
    bx0, bx1 = min(max(box[0], x0), x1), min(max(box[2], x0), x1)
    forehead = median_level(V[y0 - ya:y1 - ya, bx0 - x0:bx1 - x0].copy()) if bx1 > bx0 else 0.0
    # Only the rows some column may search.
    ra = max(y0, int(np.ceil(prior.min() - EDGE_UP * unit)))
    m = min(y1, int(np.floor(prior.max())) + 1) - ra
    if m <= 0:
        return prior.copy(), np.zeros(n)
    # Column sums from the top, for the means above and below each row.
    cs = np.empty((yb - ya + 1, n))
    cs[0] = 0.0
    for r in range(yb - ya):
        for x in range(n):
            cs[r + 1, x] = cs[r, x] + V[r, x]
    R = np.full((m, n), -1e9)
    for x in range(n):
        for i in range(m):
            y = ra + i
            if not (prior[x] - EDGE_UP * unit <= y <= prior[x]):
                continue
            a, b = max(y - s, ya), min(y + s, yb)
            if a >= y or b <= y:
                continue
            above = (cs[y - ya, x] - cs[a - ya, x]) / (y - a)
            below = (cs[b - ya, x] - cs[y - ya, x]) / (b - y)
            R[i, x] = (above - below) / max(forehead, 1.0)
    acc = R[:, 0].copy()
    back = np.zeros((m, n), np.int64)
    nxt = np.empty(m)
    for x in range(1, n):
        for i in range(m):
            best, arg = acc[i], i
            if i > 0 and acc[i - 1] > best:
                best, arg = acc[i - 1], i - 1
            if i < m - 1 and acc[i + 1] > best:
                best, arg = acc[i + 1], i + 1
            nxt[i] = best + R[i, x]
            back[i, x] = arg
        for i in range(m):
            acc[i] = nxt[i]
    rows = np.empty(n)
    contrast = np.empty(n)
    i = int(np.argmax(acc))
    for x in range(n - 1, -1, -1):
        # To a fraction of a row: the parabola through the contrast of the row and its neighbours.
        frac = 0.0
        if 0 < i < m - 1 and R[i - 1, x] > -1e8 and R[i + 1, x] > -1e8:
            curv = R[i - 1, x] - 2.0 * R[i, x] + R[i + 1, x]
            if curv < 0.0:
                frac = min(max(0.5 * (R[i - 1, x] - R[i + 1, x]) / curv, -0.5), 0.5)
        rows[x] = ra + i + frac
        contrast[x] = R[i, x]
        i = back[i, x]
    return rows, contrast


@nb.njit(**KERNEL)
def brow_edges(value: np.ndarray, layout: np.ndarray, out: np.ndarray, boxes: np.ndarray, unit: float) -> None:
    """Each brow curve onto the brow's upper edge on the HSV value, its ends out to the edge's extent.

    The edge is searched from the blob's curve (:func:`brow_outlines`) up: what held the blob's top may be a
    glasses' rim or the lid's shadow under a faint brow, never something above the brow. Where the edge's
    middle is too faint (no brow seen), the blob's curve stays. The brow's extent is the run of columns around
    the middle where the edge keeps ``EDGE_KEEP`` of the middle's contrast, its ends read off the run's
    moments; the layout's curve is stretched out to them (never shrunk: a brow's tail may fade), placed
    ``BROW_DEPTH`` below the edge and tilted onto it as in :func:`brow_outlines`.
    """
    h, w = value.shape
    for side in range(2):
        x0, y0, x1, y1 = boxes[2 + side]
        if x1 <= x0 or y1 <= y0:
            continue
        c = _BROW[side]
        margin = int(round(EDGE_MARGIN * unit))
        xa, xb = max(x0 - margin, 0), min(x1 + margin, w)
        n = xb - xa
        if n < EDGE_MIN_COLUMNS:
            continue
        # The blob's curve, row per column (level beyond its ends).
        px = along(out[c], 0)
        py = along(out[c], 1)
        order = sort_order(px)
        cols = np.arange(xa, xb) + 0.5
        prior = interp(cols, px[order], py[order])
        rows, contrast = _upper_edge(value, prior, xa, xb, y0, y1, boxes[2 + side], unit)
        # The contrast averaged over a few columns (the extent's noise).
        sm = np.empty(n)
        for i in range(n):
            sm[i] = contrast[max(i - EDGE_SMOOTH, 0):min(i + EDGE_SMOOTH + 1, n)].mean()
        contrast = sm
        mid = int(np.argmin(np.abs(cols - 0.25 * out[c, :, 0].sum())))
        k = max(n // EDGE_MIDDLE_PARTS, 1)
        middle = median(contrast[max(mid - k, 0):min(mid + k + 1, n)].copy())
        if middle <= EDGE_FLOOR:
            continue
        level = EDGE_KEEP * middle
        # The run of columns around the middle where the edge holds (gaps of one column bridged).
        i0 = mid
        while i0 > 0 and (contrast[i0 - 1] > level or (i0 > 1 and contrast[i0 - 2] > level)):
            i0 -= 1
        i1 = mid
        while i1 < n - 1 and (contrast[i1 + 1] > level or (i1 < n - 2 and contrast[i1 + 2] > level)):
            i1 += 1
        # The run's ends from its moments (an even band of length L has mean ± sqrt(3) sd at its ends), each
        # column weighted by its contrast over the level, up to the middle's: steadier than the run's ends.
        sw = sx = sxx = 0.0
        for i in range(i0, i1 + 1):
            wgt = min(max(contrast[i], level), middle) - level
            sw += wgt
            sx += wgt * cols[i]
            sxx += wgt * cols[i] * cols[i]
        if sw <= 0.0:
            continue
        mean = sx / sw
        sd = np.sqrt(max(sxx / sw - mean * mean, 0.0))
        e0, e1 = mean - np.sqrt(3.0) * sd, mean + np.sqrt(3.0) * sd
        lo = min(layout[c, 0, 0], layout[c, 3, 0])
        hi = max(layout[c, 0, 0], layout[c, 3, 0])
        a0 = lo - min(max(lo - e0, 0.0), BROW_REACH * unit)
        a1 = hi + min(max(e1 - hi, 0.0), BROW_REACH * unit)
        curve = layout[c].copy()
        for j in range(4):
            curve[j, 0] = a0 + (layout[c, j, 0] - lo) * (a1 - a0) / max(hi - lo, 1e-6)
        xs = along(curve, 0)
        inside = (xs >= cols[i0]) & (xs <= cols[i1])
        if inside.sum() < 4:
            continue
        r = interp(xs, cols, rows + BROW_DEPTH * unit) - along(curve, 1)
        b = line_fit(xs[inside], r[inside])[1]
        b = _brow_tilt(b)
        xm = xs.mean()
        a = median((r - b * (xs - xm))[inside])
        a = min(max(a, -BROW_SHIFT * unit), BROW_SHIFT * unit)
        for j in range(4):
            out[c, j, 0] = curve[j, 0]
            out[c, j, 1] = curve[j, 1] + (a + b * (curve[j, 0] - xm))
