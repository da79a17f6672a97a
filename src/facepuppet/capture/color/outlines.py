"""Feature outlines read off the feature intensity (paper §3.2): the colour tracker's per-frame rules.

In a face crop whose feature intensity C (Eq. 1 and the contrast C) is known, each feature's rectangle gets
a blob (:func:`~facepuppet.capture.color.blobs.blob_kernel`) and the layout's curves are moved onto the blob's
column profile:

* eyes: the lower lid onto the blob's bottom edge, the upper lid onto the lower edge of the lash line at
  its top (the landmark convention); the upper lid never crosses the lower one;
* brows: on the raw Eq. 1 intensity normalised inside the rectangle (forehead skin at the median), the brow
  curve onto its upper edge, at most half the brow's thickness down (the upper edge is sharp, the lower
  may merge with the lid's shadow); then the brow's upper edge is followed on the HSV value, from that
  curve up (a glasses' rim or the lid's shadow may hold the blob's top, a faint brow lies above them), and
  the curve's ends reach out as far as the edge goes (a brow on the near side of a turned head is wider
  than the layout's);
* mouth: corners and outer lips from the blob's outline, inner lips from the mouth opening inside it (dark
  pixels or pixels the blob leaves out between its top and bottom, as teeth), or the lip crease when closed.

Each curve keeps its shape and moves by one robust number (the median shift of its middle control points
over the central samples), so a noisy column cannot bend it. The work is compiled with numba, one kernel per
feature (eyes, brows, mouth; :mod:`facepuppet._util.jit`): it is the tracker's per-frame work, a few hundred
small steps that cost more to call from Python than to do.

Conventions: crop pixels, x right, y down; curves (C, 4, 2) control points in :data:`CURVE_NAMES` order;
rectangles (x0, y0, x1, y1) inclusive-exclusive, in the order of :data:`BOX_NAMES`.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from facepuppet._util.jit import INNER, KERNEL
from facepuppet.capture.color.blobs import blob_kernel, label8, open_mask
from facepuppet.capture.curves import CURVE_NAMES, bernstein

__all__ = ["BOX_NAMES", "BLOB_KINDS", "OUTLINE_PARTS", "eye_centres", "feature_intensity", "move_boxes",
           "outline_features", "skin_fraction"]

#: Rectangles :func:`outline_features` reads, in the order of its ``boxes`` argument.
BOX_NAMES = ("eye_right", "eye_left", "brow_right", "brow_left", "mouth", "cheek_left", "cheek_right")
#: Blob options, in the order of its ``blob_params`` rows.
BLOB_KINDS = ("eye", "brow", "mouth")
#: The parts :func:`outline_features` reads, each one compiled kernel.
OUTLINE_PARTS = ("eyes", "brows", "mouth")

_I = {n: i for i, n in enumerate(CURVE_NAMES)}
_BROW = np.array([_I["brow_right"], _I["brow_left"]])
_LID_UP = np.array([_I["eye_right_upper"], _I["eye_left_upper"]])
_LID_LO = np.array([_I["eye_right_lower"], _I["eye_left_lower"]])
_LIPS = np.array([_I["lip_upper_outer"], _I["lip_lower_outer"], _I["lip_upper_inner"], _I["lip_lower_inner"]])

#: Bounds (face units) of the lips' middle points around the layout: outer upper, outer lower, inner upper,
#: inner lower (the lower lips move down with the jaw).
_LIP_LOW = np.array([-0.15, -0.15, -0.15, -0.15])
_LIP_HIGH = np.array([0.15, 0.8, 0.15, 0.8])

#: How far below its upper edge the brow curve may lie (face units); the brow curve's largest tilt against the
#: layout, the tilt under which it keeps the layout's (noise), and the blob thickness (face units) above which
#: the blob is no brow band to tilt it by (a hair line, a shadow).
_BROW_DEPTH = 0.05
_BROW_TILT = 0.5
_BROW_TILT_FLOOR = 0.1
_BROW_THICK = 0.25

#: The brow's upper edge on the HSV value (:func:`_brow_edges`), face units unless said: rows averaged above
#: and below the edge, how far above the blob's curve it is searched, columns searched beyond the rectangle,
#: the least contrast (fraction of the forehead's value) of the edge's middle for it to count, the fraction of
#: that contrast the edge keeps along the brow's extent, the farthest the curve ends reach beyond the layout's,
#: and the farthest the curve moves up or down.
_EDGE_ROWS = 0.08
_EDGE_UP = 0.2
_EDGE_MARGIN = 0.2
_EDGE_FLOOR = 0.05
_EDGE_KEEP = 0.4
_BROW_REACH = 0.35
_BROW_SHIFT = 0.2

#: The contrast C's feature level is at most this many times the brightest 3 x 3 mean's height above the skin
#: level: a brighter pixel stands alone, a speck of noise (on the shared clips the brightest pixel's height is
#: 1.2-1.6 times the 3 x 3 mean's, so this never binds there; a light stretched to undo a colour cast turns a
#: camera's block noise into specks 3 times as high, which squashed C below the eye search's floor).
_SPECK = 2.0

_K = 12                                                 # boundary samples per curve
_B = bernstein(np.linspace(0.0, 1.0, _K))               # (K, 4)
_MID = _B[:, 1] + _B[:, 2]                              # how much a common shift of the middle points moves
_CENTRAL = np.flatnonzero(_MID >= 0.6)                  # samples the middle control points move most


@nb.njit(**INNER)
def _along(ctrl: np.ndarray, d: int) -> np.ndarray:
    """Coordinate ``d`` of the curve's K samples, ``B @ ctrl[:, d]``."""
    out = np.zeros(_K)
    for k in range(_K):
        for j in range(4):
            out[k] += _B[k, j] * ctrl[j, d]
    return out


@nb.njit(**INNER)
def _select(a: np.ndarray, k: int) -> np.ndarray:
    """A copy of the 1-D array ``a`` arranged so that ``d[k]`` is its k-th smallest value, ``d[:k]`` the k
    smallest and ``d[k + 1:]`` the rest (Hoare's selection; what ``np.partition(a, k)`` gives, written out
    because numba's compiles for seconds, each type again)."""
    d = a.copy()
    lo, hi = 0, len(d) - 1
    while lo < hi:
        p = d[(lo + hi) // 2]
        i, j = lo, hi
        while i <= j:
            while d[i] < p:
                i += 1
            while d[j] > p:
                j -= 1
            if i <= j:
                d[i], d[j] = d[j], d[i]
                i += 1
                j -= 1
        if k <= j:
            hi = j
        elif k >= i:
            lo = i
        else:
            break
    return d


@nb.njit(**INNER)
def _median(a: np.ndarray) -> float:
    """Median of a non-empty 1-D array: the mean of its two middle order statistics, found by selection
    (no full sort; the same value as ``0.5 * (d[(n - 1) // 2] + d[n // 2])`` of the sorted data ``d``)."""
    n = len(a)
    k = n // 2
    d = _select(a, k)                           # d[k], and d[:k] the k smallest
    hi = d[k]
    lo = d[:k].max() if n % 2 == 0 else hi
    return 0.5 * (lo + hi)


@nb.njit(**INNER)
def _quantile(a: np.ndarray, q: float) -> float:
    """Quantile ``q`` in [0, 1] of a non-empty 1-D array, interpolated linearly between its two neighbouring
    order statistics (numpy's default rule), which are found by selection (no full sort)."""
    n = len(a)
    pos = q * (n - 1)
    i = min(int(pos), n - 2) if n > 1 else 0
    j = min(i + 1, n - 1)
    d = _select(a, j)                           # d[j], and d[:j] the j smallest
    hi = d[j]
    lo = d[:j].max() if j > i else hi
    return lo + (pos - i) * (hi - lo)


@nb.njit(**INNER)
def _interp(x: np.ndarray, xp: np.ndarray, fp: np.ndarray) -> np.ndarray:
    """``np.interp(x, xp, fp)`` for increasing ``xp`` (same values: the end values outside, ``fp[j]`` where
    ``x == xp[j]``, else the line through the neighbours), written out because numba's compiles for seconds."""
    n = len(xp)
    out = np.empty(len(x))
    for i in range(len(x)):
        v = x[i]
        if v < xp[0]:
            out[i] = fp[0]
        elif v >= xp[n - 1]:
            out[i] = fp[n - 1]
        else:
            lo, hi = 0, n - 1                   # xp[lo] <= v < xp[hi]
            while hi - lo > 1:
                mid = (lo + hi) // 2
                if xp[mid] <= v:
                    lo = mid
                else:
                    hi = mid
            if xp[lo] == v:
                out[i] = fp[lo]
            else:
                out[i] = (fp[lo + 1] - fp[lo]) / (xp[lo + 1] - xp[lo]) * (v - xp[lo]) + fp[lo]
    return out


@nb.njit(**INNER)
def _order(a: np.ndarray) -> np.ndarray:
    """Indices that sort the short 1-D array ``a`` (insertion sort, stable)."""
    idx = np.arange(len(a))
    for i in range(1, len(a)):
        k = idx[i]
        j = i - 1
        while j >= 0 and a[idx[j]] > a[k]:
            idx[j + 1] = idx[j]
            j -= 1
        idx[j + 1] = k
    return idx


@nb.njit(**INNER)
def _mid_shift(ctrl: np.ndarray, y: np.ndarray) -> float:
    """The common vertical shift of the middle control points that best moves the curve onto the profile ``y``
    (median over the central samples)."""
    base = _along(ctrl, 1)
    d = np.empty(len(_CENTRAL))
    for i in range(len(_CENTRAL)):
        k = _CENTRAL[i]
        d[i] = (y[k] - base[k]) / _MID[k]
    return _median(d)


@nb.njit(**INNER)
def _sample_profile(ctrl: np.ndarray, cols: np.ndarray, prof: np.ndarray, x0: int):
    """A blob profile (per rectangle column, plus ``y0``) read at the x of the curve's K samples.

    Returns (ok, y): ok is False when fewer than three columns hold the blob.
    """
    xs = np.nonzero(cols)[0]
    if len(xs) < 3:
        return False, np.zeros(_K)
    xf = xs.astype(np.float64)
    pf = np.empty(len(xs))
    for i in range(len(xs)):
        pf[i] = prof[xs[i]]
    x_samples = _along(ctrl, 0) - x0 - 0.5
    return True, _interp(x_samples, xf, pf)


@nb.njit(**INNER)
def _lash(C: np.ndarray, mask: np.ndarray, cols: np.ndarray, top: np.ndarray, unit: float) -> float:
    """Thickness (rows) of the lash line at the top of an eye blob, where the white of the eye shows below it.

    In each column the bright run from the blob's top is measured; runs shorter than ``0.1 * unit`` are the
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
            if r >= top[x] and not (mask[r, x] and C[r, x] > 0.5):
                run = r - top[x]
                break
        if 0 < run < 0.1 * unit:
            runs[n] = run
            n += 1
    return _median(runs[:n]) if n >= 3 else 0.0


@nb.njit(**INNER)
def _top_of_boxes(img: np.ndarray, boxes: np.ndarray, floor: float):
    """The brightest pixel of ``img`` in the rectangles, and the brightest 3 x 3 mean centred in them (each
    at least ``floor``)."""
    h, w = img.shape
    top = peak = floor
    for b in range(len(boxes)):
        for y in range(max(boxes[b, 1], 0), min(boxes[b, 3], h)):
            for x in range(max(boxes[b, 0], 0), min(boxes[b, 2], w)):
                top = max(top, img[y, x])
                if 0 < y < h - 1 and 0 < x < w - 1:
                    s = 0.0
                    for dy in range(-1, 2):
                        for dx in range(-1, 2):
                            s += img[y + dy, x + dx]
                    peak = max(peak, s / 9.0)
    return top, peak


@nb.njit(**INNER)
def _median_of_boxes(img: np.ndarray, boxes: np.ndarray) -> float:
    """Median of the pixels of several rectangles of ``img`` together."""
    total = 0
    for b in range(len(boxes)):
        total += max(boxes[b, 2] - boxes[b, 0], 0) * max(boxes[b, 3] - boxes[b, 1], 0)
    vals = np.empty(total)
    n = 0
    for b in range(len(boxes)):
        for y in range(boxes[b, 1], boxes[b, 3]):
            for x in range(boxes[b, 0], boxes[b, 2]):
                vals[n] = img[y, x]
                n += 1
    return _median(vals) if n else 0.0


@nb.njit(**KERNEL)
def _eyes(C: np.ndarray, layout: np.ndarray, out: np.ndarray, boxes: np.ndarray, params: np.ndarray,
          unit: float) -> None:
    for side in range(2):
        x0, y0, x1, y1 = boxes[side]
        up, lo = _LID_UP[side], _LID_LO[side]
        ex = 0.125 * (layout[up, :, 0].sum() + layout[lo, :, 0].sum())
        ey = 0.125 * (layout[up, :, 1].sum() + layout[lo, :, 1].sum())
        sub = np.ascontiguousarray(C[y0:y1, x0:x1])
        found, mask, _, _, _, cols, top, bottom = blob_kernel(sub, params, ex - x0, ey - y0, 0.25 * unit, 3)
        if not found:
            continue
        ok, y = _sample_profile(out[lo], cols, bottom + y0, x0)
        if ok:
            d = min(max(_mid_shift(out[lo], y), -0.08 * unit), 0.08 * unit)
            out[lo, 1, 1] += d
            out[lo, 2, 1] += d
        # The lid curve is the lower edge of the lash line (the landmark convention), not the blob's top.
        ok, y = _sample_profile(out[up], cols, top + _lash(sub, mask, cols, top, unit) + y0, x0)
        if ok:
            d = min(max(_mid_shift(out[up], y), -0.1 * unit), 0.2 * unit)
            for j in (1, 2):
                # The upper lid may not cross the lower one.
                out[up, j, 1] = min(out[up, j, 1] + d, out[lo, j, 1] - 0.02 * unit)


@nb.njit(**INNER)
def _line_fit(x: np.ndarray, y: np.ndarray):
    """Robust line y ≈ a + b (x - mean x) (Theil-Sen: the median of the pairwise slopes, then the median
    offset); returns (a, b, mean x)."""
    n = len(x)
    xm = x.mean()
    slopes = np.empty(n * (n - 1) // 2)
    k = 0
    for i in range(n):
        for j in range(i + 1, n):
            if abs(x[j] - x[i]) > 1e-9:
                slopes[k] = (y[j] - y[i]) / (x[j] - x[i])
                k += 1
    b = _median(slopes[:k]) if k else 0.0
    return _median(y - b * (x - xm)), b, xm


@nb.njit(**INNER)
def _brow_tilt(b: float) -> float:
    """The tilt a brow curve takes from a measured edge slope ``b`` against the layout's: small tilts are the
    edge's noise (the layout's slant holds), so only the excess over ``_BROW_TILT_FLOOR`` counts, at most
    ``_BROW_TILT``."""
    return min(max(b - min(max(b, -_BROW_TILT_FLOOR), _BROW_TILT_FLOOR), -_BROW_TILT), _BROW_TILT)


@nb.njit(**KERNEL)
def _brows(raw: np.ndarray, layout: np.ndarray, out: np.ndarray, boxes: np.ndarray, params: np.ndarray,
           unit: float) -> None:
    for side in range(2):
        x0, y0, x1, y1 = boxes[2 + side]
        if x1 <= x0 or y1 <= y0:
            continue
        # Brows are often fainter than the eyes and lips the contrast C is scaled to: normalise the raw
        # intensity of Eq. 1 within the rectangle (forehead skin at the median).
        sub = raw[y0:y1, x0:x1].astype(np.float64)
        flat = sub.ravel()
        lo_v = _quantile(flat, 0.5)
        hi_v = _quantile(flat, 0.97)
        norm = ((sub - lo_v) / max(hi_v - lo_v, 1e-6)).astype(np.float32)
        c = _BROW[side]
        ex = 0.25 * layout[c, :, 0].sum()
        ey = 0.25 * layout[c, :, 1].sum()
        found, _, _, box, _, cols, top, bottom = blob_kernel(norm, params, ex - x0, ey - y0, 0.3 * unit, 3)
        if not found or box[2] - box[0] < 0.4 * (x1 - x0):
            continue
        # The brow's upper edge is sharp; its lower edge may merge with the lid's shadow.
        edge = np.minimum(top + _BROW_DEPTH * unit, (top + bottom) / 2.0) + y0
        ok, y = _sample_profile(out[c], cols, edge, x0)
        if not ok:
            continue
        # The curve is tilted onto the edge (brows slant, a head turned or rolled slants them more): a robust
        # line through the edge's offsets from the curve, over the samples above the blob.
        xs = _along(out[c], 0)
        inside = (xs >= box[0] + x0) & (xs <= box[2] + x0)
        r = y - _along(out[c], 1)
        b, xm = 0.0, xs.mean()
        thick = _median((bottom - top)[cols])
        if inside.sum() >= 4 and thick < _BROW_THICK * unit:
            b = _line_fit(xs[inside], r[inside])[1]
            b = _brow_tilt(b)
        a = _median(r - b * (xs - xm))
        a = min(max(a, -0.15 * unit), 0.15 * unit)
        for j in range(4):
            out[c, j, 1] += a + b * (out[c, j, 0] - xm)


@nb.njit(**INNER)
def _closed_columns(value: np.ndarray, x0: int, x1: int, y0: int, y1: int) -> np.ndarray:
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
def _median_level(block: np.ndarray) -> float:
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
    (:func:`_closed_columns`), searched in rows y0..y1 from ``_EDGE_UP`` face units above the curve ``prior``
    (its row per column) down to it, as one path that moves at most a row per column (dynamic programming).

    Returns (rows, contrast): the edge's row per column (the pixel boundary between the forehead and the brow,
    to a fraction of a row) and its contrast there, the mean value of ``_EDGE_ROWS`` face units above minus
    that below over the forehead's value (the median over the rectangle ``box``, within the columns searched).
    """
    h = value.shape[0]
    n = x1 - x0
    s = max(int(round(_EDGE_ROWS * unit)), 2)
    ya, yb = max(y0 - s, 0), min(y1 + s, h)
    V = _closed_columns(value, x0, x1, ya, yb)
    bx0, bx1 = min(max(box[0], x0), x1), min(max(box[2], x0), x1)
    forehead = _median_level(V[y0 - ya:y1 - ya, bx0 - x0:bx1 - x0].copy()) if bx1 > bx0 else 0.0
    # Only the rows some column may search.
    ra = max(y0, int(np.ceil(prior.min() - _EDGE_UP * unit)))
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
            if not (prior[x] - _EDGE_UP * unit <= y <= prior[x]):
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
def _brow_edges(value: np.ndarray, layout: np.ndarray, out: np.ndarray, boxes: np.ndarray, unit: float) -> None:
    """Each brow curve onto the brow's upper edge on the HSV value, its ends out to the edge's extent.

    The edge is searched from the blob's curve (:func:`_brows`) up: what held the blob's top may be a
    glasses' rim or the lid's shadow under a faint brow, never something above the brow. Where the edge's
    middle is too faint (no brow seen), the blob's curve stays. The brow's extent is the run of columns around
    the middle where the edge keeps ``_EDGE_KEEP`` of the middle's contrast, its ends read off the run's
    moments; the layout's curve is stretched out to them (never shrunk: a brow's tail may fade), placed
    ``_BROW_DEPTH`` below the edge and tilted onto it as in :func:`_brows`.
    """
    h, w = value.shape
    for side in range(2):
        x0, y0, x1, y1 = boxes[2 + side]
        if x1 <= x0 or y1 <= y0:
            continue
        c = _BROW[side]
        margin = int(round(_EDGE_MARGIN * unit))
        xa, xb = max(x0 - margin, 0), min(x1 + margin, w)
        n = xb - xa
        if n < 6:
            continue
        # The blob's curve, row per column (level beyond its ends).
        px = _along(out[c], 0)
        py = _along(out[c], 1)
        order = _order(px)
        cols = np.arange(xa, xb) + 0.5
        prior = _interp(cols, px[order], py[order])
        rows, contrast = _upper_edge(value, prior, xa, xb, y0, y1, boxes[2 + side], unit)
        # The contrast averaged over a few columns (the extent's noise).
        sm = np.empty(n)
        for i in range(n):
            sm[i] = contrast[max(i - 2, 0):min(i + 3, n)].mean()
        contrast = sm
        mid = int(np.argmin(np.abs(cols - 0.25 * out[c, :, 0].sum())))
        k = max(n // 6, 1)
        middle = _median(contrast[max(mid - k, 0):min(mid + k + 1, n)].copy())
        if middle <= _EDGE_FLOOR:
            continue
        level = _EDGE_KEEP * middle
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
        a0 = lo - min(max(lo - e0, 0.0), _BROW_REACH * unit)
        a1 = hi + min(max(e1 - hi, 0.0), _BROW_REACH * unit)
        curve = layout[c].copy()
        for j in range(4):
            curve[j, 0] = a0 + (layout[c, j, 0] - lo) * (a1 - a0) / max(hi - lo, 1e-6)
        xs = _along(curve, 0)
        inside = (xs >= cols[i0]) & (xs <= cols[i1])
        if inside.sum() < 4:
            continue
        r = _interp(xs, cols, rows + _BROW_DEPTH * unit) - _along(curve, 1)
        b = _line_fit(xs[inside], r[inside])[1]
        b = _brow_tilt(b)
        xm = xs.mean()
        a = _median((r - b * (xs - xm))[inside])
        a = min(max(a, -_BROW_SHIFT * unit), _BROW_SHIFT * unit)
        for j in range(4):
            out[c, j, 0] = curve[j, 0]
            out[c, j, 1] = curve[j, 1] + (a + b * (curve[j, 0] - xm))


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
    level = _quantile(lips[:n], 0.75) if n else skin
    thr = 0.5 * min(level, skin)
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
    opening = open_mask(opening, 3)
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
    if area[k] < 0.004 * unit * unit or xmax[k] - xmin[k] + 1 < 0.1 * unit:
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
def _mouth(C: np.ndarray, value: np.ndarray, layout: np.ndarray, offset: np.ndarray, out: np.ndarray,
           boxes: np.ndarray, params: np.ndarray, unit: float, reach: float) -> None:
    """Lips from the mouth blob (§3.2, Fig. 3): corners and outer lips from its outline, inner lips from the
    mouth opening inside it. ``offset`` (2,) moves the layout's lips (where the mouth was seen at acquisition);
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
    found, mask, _, _, _, cols, top, bottom = blob_kernel(sub, params, cx - x0, cy - y0, 0.3 * unit, 3)
    if not found:
        return
    xs = np.nonzero(cols)[0]
    if len(xs) < 4:
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
    skin = _median_of_boxes(value, boxes[5:7])
    itop, ibot = _opening(mask, cols, top, bottom, value[y0:y1, x0:x1], skin, unit)
    # Outer lips: the blob's outline; inner lips: the opening inside it (bounds: fraction of the unit).
    profiles = np.empty((4, len(top)), np.float32)
    for x in range(len(top)):
        profiles[0, x], profiles[1, x], profiles[2, x], profiles[3, x] = top[x], bottom[x], itop[x], ibot[x]
    for i in range(4):
        c = _LIPS[i]
        ok, y = _sample_profile(out[c], cols, profiles[i] + y0, x0)
        if ok:
            d = _mid_shift(out[c], y)
            for j in (1, 2):
                lo_b, hi_b = lay[c, j, 1] + _LIP_LOW[i] * unit, lay[c, j, 1] + _LIP_HIGH[i] * unit
                out[c, j, 1] = min(max(out[c, j, 1] + d, lo_b), hi_b)
    for j in (1, 2):
        out[ui, j, 1] = min(max(out[ui, j, 1], out[uo, j, 1]), out[lo, j, 1])
        out[li, j, 1] = min(max(out[li, j, 1], out[ui, j, 1]), out[lo, j, 1])
        # The lower lip keeps at least the layout's thickness (a pale lower lip leaves the blob short of it).
        out[lo, j, 1] = max(out[lo, j, 1], out[li, j, 1] + lay[lo, j, 1] - lay[li, j, 1])


def outline_features(C: np.ndarray, raw: np.ndarray, value: np.ndarray, layout: np.ndarray,
                     mouth_offset: np.ndarray, boxes: np.ndarray, blob_params: np.ndarray,
                     unit: float, mouth_reach: float = 0.12, parts: tuple[str, ...] = OUTLINE_PARTS) -> np.ndarray:
    """The layout moved onto each feature's blob, within plausible bounds (§3.2).

    Each part is one compiled kernel called from here (a few calls per frame cost microseconds; one kernel
    holding them all took numba 15 s longer to compile, since a caller re-optimises its callees' code).

    Parameters
    ----------
    C : (H, W) float32
        Feature intensity of the crop after the contrast enhancement, in [0, 1].
    raw : (H, W) float32
        Eq. 1's intensity before the contrast enhancement.
    value : (H, W) uint8
        HSV value V of the crop.
    layout : (C, 4, 2) float64
        The performer's neutral curves placed in the crop (crop pixels).
    mouth_offset : (2,) float64
        Crop pixels the mouth sits off the layout.
    boxes : (len(BOX_NAMES), 4) int64
        Feature rectangles, clipped to the crop.
    blob_params : (len(BLOB_KINDS), 5) float64
        :meth:`~facepuppet.capture.color.blobs.BlobConfig.as_array` per kind.
    unit : float
        Crop pixels per face unit.
    mouth_reach : float
        Farthest the mouth corners move from the layout's, face units (the profile's ``mouth_reach``).
    parts : tuple of str
        Which of :data:`OUTLINE_PARTS` to read (all by default); the others keep the layout's curves.

    Returns
    -------
    (C, 4, 2) float64
        The curves; a feature whose blob is missing keeps its layout curve (the nostrils always do).
    """
    unknown = set(parts) - set(OUTLINE_PARTS)
    if unknown:
        raise ValueError(f"unknown outline parts {sorted(unknown)}; known: {', '.join(OUTLINE_PARTS)}")
    out = layout.copy()
    if "eyes" in parts:
        _eyes(C, layout, out, boxes, blob_params[0], unit)
    if "brows" in parts:
        _brows(raw, layout, out, boxes, blob_params[1], unit)
        _brow_edges(value, layout, out, boxes, unit)
    if "mouth" in parts:
        _mouth(C, value, layout, mouth_offset, out, boxes, blob_params[2], unit, mouth_reach)
    return out


@nb.njit(**KERNEL)
def move_boxes(boxes: np.ndarray, moved: np.ndarray, mouth: int, shift: np.ndarray, mouth_offset: np.ndarray,
               w: int, h: int) -> np.ndarray:
    """Rectangles (N, 4) of a frame: the ``moved`` ones by ``shift`` (the mouth, row ``mouth``, also by
    ``mouth_offset``), each rounded to whole pixels, then clipped to the crop (w, h)."""
    out = boxes.copy()
    for k in range(len(boxes)):
        if not moved[k]:
            continue
        dx, dy = shift[0], shift[1]
        if k == mouth:
            dx += mouth_offset[0]
            dy += mouth_offset[1]
        ix, iy = np.int64(np.round(dx)), np.int64(np.round(dy))
        out[k, 0] += ix
        out[k, 2] += ix
        out[k, 1] += iy
        out[k, 3] += iy
    for k in range(len(boxes)):
        out[k, 0] = min(max(out[k, 0], 0), w)
        out[k, 2] = min(max(out[k, 2], 0), w)
        out[k, 1] = min(max(out[k, 1], 0), h)
        out[k, 3] = min(max(out[k, 3], 0), h)
    return out


@nb.njit(**KERNEL)
def eye_centres(C: np.ndarray, anchors: np.ndarray, half_w: int, half_h: int):
    """Eye centres (2, 2) in crop pixels by three mean-shift steps of C² around the expected anchors.

    Returns (ok, centres): ok is False when a window holds too little feature intensity.
    """
    h, w = C.shape
    out = np.zeros((2, 2))
    least = 0.01 * (2 * half_w + 1) * (2 * half_h + 1)
    for k in range(2):
        cx, cy = anchors[k, 0], anchors[k, 1]
        for _ in range(3):
            x0 = int(np.round(cx)) - half_w
            y0 = int(np.round(cy)) - half_h
            xa, ya = max(x0, 0), max(y0, 0)
            xb, yb = min(x0 + 2 * half_w + 1, w), min(y0 + 2 * half_h + 1, h)
            total = sx = sy = 0.0
            for y in range(ya, yb):
                for x in range(xa, xb):
                    v = float(C[y, x]) ** 2
                    total += v
                    sx += v * (x - xa)
                    sy += v * (y - ya)
            if total < least:
                return False, out
            cx, cy = sx / total + xa, sy / total + ya
        out[k, 0], out[k, 1] = cx, cy
    return True, out


# OpenCV's fixed-point reciprocals for 8-bit RGB -> HSV (12 fractional bits).
_S_DIV = np.r_[0, np.round(255.0 * 4096.0 / np.arange(1, 256))].astype(np.int64)
_H_DIV = np.r_[0, np.round(180.0 * 4096.0 / (6.0 * np.arange(1, 256)))].astype(np.int64)


@nb.njit(**INNER)
def _hsv(r: int, g: int, b: int):
    """OpenCV's 8-bit RGB -> HSV (hue code 0..179, saturation and value 0..255), same integer arithmetic."""
    v = max(r, g, b)
    diff = v - min(r, g, b)
    s = (diff * _S_DIV[v] + 2048) >> 12
    if diff == 0:
        return 0, s, v
    if v == r:
        h = g - b
    elif v == g:
        h = b - r + 2 * diff
    else:
        h = r - g + 4 * diff
    h = (h * _H_DIV[diff] + 2048) >> 12
    if h < 0:
        h += 180
    return h, s, v


@nb.njit(**INNER)
def _cr_cb(r: int, g: int, b: int):
    """OpenCV's 8-bit RGB -> YCrCb (same integer arithmetic): (Y, Cr, Cb)."""
    y = (r * 4899 + g * 9617 + b * 1868 + 8192) >> 14
    cr = min(max(((r - y) * 11682 + (128 << 14) + 8192) >> 14, 0), 255)
    cb = min(max(((b - y) * 9241 + (128 << 14) + 8192) >> 14, 0), 255)
    return y, cr, cb


@nb.njit(**KERNEL)
def skin_fraction(crop: np.ndarray, boxes: np.ndarray, table: np.ndarray) -> float:
    """Fraction of the pixels of the rectangles whose (Cr, Cb) the skin table accepts (Y in 35..250), as
    :func:`~facepuppet.capture.color.face.skin_probability`."""
    n = 0
    hit = 0
    for k in range(len(boxes)):
        x0, y0, x1, y1 = boxes[k]
        for yy in range(y0, y1):
            for xx in range(x0, x1):
                y, cr, cb = _cr_cb(np.int64(crop[yy, xx, 0]), np.int64(crop[yy, xx, 1]), np.int64(crop[yy, xx, 2]))
                n += 1
                if 35 <= y <= 250 and table[cr, cb]:
                    hit += 1
    return hit / n if n else 0.0


@nb.njit(**KERNEL)
def feature_intensity(crop: np.ndarray, weights: np.ndarray, hue_table: np.ndarray, min_saturation: float,
                      skin_boxes: np.ndarray, feature_boxes: np.ndarray):
    """Eq. 1 and the contrast C over a face crop in one pass (see :mod:`facepuppet.capture.color.transform`).

    I = w1 (V - G) / V + (w3 - w2) V + w2 + w4 G(H) with 8-bit V and G as in
    :func:`~facepuppet.capture.color.transform`; then C = smoothstep between the skin level (median of I
    over ``skin_boxes``) + 15 % and + 75 % of the way to the brightest I in ``feature_boxes``
    (a lone bright pixel is taken down to :data:`_SPECK` times the brightest 3 x 3 mean's level).

    Parameters
    ----------
    crop : (H, W, 3) uint8 RGB
    weights : (4,) float
    hue_table : (256,) float32
    min_saturation : float
        In [0, 1]; less saturated pixels get G = 0.
    skin_boxes, feature_boxes : (N, 4) int64
        Rectangles (x0, y0, x1, y1).

    Returns
    -------
    raw : (H, W) float32
        I of Eq. 1.
    C : (H, W) float32
        The contrast-enhanced intensity in [0, 1].
    value : (H, W) uint8
        HSV value V.
    """
    h, w = crop.shape[:2]
    w1, w2, w3, w4 = weights[0], weights[1], weights[2], weights[3]
    kv = (w3 - w2) / 255.0
    s_min = np.uint8(min_saturation * 255.0)
    raw = np.empty((h, w), np.float32)
    value = np.empty((h, w), np.uint8)
    use_hue = w4 != 0.0
    for y in range(h):
        for x in range(w):
            r, g, b = np.int64(crop[y, x, 0]), np.int64(crop[y, x, 1]), np.int64(crop[y, x, 2])
            v = max(r, g, b)
            i = w1 * (v - g) / max(v, 1) + kv * v + w2
            if use_hue:
                hue, s, _ = _hsv(r, g, b)
                if s >= s_min:
                    i += w4 * hue_table[hue]
            raw[y, x] = i
            value[y, x] = v
    low = _median_of_boxes(raw, skin_boxes)
    top, peak = _top_of_boxes(raw, feature_boxes, low)
    feat = low + min(top - low, _SPECK * (peak - low))
    lo = low + 0.15 * (feat - low)
    inv = 1.0 / max(0.6 * (feat - low), 1e-6)
    C = np.empty((h, w), np.float32)
    for y in range(h):
        for x in range(w):
            t = min(max((raw[y, x] - lo) * inv, 0.0), 1.0)
            C[y, x] = t * t * (3.0 - 2.0 * t)
    return raw, C, value
