"""Light from one side evened out on a face crop: a window or lamp beside the performer lights one half of the face
and leaves the other in shade.

Eq. 1 reads darkness as a feature (its value term ``w3 V``, ``w3 < 0``) and the contrast C takes one skin level
for the whole crop (the median of I over both cheeks): the shaded half of a face lit from one side lies above that
level and lights up as a feature, its eye search and mouth rules take shading for lids and lips, and the
followed face shrinks into the lit half until it no longer looks like a face. Shade scales a pixel's three
channels alike (and a camera's gamma keeps their ratios), so it is undone by a gain:

- **Whether.** The skin's value V (8-bit, the median of max(R, G, B) over each cheek rectangle) is read on both
  cheeks. Where the brighter over the darker is at most :data:`SIDES` ``from`` (a room's light), or the cheeks'
  mean chromaticities differ by more than ``colour`` (not one skin in more or less light: a cheek on the hair, a
  hand or the background, the crop off the face), the crop is left as it is.
- **How much.** The light across the face is read twice: running linearly between the cheeks' middle columns
  (the same beyond them), and as each column's upper quartile of V over the cheeks' rows (the skin, not the
  nostrils), made to rise steadily from the shaded cheek's side to the lit one's (the dips of features filled),
  the same beyond the cheeks. Each column's gain is the brighter cheek's level over the larger of the two
  readings (a shadow's sharp edge near the shaded cheek leaves the columns between it and the lit cheek lit,
  which the linear reading alone would brighten), raised to the share of the way from ``from`` to ``full`` the
  ratio has come (no jump where the evening starts), between 1 and ``most``.

A lamp on one side and a window on the other light the halves in different colours (warm and cool): Eq. 1's
colour terms (magenta, the lip hue) then differ between the halves and one half's skin lights up as a feature.
A change of light scales each channel by its own factor, so it too is undone by gains, one per channel: where
the cheeks' mean chromaticities differ by more than :data:`COLOURS` ``from`` and at most ``most`` (more: a cheek
on a coloured scene, not one skin), each column's chromaticity is read linearly between the cheeks' middle
columns (the same beyond them) and its channels scaled to the brighter cheek's chromaticity, to the share of the
way from ``from`` to ``full`` the difference has come (no jump where the evening starts). A pixel of the column's
chromaticity keeps R + G + B: the levels are then the side evening's, which follows.

Conventions: RGB uint8 face crops (H, W, 3), upright; rectangles (x0, y0, x1, y1) crop pixels; levels 8-bit.
"""

from __future__ import annotations

import cv2
import numpy as np

from facepuppet.capture.color.transform import value_median

__all__ = ["SIDES", "COLOURS", "side_gains", "evened_sides", "colour_gains", "evened_colours"]

#: The unevenness taken out: name -> (value, unit, meaning).
SIDES = {
    "from": (1.4, "ratio", "brighter cheek's value over the darker's under which the crop is left as it is (a "
             "face in a room's light: up to 1.28 on the shared clips' crops, 1.33 on a trained profile's)"),
    "full": (1.8, "ratio", "the ratio from which the darker side is brightened fully to the brighter's level"),
    "most": (3.0, "gain", "largest gain of a column (a cheek in deep shade, or covered, is not lit beyond it)"),
    "colour": (0.1, "chromaticity", "largest difference of the cheeks' mean chromaticities (red and green shares, "
               "summed) for the difference of their light to be shade (side-lit copies: up to 0.065)"),
}

#: Two lights' colours taken out of a face crop: name -> (value, unit, meaning).
COLOURS = {
    "from": (0.08, "chromaticity", "cheeks' chromaticity difference (as SIDES' ``colour``) under which the colours "
             "are left as they are (the shared clips' followed crops: up to 0.079)"),
    "full": (0.1, "chromaticity", "the difference from which the columns are brought fully to the lit cheek's "
             "chromaticity (a warm lamp and a cool window's light on the shared performers: 0.1-0.12 mostly)"),
    "most": (0.2, "chromaticity", "largest difference taken for two lights on one skin (a warm lamp and a cool "
             "window's light on the shared performers' followed crops: up to 0.15; a blue scene beside skin: 0.3)"),
}


def _value(name: str, table: dict = SIDES) -> float:
    return float(table[name][0])


def _shares(crop: np.ndarray, cheeks: np.ndarray) -> np.ndarray:
    """(2, 3) the two cheek rectangles' mean chromaticities, (R, G, B) / (R + G + B) of their mean colours (a
    rectangle without pixels: grey)."""
    shares = []
    for x0, y0, x1, y1 in cheeks[:2].tolist():
        part = crop[max(y0, 0):max(y1, 0), max(x0, 0):max(x1, 0)]
        r, g, b, _ = cv2.mean(part) if part.size else (1.0, 1.0, 1.0, 0.0)
        total = max(r + g + b, 1e-6)
        shares.append((r / total, g / total, b / total))
    return np.array(shares)


def _gap(shares: np.ndarray) -> float:
    """The difference of two chromaticities (2, 3): |dr| + |dg| (shade scales the channels alike, and a camera's
    gamma keeps their ratios)."""
    (r0, g0, _), (r1, g1, _) = shares.tolist()
    return abs(r0 - r1) + abs(g0 - g1)


def _chroma_gap(crop: np.ndarray, cheeks: np.ndarray) -> float:
    """The difference of the two cheek rectangles' mean chromaticities (:func:`_gap`)."""
    return _gap(_shares(crop, cheeks))


def _across(values, cheeks: np.ndarray, width: int) -> np.ndarray:
    """(width,) the two cheeks' ``values`` (2,) running linearly between the cheeks' middle columns, the same
    beyond them."""
    middles = np.array([0.5 * (float(cheeks[k, 0]) + float(cheeks[k, 2]) - 1.0) for k in range(2)])
    order = np.argsort(middles)
    return np.interp(np.arange(width, dtype=np.float64), middles[order], np.asarray(values, dtype=np.float64)[order])


def _ramp(levels: list[float], cheeks: np.ndarray, width: int) -> np.ndarray:
    """(width,) the light running linearly between the cheeks' middle columns at their ``levels`` (at least 1),
    the same beyond them."""
    return _across(np.maximum(np.asarray(levels), 1.0), cheeks, width)


def _columns(crop: np.ndarray, cheeks: np.ndarray, rising: bool) -> np.ndarray | None:
    """(W,) each column's upper quartile of the value over the cheeks' rows between the cheeks' outer edges, made
    to rise steadily towards the right (``rising``) or the left (the running maximum from the shaded side), the
    same beyond the cheeks; None where the cheeks hold too few pixels."""
    h, w = crop.shape[:2]
    x0, x1 = max(int(cheeks[:, 0].min()), 0), min(int(cheeks[:, 2].max()), w)
    y0, y1 = max(int(cheeks[:, 1].min()), 0), min(int(cheeks[:, 3].max()), h)
    if x1 - x0 < 2 or y1 - y0 < 1:
        return None
    values = crop[y0:y1, x0:x1].max(axis=2)
    upper = (3 * (y1 - y0 - 1)) // 4                     # the upper quartile's rank (nearest below)
    profile = np.partition(values, upper, axis=0)[upper].astype(np.float64)
    steady = np.maximum.accumulate(profile) if rising else np.maximum.accumulate(profile[::-1])[::-1]
    out = np.empty(w)
    out[x0:x1] = steady
    out[:x0], out[x1:] = steady[0], steady[-1]
    return np.maximum(out, 1.0)


def side_gains(crop: np.ndarray, cheeks: np.ndarray) -> np.ndarray | None:
    """The gain of each of the crop's columns, (W,) float32, that evens out the light between the two cheek
    rectangles ``cheeks`` (2, 4) int64 (module notes), or None where they are lit about alike, their colours
    differ, or they hold too few pixels."""
    levels = [value_median(crop, cheeks[k:k + 1]) for k in range(2)]
    low, high = max(min(levels), 1.0), max(levels)
    ratio = high / low
    start, full = _value("from"), _value("full")
    if ratio <= start or _chroma_gap(crop, cheeks) > _value("colour"):
        return None
    # the shaded cheek on the left: the light rises towards the right
    rising = (levels[0] < levels[1]) == (cheeks[0, 0] < cheeks[1, 0])
    columns = _columns(crop, cheeks, rising)
    if columns is None:
        return None
    # the two readings of the light, the columns' scaled to the brighter cheek's level at their brightest
    light = np.maximum(columns * (high / float(columns.max())), _ramp(levels, cheeks, crop.shape[1]))
    share = min((ratio - start) / (full - start), 1.0)
    return np.clip((high / light) ** share, 1.0, _value("most")).astype(np.float32)


def evened_sides(crop: np.ndarray, cheeks: np.ndarray) -> np.ndarray:
    """The face crop (H, W, 3) uint8 with the light evened out between its sides (:func:`side_gains`); the crop
    itself where the cheeks are lit about alike."""
    gains = side_gains(crop, cheeks)
    if gains is None:
        return crop
    h, w = crop.shape[:2]
    g = np.ascontiguousarray(np.broadcast_to(gains, (h, w)))
    return cv2.multiply(crop, cv2.merge((g, g, g)), dtype=cv2.CV_8U)


def colour_gains(crop: np.ndarray, cheeks: np.ndarray) -> np.ndarray | None:
    """(W, 3) float32 gains of each column's R, G, B that bring its chromaticity, read linearly between the two
    cheek rectangles' ``cheeks`` (2, 4) int64 middle columns (the same beyond them), to the brighter cheek's
    (module notes); None where the cheeks' chromaticities differ by at most :data:`COLOURS` ``from`` or by more
    than ``most``."""
    shares = _shares(crop, cheeks)
    gap = _gap(shares)
    start, full = _value("from", COLOURS), _value("full", COLOURS)
    if not start < gap <= _value("most", COLOURS):
        return None
    lit = int(value_median(crop, cheeks[1:2]) > value_median(crop, cheeks[0:1]))
    seen = np.stack([_across(shares[:, c], cheeks, crop.shape[1]) for c in range(3)], axis=1)
    share = min((gap - start) / (full - start), 1.0)
    return ((shares[lit] / np.maximum(seen, 1e-3)) ** share).astype(np.float32)


def evened_colours(crop: np.ndarray, cheeks: np.ndarray) -> np.ndarray:
    """The face crop (H, W, 3) uint8 with two lights' colours evened out between its sides (:func:`colour_gains`);
    the crop itself where the cheeks' colours are about alike, or too far apart for one skin."""
    gains = colour_gains(crop, cheeks)
    if gains is None:
        return crop
    return cv2.multiply(crop, np.ascontiguousarray(np.broadcast_to(gains, crop.shape)), dtype=cv2.CV_8U)
