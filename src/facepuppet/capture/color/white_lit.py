"""The colours each side of a face crop would have in a white light (von Kries), for the eye search's test of the
eye's white against the skin; and the light a patch would be in if it were skin, for the search for the face.

A light's colour scales each channel: under a warm lamp the white of the eye takes the lamp's colour and the skin
both the lamp's and its own, and tested against the skin's chroma (:func:`~.eye_anchors.eye_opening_centres`) the
white passes for skin. Scaled so that the cheek on its side has the chromaticity of an average skin in a white
light (:data:`WHITE_LIT_SKIN`; R + G + B kept), each side of the crop shows the white as it is against the skin,
whatever the light's colour on that side.

The search for the face tries a cascade window whose middle looks like skin in no light it knows (a face and a
wall of its colour in one strongly coloured light) in the light that gives that middle an average skin's colour
(:func:`skin_light`): if it is a face, that light is the one it is in.

Conventions: crop pixels of one face crop (x right, y down), RGB uint8; the crop's two sides are the columns left
(row 0) and right (row 1) of a middle column (the eyes' midpoint).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from facepuppet._util.jit import INNER, KERNEL

__all__ = ["WHITE_LIT_SKIN", "TINTED", "LIGHT_SPREAD", "side_colours", "skin_light", "white_lit"]

#: The chromaticity (shares of R, G and B) of an average skin under a white light.
WHITE_LIT_SKIN = np.array([0.41, 0.315, 0.275])
#: Distance of a cheek's chromaticity from :data:`WHITE_LIT_SKIN` (Euclidean, in shares) from which its side is
#: taken to be in a coloured light: the shared clips' cheeks 0.005-0.025 (performer_a's camera 0.15), a warm
#: lamp's 0.15, a cool window's 0.09.
TINTED = 0.06
#: Most a light's channel gains differ (largest over smallest) for :func:`skin_light`: a tungsten lamp before a
#: camera balanced for daylight needs 2, a cool window's light 1.6; a patch that needs more is no skin.
LIGHT_SPREAD = 4.0


@nb.njit(**KERNEL)
def side_colours(crop: np.ndarray, cheeks: np.ndarray, middle: float) -> np.ndarray:
    """(2, 3) the median R, G and B of the crop (H, W, 3) uint8 over the cheek rectangles ``cheeks`` (K, 4) x0, y0,
    x1, y1 left and right of column ``middle`` (by their middle column); a side without one takes the other's
    colour, and without either both are 0."""
    out = np.zeros((2, 3))
    seen = np.zeros(2, np.bool_)
    h, w = crop.shape[:2]
    for side in range(2):
        n = 0
        for b in range(cheeks.shape[0]):
            if ((cheeks[b, 0] + cheeks[b, 2]) * 0.5 >= middle) == (side == 1):
                n += (max(min(cheeks[b, 2], w) - max(cheeks[b, 0], 0), 0)
                      * max(min(cheeks[b, 3], h) - max(cheeks[b, 1], 0), 0))
        if n == 0:
            continue
        vals = np.empty((3, n))
        i = 0
        for b in range(cheeks.shape[0]):
            if ((cheeks[b, 0] + cheeks[b, 2]) * 0.5 >= middle) != (side == 1):
                continue
            for y in range(max(cheeks[b, 1], 0), min(cheeks[b, 3], h)):
                for x in range(max(cheeks[b, 0], 0), min(cheeks[b, 2], w)):
                    for c in range(3):
                        vals[c, i] = crop[y, x, c]
                    i += 1
        for c in range(3):
            out[side, c] = np.median(vals[c])
        seen[side] = True
    for side in range(2):
        if not seen[side] and seen[1 - side]:
            out[side] = out[1 - side]
    return out


@nb.njit(**INNER)
def white_lit(crop: np.ndarray, cheeks: np.ndarray, middle: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(gains, skin, tinted): per side (rows as :func:`side_colours`'), the gains (3,) of R, G and B that give the
    side's cheek colour :data:`WHITE_LIT_SKIN`'s chromaticity at its own R + G + B, that skin's (luma, Cr - 128,
    Cb - 128) (3,), ITU-R BT.601 as :func:`~.eye_anchors.skin_reference`'s, and whether the cheek's chromaticity
    lies :data:`TINTED` or farther from it (2,) bool."""
    colours = side_colours(crop, cheeks, middle)
    gains = np.empty((2, 3))
    skin = np.empty((2, 3))
    tinted = np.zeros(2, np.bool_)
    for side in range(2):
        total = colours[side].sum()
        off = 0.0
        for c in range(3):
            gains[side, c] = WHITE_LIT_SKIN[c] * total / max(colours[side, c], 1.0)
            off += (colours[side, c] / max(total, 1.0) - WHITE_LIT_SKIN[c]) ** 2
        tinted[side] = off >= TINTED * TINTED
        r, g, b = WHITE_LIT_SKIN[0] * total, WHITE_LIT_SKIN[1] * total, WHITE_LIT_SKIN[2] * total
        v = 0.299 * r + 0.587 * g + 0.114 * b
        skin[side, 0], skin[side, 1], skin[side, 2] = v, 0.713 * (r - v), 0.564 * (b - v)
    return gains, skin, tinted


def skin_light(patch: np.ndarray) -> np.ndarray | None:
    """The colour transform (3, 4) for ``cv2.transform`` that gives the median colour of ``patch`` (H, W, 3) uint8
    the chromaticity :data:`WHITE_LIT_SKIN` with its R + G + B kept (channel gains, no offset): the light a patch
    of skin is seen in, undone (von Kries); None for an empty patch, one with a channel whose median is 0, or one
    no light turns skin would show (gains more than :data:`LIGHT_SPREAD` apart)."""
    if patch.size == 0:
        return None
    med = np.median(patch.reshape(-1, 3), axis=0).astype(float)
    if med.min() <= 0.0:
        return None
    gains = WHITE_LIT_SKIN * med.sum() / med
    if gains.max() > LIGHT_SPREAD * gains.min():
        return None
    return np.column_stack([np.diag(gains), np.zeros(3)])
