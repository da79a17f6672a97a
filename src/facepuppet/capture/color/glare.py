"""Reflections on glasses treated as missing evidence: found around the eyes of a face crop and filled in from
what surrounds them.

A reflection on a lens (a lamp, a window) is a bright patch of little colour over the eye: to Eq. 1 it looks
like neither skin nor a dark feature, and it hides the lids and part of the eye's blob. Left as it is, the eye
search and the lids' rule read its edge as the eye's. Its pixels are found by their light and colour against the
cheeks' skin (brighter than the skin, and less coloured), kept where they form a patch taller or wider than an
eye's opening can be (the white of the eye is bright and colourless too, but lies within the opening), and
filled in from the pixels around them (OpenCV's inpainting, Telea's method): the crop then shows, where the
reflection was, what its surroundings suggest and nothing the reflection itself drew.

Conventions: RGB uint8 face crops (H, W, 3); rectangles (x0, y0, x1, y1) crop pixels; ``unit`` crop pixels per
face unit; luma and chroma as in OpenCV's YCrCb (chroma centred on 128).
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["GLARE", "glare_mask", "without_glare"]

#: The reflection's look and extent: name -> (value, unit, meaning).
GLARE = {
    "lift": (0.12, "skin luma", "how much brighter than the cheeks' skin a reflection's pixel is, at least"),
    "chroma": (0.5, "skin chroma", "most chroma along the skin's (Cr, Cb) direction, of the skin's"),
    "tall": (0.3, "face units", "a bright colourless patch taller than this is a reflection (an opening is not)"),
    "wide": (0.65, "face units", "a bright colourless patch wider than this is a reflection (an opening is not)"),
    "grow": (0.04, "face units", "the reflection's mask grown by this (its blurred edge)"),
    "radius": (0.08, "face units", "the inpainting's reach"),
    "below": (0.2, "face units", "rows searched below the eye rectangles (a lens reaches below the eye)"),
}


def _value(name: str) -> float:
    return float(GLARE[name][0])


_LIFT, _CHROMA, _TALL, _WIDE = (_value(k) for k in ("lift", "chroma", "tall", "wide"))


def glare_mask(crop: np.ndarray, cheeks: np.ndarray, eyes: np.ndarray, unit: float) -> np.ndarray | None:
    """The reflection's pixels (H, W) uint8 (255) around the eyes of a face crop, or None where there is none.

    ``crop``: (H, W, 3) uint8 RGB; ``cheeks``: (K, 4) int rectangles of skin (the skin's reference light and
    colour: their mean); ``eyes``: (2, 4) int the eye rectangles (the part searched spans them, :data:`GLARE`
    ``below`` lower); ``unit``: crop pixels per face unit. The patches' sizes are read on a half-resolution mask.
    """
    h, w = crop.shape[:2]
    (ex0, ey0, ex1, ey1), (fx0, fy0, fx1, fy1) = np.asarray(eyes).tolist()
    x0, y0 = max(min(ex0, fx0), 0), max(min(ey0, fy0), 0)
    x1, y1 = min(max(ex1, fx1), w), min(int(max(ey1, fy1) + _value("below") * unit), h)
    if x1 - x0 < 2 or y1 - y0 < 2:
        return None
    n, total = 0, np.zeros(3)
    for cx0, cy0, cx1, cy1 in np.asarray(cheeks).tolist():
        box = crop[max(cy0, 0):cy1, max(cx0, 0):cx1]
        if box.size:
            total += np.asarray(cv2.mean(cv2.cvtColor(box, cv2.COLOR_RGB2YCrCb))[:3]) * (box.size // 3)
            n += box.size // 3
    if n == 0:
        return None
    ys, cr, cb = (total / n - (0.0, 128.0, 128.0)).tolist()
    s2 = cr * cr + cb * cb
    if s2 < 1.0:
        return None                         # no skin chroma to tell a colourless patch from
    part = cv2.cvtColor(np.ascontiguousarray(crop[y0:y1, x0:x1]), cv2.COLOR_RGB2YCrCb)
    # The pixels brighter than the skin, then those of them less coloured than it: (Cr, Cb) along the skin's
    # direction under the reflection's most.
    least = min(_TALL, _WIDE) * unit
    lit = np.flatnonzero(cv2.compare(cv2.extractChannel(part, 0), (1.0 + _LIFT) * ys, cv2.CMP_GT))
    if lit.size < least:
        return None
    px = part.reshape(-1, 3)[lit].astype(np.float32)
    lit = lit[(px[:, 1] - 128.0) * cr + (px[:, 2] - 128.0) * cb < _CHROMA * s2]
    if lit.size < least:
        return None
    bright = np.zeros(part.shape[:2], bool)
    bright.flat[lit] = True
    half = bright[::2, ::2].astype(np.uint8)
    _, labels, stats, _ = cv2.connectedComponentsWithStats(half, connectivity=8)
    big = (stats[:, cv2.CC_STAT_HEIGHT] > 0.5 * _TALL * unit) | (stats[:, cv2.CC_STAT_WIDTH] > 0.5 * _WIDE * unit)
    big[0] = False
    if not big[1:].any():
        return None
    keep = np.repeat(np.repeat(big[labels], 2, axis=0), 2, axis=1)[:y1 - y0, :x1 - x0] & bright
    mask = np.zeros((h, w), np.uint8)
    mask[y0:y1, x0:x1][keep] = 255
    g = max(int(round(_value("grow") * unit)), 1)
    return cv2.dilate(mask, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * g + 1, 2 * g + 1)))


def without_glare(crop: np.ndarray, cheeks: np.ndarray, eyes: np.ndarray, unit: float) -> np.ndarray:
    """The face crop (H, W, 3) uint8 with a reflection around the eyes (:func:`glare_mask`) filled in from its
    surroundings; the crop itself where there is none."""
    mask = glare_mask(crop, cheeks, eyes, unit)
    if mask is None:
        return crop
    return cv2.inpaint(crop, mask, max(_value("radius") * unit, 1.0), cv2.INPAINT_TELEA)
