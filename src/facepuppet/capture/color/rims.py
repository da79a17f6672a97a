"""Glasses' rims taken out of a face crop: thin dark lines around the eyes, longer than any feature there, filled
in from what surrounds them.

A dark rim around each eye (with the bridge and the arms) is to Eq. 1 a dark feature like the brows and the lids,
and one the layout does not hold: the crop's likeness to a face falls by half (the tracker then lets a followed
face go when the mouth opens wide, and finds it again off the face), the eye search and the brows' rule may take a
rim's bar for a lid or a brow. The rims' pixels are found in a band of rows around the eye rectangles
(:data:`RIMS` ``above`` and ``below``) of the grey crop:

- **dark**: darker than the grey closed over ``reach`` (the light around them) by ``dark`` of it;
- **thin**: not within a dark area thicker than ``thick`` (what an opening of the dark pixels by that size keeps,
  grown by a pixel: the iris and pupil, the lashes of an open eye, a thick brow, the hair);
- **strong**: in a line darker than its light by ``strong`` on average (a faint rim, thin or light, barely
  lights Eq. 1's darkness);
- **long**: in a connected line wider than ``across`` (the bars of both lenses and the bridge: the two brows are
  apart), or wider than ``wide`` and taller than ``tall`` (a lens's outline: a brow, or a lash line with an
  eyeliner's wing, may be as wide but is flatter);

and within ``ring`` of the outside of those lines with what they enclose filled in (an eye's lashes or lid
touching a lens's inner edge lie deeper in; small gaps in an outline bridged first), grown by a pixel (their
blurred edge), and filled with the mean colour of the pixels around them that are not the rims' (``fill``). A
crop without such lines is returned as it is.

Conventions: RGB uint8 face crops (H, W, 3), upright (the face frame's x along the rows); rectangles
(x0, y0, x1, y1) crop pixels; ``unit`` crop pixels per face unit.
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["RIMS", "MIN_DARK", "RIM_CHECK_EVERY", "RIM_REUSE", "Rims", "rim_mask", "without_rims", "filled"]

#: The rims' look and extent: name -> (value, unit, meaning).
RIMS = {
    "above": (0.6, "face units", "rows searched above the eye rectangles' middle row (a lens's top, the brows)"),
    "below": (0.7, "face units", "rows searched below it (a lens's bottom)"),
    "reach": (0.3, "face units", "size of the closing whose grey is a pixel's surroundings' light"),
    "dark": (0.25, "share", "how much darker than its surroundings' light a rim's pixel is, at least"),
    "strong": (0.5, "share", "how much darker than their light a rim's pixels are on average (a faint rim, thin "
               "or light, barely lights Eq. 1's darkness and is left as it is)"),
    "fill": (0.08, "face units", "Gaussian sigma of the mean colour a rim's pixels are filled with (cut at 2)"),
    "gap": (0.15, "face units", "gaps in a lens's outline bridged before what it encloses is filled in"),
    "ring": (0.12, "face units", "farthest a rim's pixel lies from the outside of the lines and what they enclose"),
    "thick": (0.13, "face units", "a dark area thicker than this is a feature (iris, lashes, thick brow), no rim"),
    "wide": (0.8, "face units", "a thin dark line wider than this and taller than ``tall`` is a lens's outline"),
    "tall": (0.3, "face units", "(a brow, or a lash line with an eyeliner's wing, is as wide but flatter)"),
    "across": (1.2, "face units", "a thin dark line wider than this reaches across both eyes: the rims' bars and "
               "the bridge (the brows are apart)"),
}
#: Least darkness (grey levels) of a rim's pixel under its surroundings' light, whatever the light.
MIN_DARK = 12
#: Frames between looks for rims on a followed face that has shown none since it was found (glasses are put on
#: now and then; a face that has shown rims is looked at every :data:`RIM_REUSE` frames).
RIM_CHECK_EVERY = 30
#: Frames a mask read on a face that has shown rims fills (it is read again on the next).
RIM_REUSE = 2


def _value(name: str) -> float:
    return float(RIMS[name][0])


def _square(size: float) -> np.ndarray:
    """A square structuring element about ``size`` pixels across (odd, at least 3)."""
    k = max(int(round(size)) | 1, 3)
    return np.ones((k, k), np.uint8)


def _disc(size: float) -> np.ndarray:
    """A disc-shaped structuring element about ``size`` pixels across (odd, at least 3)."""
    k = max(int(round(size)) | 1, 3)
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))


def _band(crop: np.ndarray, eyes: np.ndarray, unit: float) -> tuple[int, int]:
    """Rows (y0, y1) of the crop searched: :data:`RIMS` ``above`` and ``below`` of the eye rectangles' middle row."""
    eyes = np.asarray(eyes, dtype=float)
    mid = 0.5 * (eyes[:, 1].mean() + eyes[:, 3].mean())
    h = crop.shape[0]
    y0 = min(max(int(np.floor(mid - _value("above") * unit)), 0), h)
    y1 = min(max(int(np.ceil(mid + _value("below") * unit)) + 1, y0), h)
    return y0, y1


def _longest_run(flags: np.ndarray) -> int:
    """Length of the longest run of True in the 1-D bool array ``flags``."""
    edges = np.flatnonzero(np.diff(np.concatenate(([0], flags.astype(np.int8), [0]))))
    return int((edges[1::2] - edges[::2]).max()) if edges.size else 0


def rim_mask(crop: np.ndarray, eyes: np.ndarray, unit: float) -> tuple[np.ndarray | None, int]:
    """The rims' pixels of a face crop: ((y1 - y0, W) uint8 mask (255) of the rows from ``y0`` on, y0), or
    (None, y0) where there are none (module notes).

    ``crop``: (H, W, 3) uint8 RGB; ``eyes``: (2, 4) the eye rectangles; ``unit``: crop pixels per face unit.
    """
    y0, y1 = _band(crop, eyes, unit)
    if y1 - y0 < 3:
        return None, y0
    grey = cv2.cvtColor(np.ascontiguousarray(crop[y0:y1]), cv2.COLOR_RGB2GRAY)
    light = cv2.morphologyEx(grey, cv2.MORPH_CLOSE, _square(_value("reach") * unit), borderType=cv2.BORDER_REPLICATE)
    below = cv2.subtract(light, grey)                   # a closing is at least the grey: no level is lost
    dark = ((below > MIN_DARK) & (below.astype(np.float32) > _value("dark") * light)).astype(np.uint8)
    if not dark.any():
        return None, y0
    thick = cv2.dilate(cv2.morphologyEx(dark, cv2.MORPH_OPEN, _disc(_value("thick") * unit)), _square(3))
    thin = dark & (1 - thick)
    if _longest_run(thin.any(axis=0)) < min(_value("wide"), _value("across")) * unit:
        return None, y0                 # no line spans that many columns: none is that wide
    n, labels, stats, _ = cv2.connectedComponentsWithStats(thin, connectivity=8)
    w, h = stats[1:, cv2.CC_STAT_WIDTH], stats[1:, cv2.CC_STAT_HEIGHT]
    shaped = np.flatnonzero((w >= _value("across") * unit)
                            | ((w >= _value("wide") * unit) & (h >= _value("tall") * unit))) + 1
    if not shaped.size:
        return None, y0
    on = thin > 0
    share = np.bincount(labels[on], below[on] / np.maximum(light[on], 1.0), n)
    keep = shaped[share[shaped] >= _value("strong") * np.maximum(stats[shaped, cv2.CC_STAT_AREA], 1)]
    if not keep.size:
        return None, y0
    chosen = np.zeros(n, np.uint8)
    chosen[keep] = 1
    lines = chosen[labels]
    # A lens's outline encloses the eye, whose lashes or lid may touch its inner edge: only the pixels within
    # ``ring`` of the outside of the lines with what they enclose filled in are the rims' (the lines' small gaps
    # closed first: a reflection may break an outline).
    closed = cv2.morphologyEx(lines, cv2.MORPH_CLOSE, _disc(_value("gap") * unit))
    outside = np.pad(1 - closed, 1, constant_values=1)
    cv2.floodFill(outside, None, (0, 0), 2)
    solid = (outside[1:-1, 1:-1] != 2).astype(np.uint8)
    depth = cv2.distanceTransform(solid, cv2.DIST_L2, 3)
    mask = ((lines > 0) & (depth <= _value("ring") * unit)).astype(np.uint8) * 255
    return cv2.dilate(mask, _square(3)), y0


def without_rims(crop: np.ndarray, eyes: np.ndarray, unit: float) -> tuple[np.ndarray, bool]:
    """The face crop (H, W, 3) uint8 with the glasses' rims (:func:`rim_mask`) filled in (:func:`filled`), and
    whether it had any; the crop itself where it had none."""
    mask, y0 = rim_mask(crop, eyes, unit)
    if mask is None:
        return crop, False
    return filled(crop, mask, y0, unit), True


def filled(crop: np.ndarray, mask: np.ndarray, y0: int, unit: float) -> np.ndarray:
    """A copy of the face crop (H, W, 3) uint8 whose pixels under ``mask`` ((h, W) uint8, nonzero: a rim's, the
    crop's rows from ``y0`` on) take the mean colour of the pixels around them that are not under it, weighted by
    a Gaussian of :data:`RIMS` ``fill`` face units cut at two of them (the skin's colour, not a lighter or greyer
    one the eye search would take for an eye's white)."""
    sigma = max(_value("fill") * unit, 1.0)
    reach = int(round(2.0 * sigma))
    rows_on, cols_on = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    if not rows_on.size:
        return crop
    # Only the mask's box grown by the Gaussian's reach is blurred (the mean around each rim pixel reads no more).
    h, w = mask.shape
    r0, r1 = max(rows_on[0] - reach - 1, 0), min(rows_on[-1] + 2 + reach, h)
    c0, c1 = max(cols_on[0] - reach - 1, 0), min(cols_on[-1] + 2 + reach, w)
    sub = mask[r0:r1, c0:c1]
    seen = cv2.compare(sub, 0, cv2.CMP_EQ).astype(np.float32) * np.float32(1.0 / 255.0)   # 1 off the rims
    colour = cv2.multiply(crop[y0 + r0:y0 + r1, c0:c1].astype(np.float32), cv2.merge((seen, seen, seen)))
    # Each rim pixel's mean of the others around it: blurred colour over blurred weight.
    k = 2 * reach + 1
    colour = cv2.GaussianBlur(colour, (k, k), sigma, borderType=cv2.BORDER_REPLICATE)
    weight = cv2.max(cv2.GaussianBlur(seen, (k, k), sigma, borderType=cv2.BORDER_REPLICATE), 1e-3)
    mean = cv2.divide(colour, cv2.merge((weight, weight, weight)), dtype=cv2.CV_8U)
    out = crop.copy()
    cv2.copyTo(mean, sub, out[y0 + r0:y0 + r1, c0:c1])
    return out


class Rims:
    """Glasses' rims taken out of the successive face crops of one take: a search's candidates always; a followed
    face's every :data:`RIM_CHECK_EVERY` frames until it shows rims, then every :data:`RIM_REUSE` frames, the
    last mask read filling the frames between (the crop is aligned on the face, the rims move with it).
    """

    def __init__(self):
        self.restart()

    def restart(self) -> None:
        """A face just found: looked at for rims at its next followed frame."""
        self.seen, self.wait = False, 0
        self._last: tuple[np.ndarray, int] | None = None

    def __call__(self, crop: np.ndarray, eyes: np.ndarray, unit: float, followed: bool) -> np.ndarray:
        """The crop (H, W, 3) uint8 with the rims filled in (:func:`without_rims`); ``followed``: whether it is
        the crop of the face followed (else a candidate of a search, looked at afresh, the state untouched)."""
        if not followed:
            return without_rims(crop, eyes, unit)[0]
        if self.wait > 0:
            self.wait -= 1
            return crop if self._last is None else filled(crop, *self._last, unit)
        mask, y0 = rim_mask(crop, eyes, unit)
        self.seen = self.seen or mask is not None
        self._last = None if mask is None else (mask, y0)
        self.wait = (RIM_REUSE if self.seen else RIM_CHECK_EVERY) - 1
        return crop if mask is None else filled(crop, mask, y0, unit)
