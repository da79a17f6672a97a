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


def glare_mask(crop: np.ndarray, cheeks: np.ndarray, eyes: np.ndarray, unit: float) -> np.ndarray | None:
    """The reflection's pixels (H, W) uint8 (255) around the eyes of a face crop, or None where there is none.

    ``crop``: (H, W, 3) uint8 RGB; ``cheeks``: (K, 4) int rectangles of skin (the skin's reference light and
    colour); ``eyes``: (2, 4) int the eye rectangles (the part searched spans them, :data:`GLARE` ``below``
    lower); ``unit``: crop pixels per face unit.
    """
    h, w = crop.shape[:2]
    ycc = cv2.cvtColor(crop, cv2.COLOR_RGB2YCrCb)
    skin = np.concatenate([ycc[max(y0, 0):y1, max(x0, 0):x1].reshape(-1, 3) for x0, y0, x1, y1 in cheeks])
    if len(skin) == 0:
        return None
    ys, cr, cb = np.median(skin.astype(np.float32), axis=0) - np.array([0.0, 128.0, 128.0], np.float32)
    s2 = float(cr * cr + cb * cb)
    if s2 < 1.0:
        return None                         # no skin chroma to tell a colourless patch from
    x0, y0 = max(int(eyes[:, 0].min()), 0), max(int(eyes[:, 1].min()), 0)
    x1, y1 = min(int(eyes[:, 2].max()), w), min(int(eyes[:, 3].max() + _value("below") * unit), h)
    if x1 <= x0 or y1 <= y0:
        return None
    part = ycc[y0:y1, x0:x1].astype(np.float32)
    proj = (part[..., 1] - 128.0) * cr + (part[..., 2] - 128.0) * cb
    bright = (part[..., 0] > (1.0 + _value("lift")) * ys) & (proj < _value("chroma") * s2)
    if not bright.any():
        return None
    n, labels, stats, _ = cv2.connectedComponentsWithStats(bright.astype(np.uint8), connectivity=8)
    big = (stats[:, cv2.CC_STAT_HEIGHT] > _value("tall") * unit) | (stats[:, cv2.CC_STAT_WIDTH] > _value("wide") * unit)
    big[0] = False
    if not big[1:].any():
        return None
    mask = np.zeros((h, w), np.uint8)
    mask[y0:y1, x0:x1] = np.where(big[labels], 255, 0).astype(np.uint8)
    g = max(int(round(_value("grow") * unit)), 1)
    return cv2.dilate(mask, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * g + 1, 2 * g + 1)))


def without_glare(crop: np.ndarray, cheeks: np.ndarray, eyes: np.ndarray, unit: float) -> np.ndarray:
    """The face crop (H, W, 3) uint8 with a reflection around the eyes (:func:`glare_mask`) filled in from its
    surroundings; the crop itself where there is none."""
    mask = glare_mask(crop, cheeks, eyes, unit)
    if mask is None:
        return crop
    return cv2.inpaint(crop, mask, max(_value("radius") * unit, 1.0), cv2.INPAINT_TELEA)
