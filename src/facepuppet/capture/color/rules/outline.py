"""The feature rules of §3.2 applied to a face crop: which rectangles they read and in which order.

In a face crop whose contrast C (Eq. 1 and the contrast enhancement) is known, each feature's rectangle gets a
blob (:func:`~facepuppet.capture.color.blobs.blob_kernel`) and the layout's curves are moved onto the blob
(:mod:`.eyes`, :mod:`.brows`, :mod:`.mouth`). Each curve keeps its shape and moves by one robust number (the
median shift of its middle control points over the central samples), so a noisy column cannot bend it.

Conventions: crop pixels, x right, y down; curves (C, 4, 2) control points in
:data:`~facepuppet.capture.curves.CURVE_NAMES` order; rectangles (x0, y0, x1, y1) inclusive-exclusive, in the
order of :data:`BOX_NAMES`.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from facepuppet._util.jit import KERNEL
from facepuppet.capture.color.blobs import BlobConfig
from facepuppet.capture.color.rules.brows import brow_edges, brow_outlines
from facepuppet.capture.color.rules.eyes import eye_outlines
from facepuppet.capture.color.rules.mouth import mouth_outlines

__all__ = ["BOX_NAMES", "BLOB_KINDS", "BLOB_CONFIGS", "BLOB_PARAMS", "OUTLINE_PARTS", "outline_features", "move_boxes"]

#: Rectangles :func:`outline_features` reads, in the order of its ``boxes`` argument.
BOX_NAMES = ("eye_right", "eye_left", "brow_right", "brow_left", "mouth", "cheek_left", "cheek_right")
#: Blob options, in the order of its ``blob_params`` rows.
BLOB_KINDS = ("eye", "brow", "mouth")
#: Blob options per kind of rectangle (:class:`~facepuppet.capture.color.blobs.BlobConfig`).
BLOB_CONFIGS = {
    "brow": BlobConfig(seed_level=0.7, grow_level=0.45, radius=1, close=3),
    "eye": BlobConfig(seed_level=0.7, grow_level=0.35, radius=1, close=3),
    "mouth": BlobConfig(seed_level=0.6, grow_level=0.3, radius=1, close=3),
}
#: (len(BLOB_KINDS), 5) float64: :data:`BLOB_CONFIGS` as the ``blob_params`` rows :func:`outline_features` takes.
BLOB_PARAMS = np.array([BLOB_CONFIGS[k].as_array() for k in BLOB_KINDS])
#: The parts :func:`outline_features` reads, each one compiled kernel.
OUTLINE_PARTS = ("eyes", "brows", "mouth")


def outline_features(C: np.ndarray, *, raw: np.ndarray, value: np.ndarray, layout: np.ndarray, boxes: np.ndarray,
                     blob_params: np.ndarray, unit: float, mouth_reach: float, mouth_offset: np.ndarray | None = None,
                     parts: tuple[str, ...] = OUTLINE_PARTS, rgb: np.ndarray | None = None) -> np.ndarray:
    """The layout moved onto each feature's blob, within plausible bounds (§3.2).

    Each part is one compiled kernel called from here (:mod:`.eyes`, :mod:`.brows`, :mod:`.mouth`): numba
    re-optimises a caller with its callees' code, so one kernel holding them all would compile far longer.

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
    boxes : (len(BOX_NAMES), 4) int64
        Feature rectangles, clipped to the crop.
    blob_params : (len(BLOB_KINDS), 5) float64
        :meth:`~facepuppet.capture.color.blobs.BlobConfig.as_array` per kind.
    unit : float
        Crop pixels per face unit.
    mouth_reach : float
        Farthest the mouth corners move from the layout's, face units (the profile's ``mouth_reach``).
    mouth_offset : (2,) float64, optional
        Crop pixels the mouth sits off the layout (default none).
    parts : tuple of str
        Which of :data:`OUTLINE_PARTS` to read (all by default); the others keep the layout's curves.
    rgb : (H, W, 3) uint8, optional
        The crop itself (the mouth tells teeth by their low saturation); without it, no teeth are taken.

    Returns
    -------
    (C, 4, 2) float64
        The curves; a feature whose blob is missing keeps its layout curve (the nostrils always do).
    """
    unknown = set(parts) - set(OUTLINE_PARTS)
    if unknown:
        raise ValueError(f"unknown outline parts {sorted(unknown)}; known: {', '.join(OUTLINE_PARTS)}")
    out = layout.copy()
    if mouth_offset is None:
        mouth_offset = np.zeros(2)
    if "eyes" in parts:
        eye_outlines(C, layout, out, boxes, blob_params[0], unit)
    if "brows" in parts:
        brow_outlines(raw, layout, out, boxes, blob_params[1], unit)
        brow_edges(value, layout, out, boxes, unit)
    if "mouth" in parts:
        if rgb is None:
            rgb = np.zeros(C.shape + (3,), np.uint8)
        mouth_outlines(C, value, rgb, layout, mouth_offset, out, boxes, blob_params[2], unit, mouth_reach)
    return out


@nb.njit(**KERNEL)
def move_boxes(boxes: np.ndarray, moved: np.ndarray, mouth: int, shift: np.ndarray, mouth_offset: np.ndarray,
               scale: float, centre: np.ndarray, w: int, h: int) -> np.ndarray:
    """Rectangles (N, 4) of a frame: the ``moved`` ones by ``shift`` (the mouth, row ``mouth``, also by
    ``mouth_offset``, and enlarged by ``scale`` if above 1 about ``centre`` (2,), the eyes' midpoint: an open
    jaw reaches as far in face units on a face the eyes found larger; a smaller face keeps the box's room to
    spare), each rounded to whole pixels, then clipped to the crop (w, h)."""
    out = boxes.copy()
    scale = max(scale, 1.0)
    for k in range(len(boxes)):
        if not moved[k]:
            continue
        dx, dy = shift[0], shift[1]
        if k == mouth:
            dx += mouth_offset[0]
            dy += mouth_offset[1]
            for j in range(2):                  # x, then y
                d = dx if j == 0 else dy
                for i in (j, j + 2):
                    out[k, i] = np.int64(np.round(centre[j] + scale * (boxes[k, i] - centre[j]) + d))
            continue
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
