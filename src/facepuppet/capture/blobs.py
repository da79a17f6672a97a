"""Blob construction (paper §3.2): seeded growing above a threshold, morphological cleaning, largest region.

Conventions: images (H, W), rows are y (down), columns x (right).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

__all__ = ["BlobConfig", "Blob", "grow_blob", "column_profile"]


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


_KERNELS: dict[int, np.ndarray] = {}


def _kernel(size: int) -> np.ndarray:
    k = _KERNELS.get(size)
    if k is None:
        k = _KERNELS[size] = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size))
    return k


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
    grow = (intensity > config.grow_level).astype(np.uint8)
    if config.radius > 0:
        grow = cv2.morphologyEx(grow, cv2.MORPH_CLOSE, _kernel(2 * config.radius + 1))
    if config.close > 1:
        grow = cv2.morphologyEx(grow, cv2.MORPH_CLOSE, _kernel(config.close))
    if config.open > 1:
        grow = cv2.morphologyEx(grow, cv2.MORPH_OPEN, _kernel(config.open))
    n, labels, stats, cents = cv2.connectedComponentsWithStats(grow, connectivity=8)
    if n < 2:
        return None
    seeded = np.zeros(n, dtype=bool)
    seeded[labels[intensity > config.seed_level]] = True
    seeded[0] = False
    areas = np.where(seeded, stats[:, cv2.CC_STAT_AREA], 0)
    if near is None:
        k = int(np.argmax(areas))
    else:
        d2 = ((cents - np.asarray(near[:2])) ** 2).sum(axis=1) / max(near[2], 1e-6) ** 2
        k = int(np.argmax(np.where(areas >= min_area, areas / (1.0 + d2), -1.0)))
    if areas[k] < min_area:
        return None
    x, y, w, h = stats[k, :4]
    return Blob(labels == k, int(areas[k]), np.array([x, y, x + w, y + h]), cents[k].astype(float))


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
