"""Blob construction (paper §3.2): seeded growing above a threshold, morphological cleaning, largest region.

Conventions: images (H, W), rows are y (down), columns x (right).

The work is compiled with numba (:func:`blob_kernel`): the tracker grows six blobs per frame in rectangles of
a few hundred pixels, where the cost of calling out to a library for each step outweighs the step itself.
Morphology uses OpenCV's elliptic structuring elements and border rules (pixels outside the image neither
dilate nor erode), labelling is 8-connected.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from facepuppet._util.jit import INNER, KERNEL

__all__ = ["BlobConfig", "Blob", "grow_blob", "column_profile", "blob_kernel", "ellipse_kernel"]



@dataclass(frozen=True)
class BlobConfig:
    """Options of blob growing.

    Attributes
    ----------
    seed_level : float
        Intensity above which a pixel may seed a blob.
    grow_level : float
        Intensity above which a pixel may join a blob (``grow_level <= seed_level``).
    radius : int
        Growing reaches pixels within this many pixels of the blob, across gaps (0: touching pixels only).
    close : int
        Size of the closing (dilation then erosion) that joins nearby parts and fills small gaps.
    open : int
        Size of the opening (erosion then dilation) that removes thin protrusions (0: none).
    """

    seed_level: float = 0.7
    grow_level: float = 0.4
    radius: int = 1
    close: int = 3
    open: int = 0

    def as_array(self) -> np.ndarray:
        """(seed_level, grow_level, radius, close, open) as a float64 array, the form :func:`blob_kernel` takes."""
        return np.array([self.seed_level, self.grow_level, self.radius, self.close, self.open], dtype=np.float64)


@dataclass(frozen=True)
class Blob:
    """The largest seeded region of a rectangle.

    Attributes
    ----------
    mask : (H, W) bool
    area : int
    box : (4,) int
        x0, y0, x1, y1 (inclusive-exclusive) in the rectangle's pixels.
    centroid : (2,) float
        x, y in the rectangle's pixels.
    """

    mask: np.ndarray
    area: int
    box: np.ndarray
    centroid: np.ndarray


@nb.njit(**INNER)
def ellipse_kernel(size: int) -> np.ndarray:
    """OpenCV's elliptic structuring element of ``size`` x ``size`` (``cv2.MORPH_ELLIPSE``), (size, size) uint8."""
    k = np.zeros((size, size), np.uint8)
    r = size // 2
    c = size // 2
    inv_r2 = 1.0 / (r * r) if r > 0 else 0.0
    for i in range(size):
        dy = i - r
        if abs(dy) <= r:
            dx = int(np.round(c * np.sqrt((r * r - dy * dy) * inv_r2)))
            j1 = max(c - dx, 0)
            j2 = min(c + dx + 1, size)
            k[i, j1:j2] = 1
    return k


@nb.njit(**INNER)
def _morph(m: np.ndarray, kernel: np.ndarray, dilate: bool) -> np.ndarray:
    """Binary dilation (or erosion) of ``m`` by a centred kernel; pixels outside the image are ignored."""
    h, w = m.shape
    kh, kw = kernel.shape
    ay, ax = kh // 2, kw // 2
    # The mask in a frame of the neutral value (0 for dilation, 1 for erosion): no bounds checks below, and
    # the innermost loop runs along a row with a fixed offset (vectorised).
    neutral = 0 if dilate else 1
    pad = np.full((h + kh, w + kw), neutral, np.uint8)
    for y in range(h):
        for x in range(w):
            pad[y + ay, x + ax] = 1 if m[y, x] else 0
    out = np.full((h, w), neutral, np.uint8)
    for i in range(kh):
        for j in range(kw):
            if kernel[i, j] == 0:
                continue
            for y in range(h):
                row = pad[y + i]
                o = out[y]
                if dilate:
                    for x in range(w):
                        o[x] |= row[x + j]
                else:
                    for x in range(w):
                        o[x] &= row[x + j]
    return out


@nb.njit(**INNER)
def _cross(m: np.ndarray, dilate: bool) -> np.ndarray:
    """:func:`_morph` by the 3 x 3 elliptic element, a cross: each pixel with its four neighbours (those inside
    the image), without the padded copy (the blobs' closings and the mouth opening's opening, every frame)."""
    h, w = m.shape
    out = np.empty((h, w), np.uint8)
    for y in range(h):
        for x in range(w):
            v = m[y, x] != 0
            for yy, xx in ((y - 1, x), (y + 1, x), (y, x - 1), (y, x + 1)):
                if 0 <= yy < h and 0 <= xx < w:
                    n = m[yy, xx] != 0
                    v = (v or n) if dilate else (v and n)
            out[y, x] = 1 if v else 0
    return out


@nb.njit(**INNER)
def close_mask(m: np.ndarray, size: int) -> np.ndarray:
    """Closing (dilation then erosion) by the elliptic element of ``size``; ``size <= 1`` returns ``m``."""
    if size <= 1:
        return m
    if size == 3:
        return _cross(_cross(m, True), False)
    k = ellipse_kernel(size)
    return _morph(_morph(m, k, True), k, False)


@nb.njit(**INNER)
def open_mask(m: np.ndarray, size: int) -> np.ndarray:
    """Opening (erosion then dilation) by the elliptic element of ``size``; ``size <= 1`` returns ``m``."""
    if size <= 1:
        return m
    if size == 3:
        return _cross(_cross(m, False), True)
    k = ellipse_kernel(size)
    return _morph(_morph(m, k, False), k, True)


@nb.njit(**INNER)
def _root(parent: np.ndarray, k: int) -> int:
    """The representative of provisional label ``k`` (path halving)."""
    while parent[k] != k:
        parent[k] = parent[parent[k]]
        k = parent[k]
    return k


@nb.njit(**INNER)
def label8(m: np.ndarray) -> tuple[np.ndarray, int]:
    """8-connected components of a binary mask: labels (H, W) int32 (0 background, 1.. in raster order), count.

    Two raster passes: provisional labels joined with those of the neighbours already seen (left, and the
    three above), then each part numbered by the order of its first pixel, as a flood fill in raster order
    would number it.
    """
    h, w = m.shape
    labels = np.zeros((h, w), np.int32)
    parent = np.empty(h * w + 1, np.int32)
    n = 1
    for y in range(h):
        for x in range(w):
            if m[y, x] == 0:
                continue
            k = 0
            for yy, xx in ((y, x - 1), (y - 1, x - 1), (y - 1, x), (y - 1, x + 1)):
                if yy < 0 or xx < 0 or xx >= w:
                    continue
                seen = labels[yy, xx]
                if seen == 0:
                    continue
                r = _root(parent, seen)
                if k == 0:
                    k = r
                elif r != k:
                    lo, hi = min(r, k), max(r, k)
                    parent[hi] = lo
                    k = lo
            if k == 0:
                parent[n] = n
                k = n
                n += 1
            labels[y, x] = k
    number = np.zeros(n, np.int32)
    count = 1
    for y in range(h):
        for x in range(w):
            k = labels[y, x]
            if k:
                r = _root(parent, k)
                if number[r] == 0:
                    number[r] = count
                    count += 1
                labels[y, x] = number[r]
    return labels, count


@nb.njit(**KERNEL)
def blob_kernel(intensity: np.ndarray, params: np.ndarray, near_x: float, near_y: float, near_r: float,
                min_area: int):
    """The blob of :func:`grow_blob` and its column profile, in one compiled call.

    Parameters
    ----------
    intensity : (H, W) float
    params : (5,) float64
        :meth:`BlobConfig.as_array`.
    near_x, near_y, near_r : float
        Preferred place (``near_r <= 0``: none), as in :func:`grow_blob`.
    min_area : int

    Returns
    -------
    found : bool
    mask : (H, W) uint8
    area : int
    box : (4,) int64
    centroid : (2,) float64
    cols : (W,) bool
    top, bottom : (W,) float32
        As :func:`column_profile` of ``mask``.
    """
    h, w = intensity.shape
    seed_level, grow_level = params[0], params[1]
    radius, close, opn = int(params[2]), int(params[3]), int(params[4])
    m = np.zeros((h, w), np.uint8)
    for y in range(h):
        for x in range(w):
            if intensity[y, x] > grow_level:
                m[y, x] = 1
    if radius > 0:
        m = close_mask(m, 2 * radius + 1)
    if close != 2 * radius + 1:              # a closing is idempotent: the same one twice changes nothing
        m = close_mask(m, close)
    m = open_mask(m, opn)
    labels, n = label8(m)
    area = np.zeros(n, np.int64)
    sx = np.zeros(n)
    sy = np.zeros(n)
    seeded = np.zeros(n, np.bool_)
    box = np.empty((n, 4), np.int64)
    box[:, 0] = w
    box[:, 1] = h
    box[:, 2] = 0
    box[:, 3] = 0
    for y in range(h):
        for x in range(w):
            k = labels[y, x]
            if k == 0:
                continue
            area[k] += 1
            sx[k] += x
            sy[k] += y
            box[k, 0] = min(box[k, 0], x)
            box[k, 1] = min(box[k, 1], y)
            box[k, 2] = max(box[k, 2], x + 1)
            box[k, 3] = max(box[k, 3], y + 1)
            if intensity[y, x] > seed_level:
                seeded[k] = True
    best = 0
    best_score = -1.0
    for k in range(1, n):
        if not seeded[k] or area[k] < min_area:
            continue
        score = float(area[k])
        if near_r > 0:
            dx = sx[k] / area[k] - near_x
            dy = sy[k] / area[k] - near_y
            score /= 1.0 + (dx * dx + dy * dy) / (near_r * near_r)
        if score > best_score:
            best, best_score = k, score
    mask = np.zeros((h, w), np.uint8)
    cols = np.zeros(w, np.bool_)
    top = np.zeros(w, np.float32)
    bottom = np.full(w, np.float32(h))
    centroid = np.zeros(2)
    if best == 0:
        return False, mask, 0, box[0], centroid, cols, top, bottom
    for y in range(h):
        for x in range(w):
            if labels[y, x] == best:
                mask[y, x] = 1
                if not cols[x]:
                    cols[x] = True
                    top[x] = y
                bottom[x] = y + 1
    centroid[0] = sx[best] / area[best]
    centroid[1] = sy[best] / area[best]
    return True, mask, area[best], box[best].copy(), centroid, cols, top, bottom


def grow_blob(intensity: np.ndarray, config: BlobConfig = BlobConfig(), min_area: int = 3,
              near: tuple[float, float, float] | None = None) -> Blob | None:
    """Grow blobs from seeds and keep the largest (§3.2).

    Pixels above ``seed_level`` are seeds; a blob is every pixel above ``grow_level`` reachable from a seed
    through such pixels, where steps of up to ``radius`` pixels may cross gaps. This is the connected-component
    form of the paper's seed-by-seed growing (same result, one pass): components of the grow mask, closed by
    the radius, that contain a seed. Closing and opening then join and clean them, and the largest region wins.

    Parameters
    ----------
    intensity : (H, W) float32
        Feature intensity (high on the feature) of one rectangle.
    config : BlobConfig
    min_area : int
        Smaller regions do not count.
    near : (x, y, r), optional
        Prefer regions near (x, y) (rectangle pixels): each region's area is weighted by ``1 / (1 + (d / r)²)``
        with ``d`` the distance of its centroid, so a large region far from where the feature is expected
        (a shadow at the rectangle's edge) loses to the feature.

    Returns
    -------
    Blob or None
        None when no seeded region of ``min_area`` pixels exists.
    """
    img = np.asarray(intensity)
    if img.ndim != 2:
        raise ValueError(f"intensity must be a 2-D image, got shape {img.shape}")
    nx, ny, nr = (0.0, 0.0, 0.0) if near is None else (float(near[0]), float(near[1]), max(float(near[2]), 1e-6))
    found, mask, area, box, centroid, *_ = blob_kernel(img, config.as_array(), nx, ny, nr, int(min_area))
    if not found:
        return None
    return Blob(mask.view(np.bool_), int(area), box, centroid)


def column_profile(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Top and bottom row of a mask in each column.

    Parameters
    ----------
    mask : (H, W) bool

    Returns
    -------
    cols : (W,) bool
        Columns that hold any mask pixel.
    top, bottom : (W,) float
        First and last mask row per column (the pixel edges: top row, bottom row + 1); undefined where
        ``cols`` is False.
    """
    cols = mask.any(axis=0)
    top = mask.argmax(axis=0).astype(np.float32)
    bottom = (mask.shape[0] - mask[::-1].argmax(axis=0)).astype(np.float32)
    return cols, top, bottom
