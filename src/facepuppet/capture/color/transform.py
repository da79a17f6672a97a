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
import numpy as np

__all__ = [
    "LipHue",
    "channels",
    "lip_hue_table",
    "transform",
    "contrast",
    "DEFAULT_WEIGHTS",
]

#: Generic weights (w1, w2, w3, w4) of Eq. 1: magenta, black, value, lip hue.
DEFAULT_WEIGHTS = np.array([0.9, 0.2, -0.8, 0.5], dtype=np.float32)


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
