"""Colour space transformation of the paper's §3.1: Eq. 1 and the contrast enhancement C.

Conventions: RGB uint8 images (H, W, 3); channels scaled to [0, 1]; hue in degrees [0, 360).

M (magenta) and K (black) are the CMYK channels, V the HSV value, G(H) a bump on the lips' hue:

    K = 1 - max(R, G, B),   M = (max(R, G, B) - G) / max(R, G, B),   V = max(R, G, B)

Since K = 1 - V, the two terms w2 K + w3 V of Eq. 1 collapse to w2 + (w3 - w2) V: K only shifts the
intensity by a constant. The weights keep the paper's four-term form (w1, w2, w3, w4), with the signs it
prescribes (w1, w2, w4 >= 0, w3 < 0).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numba as nb
import numpy as np

from facepuppet._util.jit import INNER, KERNEL
from facepuppet.capture.color.face import SKIN_Y_MAX, SKIN_Y_MIN
from facepuppet.capture.color.rules.kernels import median, median_of_boxes, top_of_boxes

__all__ = [
    "LipHue",
    "channels",
    "lip_hue_table",
    "transform",
    "contrast",
    "DEFAULT_WEIGHTS",
    "SPECK",
    "CONTRAST_LOW",
    "CONTRAST_HIGH",
    "GREY_CONTRAST",
    "GREY_SPREAD",
    "ycrcb_u8",
    "hsv_hue_saturation",
    "skin_fraction",
    "feature_intensity",
    "DARK_WEIGHTS",
    "DARK_SKIN",
    "dark_skin_weights",
    "value_median",
]

#: Generic weights (w1, w2, w3, w4) of Eq. 1: magenta, black, value, lip hue.
DEFAULT_WEIGHTS = np.array([0.9, 0.2, -0.8, 0.5], dtype=np.float32)
#: Generic weights of Eq. 1 for skin of a low value V in the crop as measured (dark skin, or a face the light's
#: stretch left dark): there the colour terms, M = (V - G) / V and the hue's G(H), are ratios of small numbers,
#: their noise growing as 1 / V, while the darkness term's contrast shrinks with V; magenta is left out and the
#: lip hue's weight halved.
DARK_WEIGHTS = np.array([0.0, 0.2, -0.8, 0.25], dtype=np.float32)
#: The skin's level (the median HSV value V of the skin rectangles, 8-bit) at and under which the generic
#: weights are :data:`DARK_WEIGHTS`, and from which they are :data:`DEFAULT_WEIGHTS`; linear in between.
DARK_SKIN = (90.0, 140.0)

# Tuning constants of the contrast C in feature_intensity
#                      unit        what it does
CONTRAST_LOW = 0.15    # fraction    C starts rising this far from the skin level to the feature level
CONTRAST_HIGH = 0.75   # fraction    C reaches 1 this far from the skin level to the feature level
#: The feature level is at most this many times the brightest 3 x 3 mean's height above the skin level: a
#: brighter pixel stands alone, a speck of noise (a light stretched to undo a colour cast turns a camera's block
#: noise into specks).
SPECK = 2.0
#: Span of the smooth step, as a fraction of the skin-to-feature distance.
CONTRAST_SPAN = CONTRAST_HIGH - CONTRAST_LOW
#: Where the crop has no colour (grey footage, a monochrome or infrared camera) the colour terms of Eq. 1 vanish
#: and I is the darkness alone, so the shading of the eye sockets and the nose's sides rises towards the eyes'
#: level and draws the eye search: the C it reads then starts and ends higher, at these fractions (low, high) of
#: the way (the lips, only a little darker than the skin in grey, need the usual ones).
GREY_CONTRAST = (0.4, 0.9)
#: The crop's colour, the mean over its pixels of max(R, G, B) - min(R, G, B) (8-bit levels), at or under which
#: the eyes' C takes :data:`GREY_CONTRAST`, and from which it takes CONTRAST_LOW and CONTRAST_HIGH; linear in
#: between. Grey footage through a video codec gives about 1; faces in colour, dim, hazy or under coloured light,
#: 17 and more (a hand or shadow over the cheeks does not take the colour out of the whole crop).
GREY_SPREAD = (3.0, 8.0)


@dataclass(frozen=True)
class LipHue:
    """The function G of Eq. 1: a Gaussian bump over hue, high on the lips' hue range.

    Attributes
    ----------
    centre : float
        Hue of the lips in degrees (red-magenta is near 350).
    width : float
        Standard deviation of the bump in degrees.
    min_saturation : float
        Below this HSV saturation (0..1) G is 0: grey pixels have no meaningful hue.
    """

    centre: float = 352.0
    width: float = 14.0
    min_saturation: float = 0.12


def lip_hue_table(hue: LipHue) -> np.ndarray:
    """G tabulated over OpenCV's 8-bit hue codes (0..179 = 0..358 degrees), padded to 256 entries.

    Returns
    -------
    (256,) float32
    """
    deg = np.arange(256, dtype=np.float64) * 2.0
    d = (deg - hue.centre + 180.0) % 360.0 - 180.0
    table = np.exp(-0.5 * (d / hue.width) ** 2)
    table[180:] = 0.0
    return table.astype(np.float32)


def channels(rgb: np.ndarray, hue_table: np.ndarray, min_saturation: float = 0.12) -> np.ndarray:
    """The four channels (M, K, V, G(H)) of Eq. 1, each in [0, 1].

    Parameters
    ----------
    rgb : (H, W, 3) uint8
    hue_table : (256,) float32
        G over 8-bit hue codes (:func:`lip_hue_table`).
    min_saturation : float
        Pixels less saturated than this get G = 0.

    Returns
    -------
    (4, H, W) float32
    """
    hsv = cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV)
    v = hsv[..., 2].astype(np.float32) * np.float32(1.0 / 255.0)
    g = rgb[..., 1].astype(np.float32) * np.float32(1.0 / 255.0)
    m = (v - g) / np.maximum(v, np.float32(1.0 / 255.0))
    gh = hue_table[hsv[..., 0]]
    gh[hsv[..., 1] < np.uint8(min_saturation * 255.0)] = 0.0
    return np.stack([m, 1.0 - v, v, gh])


def transform(rgb: np.ndarray, weights: np.ndarray, hue_table: np.ndarray, min_saturation: float = 0.12) -> np.ndarray:
    """Eq. 1: I = w1 M + w2 K + w3 V + w4 G(H).

    Parameters
    ----------
    rgb : (H, W, 3) uint8
        A small crop (the face region): the cost is linear in its pixels.
    weights : (4,) float
        (w1, w2, w3, w4).
    hue_table : (256,) float32
        G tabulated by :func:`lip_hue_table`.
    min_saturation : float

    Returns
    -------
    (H, W) float32
        The feature intensity, high on brows, lid lines, nostrils, lips and mouth opening, low on skin.
    """
    w1, w2, w3, w4 = (np.float32(x) for x in weights)
    hsv = cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV)
    v = hsv[..., 2].astype(np.float32)
    g = rgb[..., 1].astype(np.float32)
    # w1 (v - g) / v + (w3 - w2) v / 255 + w2 + w4 G(H)
    out = (v - g) / np.maximum(v, np.float32(1.0))
    out *= w1
    out += v * ((w3 - w2) / np.float32(255.0))
    out += w2
    if w4 != 0.0:
        gh = hue_table[hsv[..., 0]]
        gh[hsv[..., 1] < np.uint8(min_saturation * 255.0)] = 0.0
        out += w4 * gh
    return out


def contrast(intensity: np.ndarray, low: float, high: float, out: np.ndarray | None = None) -> np.ndarray:
    """The contrast enhancement C: a smooth step from the skin level ``low`` to the feature level ``high``.

    C(I) = x² (3 − 2x) with x = clip((I − low) / (high − low), 0, 1): pixels at or below the skin level go
    to 0, pixels at or above the feature level go to 1, and the mid-tones are pushed apart (the slope at the
    middle is 1.5 times that of a linear stretch).

    Parameters
    ----------
    intensity : (H, W) float32
        I of Eq. 1.
    low, high : float
        Skin and feature levels, ``high > low``.
    out : (H, W) float32, optional
        Where to write (may be ``intensity`` itself).

    Returns
    -------
    (H, W) float32 in [0, 1]
    """
    span = max(float(high) - float(low), 1e-6)
    x = np.subtract(intensity, np.float32(low), out=out)
    x *= np.float32(1.0 / span)
    np.clip(x, 0.0, 1.0, out=x)
    y = x * x
    x *= np.float32(-2.0)
    x += np.float32(3.0)
    x *= y
    return x


@nb.njit(**INNER)
def ycrcb_u8(r: int, g: int, b: int):
    """OpenCV's 8-bit RGB -> YCrCb (same integer arithmetic): (Y, Cr, Cb)."""
    y = (r * 4899 + g * 9617 + b * 1868 + 8192) >> 14
    cr = min(max(((r - y) * 11682 + (128 << 14) + 8192) >> 14, 0), 255)
    cb = min(max(((b - y) * 9241 + (128 << 14) + 8192) >> 14, 0), 255)
    return y, cr, cb


@nb.njit(**KERNEL)
def skin_fraction(crop: np.ndarray, boxes: np.ndarray, table: np.ndarray) -> float:
    """Fraction of the pixels of the rectangles whose (Cr, Cb) the skin table accepts (luma Y in
    :data:`~.face.SKIN_Y_MIN` .. :data:`~.face.SKIN_Y_MAX`), as
    :func:`~facepuppet.capture.color.face.skin_probability`."""
    n = 0
    hit = 0
    for k in range(len(boxes)):
        x0, y0, x1, y1 = boxes[k]
        for yy in range(y0, y1):
            for xx in range(x0, x1):
                y, cr, cb = ycrcb_u8(np.int64(crop[yy, xx, 0]), np.int64(crop[yy, xx, 1]), np.int64(crop[yy, xx, 2]))
                n += 1
                if SKIN_Y_MIN <= y <= SKIN_Y_MAX and table[cr, cb]:
                    hit += 1
    return hit / n if n else 0.0


@nb.njit(**INNER)
def _eq1_row(v: np.ndarray, g: np.ndarray, hue_term: np.ndarray, out: np.ndarray, w1: float, kv: float,
             w2: float) -> None:
    """One row of Eq. 1 from the row's 8-bit value ``v`` and green ``g`` (as floats) and the hue's term
    (w4 G(H), or 0): ``out = w1 (v - g) / max(v, 1) + kv v + w2 + hue_term`` (float32 out), summed in that order."""
    for x in range(len(out)):
        vx = v[x]
        out[x] = w1 * (vx - g[x]) / max(vx, 1.0) + kv * vx + w2 + hue_term[x]


def dark_skin_weights(weights: np.ndarray, dark: np.ndarray, level: float) -> np.ndarray:
    """Eq. 1's weights (4,) float64 for skin of median HSV value ``level`` (8-bit): ``weights`` from
    :data:`DARK_SKIN`'s upper end, ``dark`` at and under its lower, linear in between."""
    s = min(max((level - DARK_SKIN[0]) / (DARK_SKIN[1] - DARK_SKIN[0]), 0.0), 1.0)
    return s * np.asarray(weights, dtype=np.float64) + (1.0 - s) * np.asarray(dark, dtype=np.float64)


def feature_intensity(crop: np.ndarray, weights: np.ndarray, hue_table: np.ndarray, min_saturation: float,
                      skin_boxes: np.ndarray, feature_boxes: np.ndarray, *, grey_contrast: bool = False,
                      dark: np.ndarray | None = None):
    """Eq. 1 and the contrast C over a face crop in one pass (as :func:`transform` and :func:`contrast`).

    I = w1 (V - G) / V + (w3 - w2) V + w2 + w4 G(H) with 8-bit V and G as in :func:`transform`; then C = smoothstep
    between the skin level (median of I over ``skin_boxes``) + :data:`CONTRAST_LOW` and + :data:`CONTRAST_HIGH` of
    the way to the brightest I in ``feature_boxes`` (a lone bright pixel is taken down to :data:`SPECK` times the
    brightest 3 x 3 mean's level). With ``dark``, the weights go over to it as the skin's value falls
    (:func:`dark_skin_weights` of the median V over ``skin_boxes``). On a crop without colour, the eyes' C takes
    fractions going over to :data:`GREY_CONTRAST` (:data:`GREY_SPREAD`). The hue and saturation are OpenCV's 8-bit
    HSV of the crop (:func:`hsv_hue_saturation`, as :func:`cv2.cvtColor`), computed only when the hue term is used.

    Parameters
    ----------
    crop : (H, W, 3) uint8 RGB
    weights : (4,) float
    hue_table : (256,) float32
    min_saturation : float
        In [0, 1]; less saturated pixels get G = 0.
    skin_boxes, feature_boxes : (N, 4) int64
        Rectangles (x0, y0, x1, y1).
    grey_contrast : bool
        Whether ``eyes`` goes over to :data:`GREY_CONTRAST` on a crop without colour.
    dark : (4,) float, optional
        The weights for skin of a low value (:data:`DARK_WEIGHTS` for the generic ones); default none.

    Returns
    -------
    raw : (H, W) float32
        I of Eq. 1.
    C : (H, W) float32
        The contrast-enhanced intensity in [0, 1].
    value : (H, W) uint8
        HSV value V.
    eyes : (H, W) float32
        C as the eye search reads it: on a crop without colour (and ``grey_contrast``) at fractions going over to
        :data:`GREY_CONTRAST`, else ``C`` itself.
    """
    if dark is not None:
        weights = dark_skin_weights(weights, dark, value_median(crop, skin_boxes))
    return _feature_intensity(crop, np.asarray(weights, dtype=np.float64), hue_table, min_saturation, skin_boxes,
                              feature_boxes, grey_contrast)


@nb.njit(**KERNEL)
def value_median(crop: np.ndarray, boxes: np.ndarray) -> float:
    """Median HSV value V (8-bit) of the pixels of the rectangles ``boxes`` (N, 4) int64 of ``crop`` together
    (clipped to it); without any pixel, :data:`DARK_SKIN`'s upper level (at which :func:`dark_skin_weights` keeps
    the weights given)."""
    h, w = crop.shape[:2]
    total = 0
    for b in range(len(boxes)):
        total += max(min(boxes[b, 2], w) - max(boxes[b, 0], 0), 0) * max(min(boxes[b, 3], h) - max(boxes[b, 1], 0), 0)
    vals = np.empty(total)
    n = 0
    for b in range(len(boxes)):
        for y in range(max(boxes[b, 1], 0), min(boxes[b, 3], h)):
            for x in range(max(boxes[b, 0], 0), min(boxes[b, 2], w)):
                vals[n] = max(crop[y, x, 0], crop[y, x, 1], crop[y, x, 2])
                n += 1
    return median(vals[:n]) if n else DARK_SKIN[1]


def _hsv_tables() -> tuple[np.ndarray, np.ndarray]:
    """OpenCV's division tables of its 8-bit RGB -> HSV (hue range 0..180), (256,) int64 each: 255 / v for the
    saturation and 30 / (max - min) for the hue, in 12-bit fixed point, rounded to nearest (0 at 0)."""
    i = np.arange(1, 256, dtype=np.float64)
    sdiv, hdiv = np.zeros(256, np.int64), np.zeros(256, np.int64)
    sdiv[1:] = np.rint((255 << 12) / i)
    hdiv[1:] = np.rint((180 << 12) / (6.0 * i))
    return sdiv, hdiv


_SDIV, _HDIV = _hsv_tables()


@nb.njit(**INNER)
def hsv_hue_saturation(r: int, g: int, b: int):
    """OpenCV's 8-bit RGB -> HSV (:func:`cv2.cvtColor`, ``COLOR_RGB2HSV``; same integer arithmetic): (hue code
    0..180, saturation 0..255) of a pixel's r, g, b (0..255)."""
    v = max(r, g, b)
    diff = v - min(r, g, b)
    s = (diff * _SDIV[v] + 2048) >> 12
    if v == r:
        hue = g - b
    elif v == g:
        hue = b - r + 2 * diff
    else:
        hue = r - g + 4 * diff
    hue = (hue * _HDIV[diff] + 2048) >> 12
    if hue < 0:
        hue += 180
    return hue, s


@nb.njit(**KERNEL)
def _feature_intensity(crop: np.ndarray, weights: np.ndarray, hue_table: np.ndarray, min_saturation: float,
                       skin_boxes: np.ndarray, feature_boxes: np.ndarray, grey_contrast: bool):
    """:func:`feature_intensity` once the weights are known; the hue and saturation (:func:`hsv_hue_saturation`)
    are computed only where the hue term's weight w4 is not 0."""
    h, w = crop.shape[:2]
    w1, w2, w3, w4 = weights[0], weights[1], weights[2], weights[3]
    kv = (w3 - w2) / 255.0
    s_min = np.uint8(min_saturation * 255.0)
    raw = np.empty((h, w), np.float32)
    value = np.empty((h, w), np.uint8)
    use_hue = w4 != 0.0
    # Per row: the value, the green and the hue's term pixel by pixel (table lookups), then Eq. 1's arithmetic
    # over the row in a loop of its own (free of lookups and branches, it is vectorised).
    v_row, g_row, hue_row = np.empty(w), np.empty(w), np.zeros(w)
    spread = 0
    for y in range(h):
        for x in range(w):
            r, g, b = np.int64(crop[y, x, 0]), np.int64(crop[y, x, 1]), np.int64(crop[y, x, 2])
            v = max(r, g, b)
            spread += v - min(r, g, b)
            if use_hue:
                hue, sat = hsv_hue_saturation(r, g, b)
                hue_row[x] = w4 * hue_table[hue] if sat >= s_min else 0.0
            v_row[x] = v
            g_row[x] = g
            value[y, x] = v
        _eq1_row(v_row, g_row, hue_row, raw[y], w1, kv, w2)
    low = median_of_boxes(raw, skin_boxes)
    top, peak = top_of_boxes(raw, feature_boxes, low)
    feat = low + min(top - low, SPECK * (peak - low))
    grey = 0.0
    if grey_contrast:
        colour = spread / max(h * w, 1)
        grey = min(max((GREY_SPREAD[1] - colour) / (GREY_SPREAD[1] - GREY_SPREAD[0]), 0.0), 1.0)
    C = _smoothstep(raw, low + CONTRAST_LOW * (feat - low), 1.0 / max(CONTRAST_SPAN * (feat - low), 1e-6))
    if grey <= 0.0:
        return raw, C, value, C
    c_low = CONTRAST_LOW + grey * (GREY_CONTRAST[0] - CONTRAST_LOW)
    c_high = CONTRAST_HIGH + grey * (GREY_CONTRAST[1] - CONTRAST_HIGH)
    return raw, C, value, _smoothstep(raw, low + c_low * (feat - low), 1.0 / max((c_high - c_low) * (feat - low), 1e-6))


@nb.njit(**INNER)
def _smoothstep(raw: np.ndarray, lo: float, inv: float) -> np.ndarray:
    """(H, W) float32 ``t² (3 - 2 t)`` with ``t = clip((raw - lo) inv, 0, 1)``."""
    h, w = raw.shape
    C = np.empty((h, w), np.float32)
    for y in range(h):
        for x in range(w):
            t = min(max((raw[y, x] - lo) * inv, 0.0), 1.0)
            C[y, x] = t * t * (3.0 - 2.0 * t)
    return C
