"""Small numba helpers of the feature rules: curve samples, order statistics, interpolation, robust fits.

The rules (:mod:`.eyes`, :mod:`.brows`, :mod:`.mouth`) sample each curve at :data:`SAMPLES` points and move
its two middle control points by one robust number; these functions are compiled into the rules' kernels
(``INNER``, :mod:`facepuppet._util.jit`). numpy equivalents are written out where numba's own compile for
seconds per argument type (``np.partition``, ``np.interp``, ``np.argsort``).

Conventions: crop pixels, x right, y down; a curve is (4, 2) control points of a cubic Bezier.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from facepuppet._util.jit import INNER
from facepuppet.capture.curves import bernstein

__all__ = ["SAMPLES", "BASIS", "MID_WEIGHT", "CENTRAL_WEIGHT", "CENTRAL", "MIN_COLUMNS", "MID_SHARE", "along",
           "select_kth", "median", "quantile", "quantile_pair", "interp", "sort_order", "mid_y", "mid_shift",
           "sample_profile", "line_fit", "top_of_boxes", "median_of_boxes"]

#: Boundary samples per curve, K.
SAMPLES = 12
#: (K, 4) Bernstein basis of the samples, evenly spaced in the curve parameter.
BASIS = bernstein(np.linspace(0.0, 1.0, SAMPLES))
#: (K,) how far each sample moves when both middle control points move by one.
MID_WEIGHT = BASIS[:, 1] + BASIS[:, 2]
#: Least :data:`MID_WEIGHT` of a sample the middle control points' shift is read on (the central samples).
CENTRAL_WEIGHT = 0.6
#: Indices of the central samples.
CENTRAL = np.flatnonzero(MID_WEIGHT >= CENTRAL_WEIGHT)
#: Fewest rectangle columns holding a blob for its profile to be read (:func:`sample_profile`).
MIN_COLUMNS = 3
#: How far a curve's middle B(1/2) moves when both middle control points move by one: 3/8 + 3/8.
MID_SHARE = 0.75


@nb.njit(**INNER)
def mid_y(ctrl: np.ndarray) -> float:
    """y of a curve's middle, B(1/2), of its control points ``ctrl`` (4, 2)."""
    return 0.125 * (ctrl[0, 1] + ctrl[3, 1]) + 0.375 * (ctrl[1, 1] + ctrl[2, 1])


@nb.njit(**INNER)
def along(ctrl: np.ndarray, d: int) -> np.ndarray:
    """Coordinate ``d`` of the curve's K samples, ``B @ ctrl[:, d]``."""
    out = np.zeros(SAMPLES)
    for k in range(SAMPLES):
        for j in range(4):
            out[k] += BASIS[k, j] * ctrl[j, d]
    return out


@nb.njit(**INNER)
def _select_range(d: np.ndarray, lo: int, hi: int, k: int) -> None:
    """Arrange ``d[lo:hi + 1]`` in place so that ``d[k]`` is its value of rank k (as :func:`select_kth` does for a
    whole array: smaller or equal values before it, greater or equal after it)."""
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


@nb.njit(**INNER)
def select_kth(a: np.ndarray, k: int) -> np.ndarray:
    """A copy of the 1-D array ``a`` arranged so that ``d[k]`` is its k-th smallest value, ``d[:k]`` the k
    smallest and ``d[k + 1:]`` the rest (Hoare's selection; what ``np.partition(a, k)`` gives, written out
    because numba's compiles for seconds, each type again)."""
    d = a.copy()
    _select_range(d, 0, len(d) - 1, k)
    return d


@nb.njit(**INNER)
def median(a: np.ndarray) -> float:
    """Median of a non-empty 1-D array: the mean of its two middle order statistics, found by selection
    (no full sort; the same value as ``0.5 * (d[(n - 1) // 2] + d[n // 2])`` of the sorted data ``d``)."""
    n = len(a)
    k = n // 2
    d = select_kth(a, k)                           # d[k], and d[:k] the k smallest
    hi = d[k]
    lo = d[:k].max() if n % 2 == 0 else hi
    return 0.5 * (lo + hi)


@nb.njit(**INNER)
def quantile(a: np.ndarray, q: float) -> float:
    """Quantile ``q`` in [0, 1] of a non-empty 1-D array, interpolated linearly between its two neighbouring
    order statistics (numpy's default rule), which are found by selection (no full sort)."""
    n = len(a)
    pos = q * (n - 1)
    i = min(int(pos), n - 2) if n > 1 else 0
    j = min(i + 1, n - 1)
    d = select_kth(a, j)                           # d[j], and d[:j] the j smallest
    hi = d[j]
    lo = d[:j].max() if j > i else hi
    return lo + (pos - i) * (hi - lo)


@nb.njit(**INNER)
def quantile_pair(a: np.ndarray, q_lo: float, q_hi: float):
    """``(quantile(a, q_lo), quantile(a, q_hi))`` of a non-empty 1-D array for ``q_lo <= q_hi`` (the same values,
    :func:`quantile`): the order statistics are selected on one float64 copy, the upper ones among the values
    above the lower ones."""
    n = len(a)
    d = np.empty(n)
    for t in range(n):
        d[t] = a[t]
    pos1, pos2 = q_lo * (n - 1), q_hi * (n - 1)
    i1 = min(int(pos1), n - 2) if n > 1 else 0
    i2 = min(int(pos2), n - 2) if n > 1 else 0
    j1, j2 = min(i1 + 1, n - 1), min(i2 + 1, n - 1)
    _select_range(d, 0, n - 1, j1)                 # d[j1] of its rank, the j1 smallest before it
    hi1 = d[j1]
    lo1 = d[:j1].max() if j1 > i1 else hi1
    if j2 == j1:
        hi2, lo2 = hi1, lo1
    else:
        _select_range(d, j1 + 1, n - 1, j2)        # among the values above d[j1]
        hi2 = d[j2]
        lo2 = d[j1 + 1:j2].max() if j2 - 1 > j1 else d[j1]
    return lo1 + (pos1 - i1) * (hi1 - lo1), lo2 + (pos2 - i2) * (hi2 - lo2)


@nb.njit(**INNER)
def interp(x: np.ndarray, xp: np.ndarray, fp: np.ndarray) -> np.ndarray:
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
def sort_order(a: np.ndarray) -> np.ndarray:
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
def mid_shift(ctrl: np.ndarray, y: np.ndarray) -> float:
    """The common vertical shift of the middle control points that best moves the curve onto the profile ``y``
    (median over the central samples)."""
    base = along(ctrl, 1)
    d = np.empty(len(CENTRAL))
    for i in range(len(CENTRAL)):
        k = CENTRAL[i]
        d[i] = (y[k] - base[k]) / MID_WEIGHT[k]
    return median(d)


@nb.njit(**INNER)
def sample_profile(ctrl: np.ndarray, cols: np.ndarray, prof: np.ndarray, x0: int):
    """A blob profile (per rectangle column, plus ``y0``) read at the x of the curve's K samples.

    Returns (ok, y): ok is False when fewer than three columns hold the blob.
    """
    xs = np.nonzero(cols)[0]
    if len(xs) < MIN_COLUMNS:
        return False, np.zeros(SAMPLES)
    xf = xs.astype(np.float64)
    pf = np.empty(len(xs))
    for i in range(len(xs)):
        pf[i] = prof[xs[i]]
    x_samples = along(ctrl, 0) - x0 - 0.5
    return True, interp(x_samples, xf, pf)


@nb.njit(**INNER)
def line_fit(x: np.ndarray, y: np.ndarray):
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
    b = median(slopes[:k]) if k else 0.0
    return median(y - b * (x - xm)), b, xm


@nb.njit(**INNER)
def top_of_boxes(img: np.ndarray, boxes: np.ndarray, floor: float):
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
def median_of_boxes(img: np.ndarray, boxes: np.ndarray) -> float:
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
    return median(vals) if n else 0.0
