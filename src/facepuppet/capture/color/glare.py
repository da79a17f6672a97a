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
import numba as nb
import numpy as np

from facepuppet._util.jit import INNER, KERNEL
from facepuppet.capture.color.transform import ycrcb_u8
from facepuppet.capture.color.veil import without_veil

__all__ = ["GLARE", "glare_mask", "glare_pixels", "without_glare"]

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


#: Pixels beyond the inpainting's reach around the mask that :func:`without_glare` hands it (its fast marching
#: steps one pixel past the reach, and the extended image's border is one pixel).
INPAINT_MARGIN = 4


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
    found, mask = glare_pixels(crop, np.ascontiguousarray(cheeks, dtype=np.int64), x0, y0, x1, y1, float(unit))
    if not found:
        return None
    g = max(int(round(_value("grow") * unit)), 1)
    return cv2.dilate(mask, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * g + 1, 2 * g + 1)))


@nb.njit(**INNER)
def _slice_end(stop: int, n: int) -> int:
    """Where Python's slice ``[start:stop]`` of a length ``n`` ends (a negative ``stop`` counts from the end)."""
    return min(stop if stop >= 0 else max(n + stop, 0), n)


@nb.njit(**KERNEL)
def glare_pixels(crop: np.ndarray, cheeks: np.ndarray, x0: int, y0: int, x1: int, y1: int, unit: float):
    """The reflection's pixels in ``crop[y0:y1, x0:x1]`` (:func:`glare_mask`'s work but the mask's growth).

    The skin's light and colour are the mean YCrCb (OpenCV's 8-bit conversion) of the ``cheeks`` rectangles
    (K, 4) int64 (each clipped as a slice of the crop, the rectangles' means weighted by their pixels); the
    pixels brighter than it by :data:`GLARE` ``lift`` whose chroma along the skin's is under ``chroma`` of the
    skin's (in float32) are kept where they belong to a patch (8-connected on the half-resolution mask, the
    pixels of even row and column) taller than half ``tall`` or wider than half ``wide`` face units there.

    Returns
    -------
    found : bool
        Whether there is a reflection (False also where the part is empty or the skin has no chroma).
    mask : (H, W) uint8
        255 on the reflection's pixels (empty (0, 0) when not found).
    """
    h, w = crop.shape[:2]
    none = np.zeros((0, 0), np.uint8)
    n = 0
    t0 = t1 = t2 = 0.0
    for k in range(len(cheeks)):
        r0, c0 = max(cheeks[k, 1], 0), max(cheeks[k, 0], 0)
        r1, c1 = _slice_end(cheeks[k, 3], h), _slice_end(cheeks[k, 2], w)
        if r1 <= r0 or c1 <= c0:
            continue
        s0 = s1 = s2 = 0
        for y in range(r0, r1):
            for x in range(c0, c1):
                luma, u, v = ycrcb_u8(np.int64(crop[y, x, 0]), np.int64(crop[y, x, 1]), np.int64(crop[y, x, 2]))
                s0 += luma
                s1 += u
                s2 += v
        count = (r1 - r0) * (c1 - c0)
        inv = 1.0 / count                   # a rectangle's mean as cv2.mean takes it, times its pixels
        t0 += s0 * inv * count
        t1 += s1 * inv * count
        t2 += s2 * inv * count
        n += count
    if n == 0:
        return False, none
    ys, cr, cb = t0 / n, t1 / n - 128.0, t2 / n - 128.0
    s2 = cr * cr + cb * cb
    if s2 < 1.0:
        return False, none                  # no skin chroma to tell a colourless patch from
    # The pixels brighter than the skin, then those of them less coloured than it: (Cr, Cb) along the skin's
    # direction under the reflection's most.
    least = min(_TALL, _WIDE) * unit
    level = (1.0 + _LIFT) * ys
    fcr, fcb, bound, mid = np.float32(cr), np.float32(cb), np.float32(_CHROMA * s2), np.float32(128.0)
    ph, pw = y1 - y0, x1 - x0
    bright = np.zeros((ph, pw), np.bool_)
    n_lit = n_kept = 0
    for y in range(ph):
        for x in range(pw):
            luma, u, v = ycrcb_u8(np.int64(crop[y0 + y, x0 + x, 0]), np.int64(crop[y0 + y, x0 + x, 1]),
                                  np.int64(crop[y0 + y, x0 + x, 2]))
            if luma > level:
                n_lit += 1
                if (np.float32(u) - mid) * fcr + (np.float32(v) - mid) * fcb < bound:
                    n_kept += 1
                    bright[y, x] = True
    if n_lit < least or n_kept < least:
        return False, none
    # The patches of the half-resolution mask (8-connected), and which are big.
    hh, hw = (ph + 1) // 2, (pw + 1) // 2
    labels = np.zeros((hh, hw), np.int64)
    big = np.zeros(hh * hw + 1, np.bool_)
    stack = np.empty(hh * hw, np.int64)
    tall, wide = 0.5 * _TALL * unit, 0.5 * _WIDE * unit
    n_labels = 0
    any_big = False
    for i in range(hh):
        for j in range(hw):
            if not bright[2 * i, 2 * j] or labels[i, j]:
                continue
            n_labels += 1
            labels[i, j] = n_labels
            top, bottom, left, right = i, i, j, j
            stack[0] = i * hw + j
            size = 1
            while size:
                size -= 1
                ci, cj = stack[size] // hw, stack[size] % hw
                top, bottom, left, right = min(top, ci), max(bottom, ci), min(left, cj), max(right, cj)
                for di in range(-1, 2):
                    for dj in range(-1, 2):
                        ni, nj = ci + di, cj + dj
                        if 0 <= ni < hh and 0 <= nj < hw and not labels[ni, nj] and bright[2 * ni, 2 * nj]:
                            labels[ni, nj] = n_labels
                            stack[size] = ni * hw + nj
                            size += 1
            if bottom - top + 1 > tall or right - left + 1 > wide:
                big[n_labels] = True
                any_big = True
    if not any_big:
        return False, none
    mask = np.zeros((h, w), np.uint8)
    for y in range(ph):
        for x in range(pw):
            if bright[y, x] and big[labels[y // 2, x // 2]]:
                mask[y0 + y, x0 + x] = 255
    return True, mask


def without_glare(crop: np.ndarray, cheeks: np.ndarray, eyes: np.ndarray, unit: float) -> np.ndarray:
    """The face crop (H, W, 3) uint8 with a veil over the face taken off (:func:`.veil.without_veil`) and a
    reflection around the eyes (:func:`glare_mask`) filled in from its surroundings; the crop itself where there
    is neither."""
    crop = without_veil(crop, unit)
    mask = glare_mask(crop, cheeks, eyes, unit)
    if mask is None:
        return crop
    # Telea's inpainting reads and writes only within its reach of the mask (OpenCV rounds the reach to whole
    # pixels): it runs on the mask's bounding box grown by the reach and a margin, the same pixels as on the
    # whole crop.
    radius = max(_value("radius") * unit, 1.0)
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    if not rows.size:
        return crop
    m = int(np.ceil(radius)) + INPAINT_MARGIN
    h, w = mask.shape
    y0, y1 = max(rows[0] - m, 0), min(rows[-1] + 1 + m, h)
    x0, x1 = max(cols[0] - m, 0), min(cols[-1] + 1 + m, w)
    out = crop.copy()
    out[y0:y1, x0:x1] = cv2.inpaint(np.ascontiguousarray(crop[y0:y1, x0:x1]), np.ascontiguousarray(mask[y0:y1, x0:x1]),
                                    radius, cv2.INPAINT_TELEA)
    return out
