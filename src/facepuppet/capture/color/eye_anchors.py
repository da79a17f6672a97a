"""The colour tracker's eye search.

The colour tracker aligns its face frame on the eyes: the centres it finds (:func:`eye_opening_centres`: the
height by mean shift of the darkness under the skin's luma, :func:`dark_centres`; the place along the eye the
midpoint of the eye's opening, which dark makeup, shadows and the gaze do not move) are mapped onto the
profile's eye anchors, and the layout follows. A trained profile's anchors are learnt where :func:`eye_centres`
lands on the performer's own labelled frames, which calibrates its bias on that face out, so with it the tracker
uses the mean shift alone; the opening's place is for the generic profile's average anchors. Where the height
found sits relative to the eye itself depends on the performer (lashes, lid shadows, brows close above): the
generic anchors may put the layout a little off: :mod:`.eye_calibration` moves them onto the landmark backend's
eyes where that backend is available.

Conventions: crop pixels of one face crop (x right, y down); an eye centre is the mean of the points along the
eye's upper and lower lid curves, right eye first (as in the anchors).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from facepuppet._util.jit import INNER, KERNEL
from facepuppet.capture.color.lids import EYES
from facepuppet.capture.color.white_lit import white_lit
from facepuppet.capture.curves import bezier_points

__all__ = ["EYE_STEPS", "EYE_LEAST", "EYE_TALL", "EYE_TALL_LEVEL", "OPENING", "OPENING_TABLE", "eye_centres",
           "darkness", "without_long_runs", "without_tall_runs", "dark_centres",
           "eye_opening_centres", "eye_centres_of", "skin_reference"]

# Tuning constants of the eye search (eye_centres)
EYE_STEPS = 3         # steps       mean-shift steps of the search from the anchors
EYE_LEAST = 0.01      # C^2         least mean of C^2 over a window for it to hold an eye
EYE_TALL = 0.6        # face units  longest run of C down a column the search keeps (taller: beside the face)
EYE_TALL_LEVEL = 0.3  # C           from which a pixel of C belongs to a run (:func:`without_tall_runs`)

#: The eye opening's extent (eye_opening_centres): name -> (value, unit, meaning).
OPENING = {
    "chroma": (0.6, "skin chroma", "most chroma along the skin's (Cr, Cb) direction of an opening pixel"),
    "luma": (0.3, "skin luma", "least luma of an opening pixel (lashes, eyeliner and pupil are darker)"),
    "tail": (0.03, "share", "share of the opening's pixels left out at each end of its extent"),
    "least": (0.015, "face units^2", "least area of opening pixels for the extent to be read"),
    "full": (0.03, "face units^2", "area of opening pixels from which the extent alone places the eye"),
    "outset": (0.0, "face units", "how far outward of the corners' midpoint the extent's midpoint lies"),
    "steps": (2, "steps", "times the window is re-centred on the extent's midpoint"),
    "above": (0.06, "face units", "the window's reach above the height found (the lash line's)"),
    "below": (0.14, "face units", "the window's reach below the height found"),
    "local": (0.05, "face units", "half size of the box whose mean luma an opening pixel must exceed"),
    "lift": (1.0, "local luma", "how far an opening pixel's luma must exceed its box's mean (a share of it)"),
    "half_width": (0.3, "face units", "half width of the window the opening is looked for in"),
    "agree": (0.1, "face units", "farthest the opening's place may lie from the mean shift's (on the eye's blob)"),
    "wider": (1.15, "ratio", "most one eye's opening may be wider than the other's (cut at its outer end)"),
    "dark_low": (0.3, "skin luma", "how far under the skin's luma (a share of it) a pixel's darkness starts (the "
                 "eye search's mean shift)"),
    "dark_high": (0.8, "skin luma", "how far under the skin's luma a pixel is fully dark"),
    "dark_above": (0.1, "face units", "the mean shift's reach above the eye (its reach below: the eye window's)"),
    "dark_agree": (0.08, "face units", "farthest the darkness's place may lie from C's, each way, to be taken"),
    "dark_level": (0.5, "darkness", "darkness from which a pixel belongs to a dark run (the runs' test)"),
    "dark_wide": (0.5, "face units", "longest horizontal dark run the eye's darkness keeps (wider: a rim, brows)"),
    "tall": (0.3, "face units", "run of pixels of the opening's colour down a column from the window's bottom row "
             "from which the column is left out (a wall beside a turned head runs on; the cheek lies under an eye)"),
}

def eye_centres_of(curves: np.ndarray, samples: int = 16) -> np.ndarray:
    """Eye centres (2, 2), right eye first: the mean of ``samples`` points along each eye's two lid curves.

    ``curves`` (C, 4, 2) in CURVE_NAMES order, any coordinates.
    """
    return np.array([np.concatenate([bezier_points(curves[i], samples) for i in lids]).mean(axis=0)
                     for lids in EYES])


_OPENING_ORDER = ("chroma", "luma", "tail", "least", "full", "outset", "steps", "above", "below", "local", "lift",
                  "half_width", "wider", "agree", "dark_low", "dark_high", "dark_above", "dark_agree", "dark_level",
                  "dark_wide", "tall")


def _opening_table() -> np.ndarray:
    """The values of :data:`OPENING` as float64, the form the kernel takes."""
    return np.array([OPENING[k][0] for k in _OPENING_ORDER], dtype=np.float64)


OPENING_TABLE = _opening_table()


@nb.njit(**KERNEL)
def eye_centres(C: np.ndarray, anchors: np.ndarray, half_w: int, half_h: int):
    """Eye centres (2, 2) in crop pixels by :data:`EYE_STEPS` mean-shift steps of C² around the expected anchors.

    ``C``: (H, W) float32 contrast C; ``anchors``: (>= 2, 2) expected centres, right eye first; the window is
    ``2 half_w + 1`` by ``2 half_h + 1`` pixels.

    Returns (ok, centres): ok is False when a window holds too little feature intensity.
    """
    h, w = C.shape
    out = np.zeros((2, 2))
    least = EYE_LEAST * (2 * half_w + 1) * (2 * half_h + 1)
    for k in range(2):
        cx, cy = anchors[k, 0], anchors[k, 1]
        for _ in range(EYE_STEPS):
            x0 = int(np.round(cx)) - half_w
            y0 = int(np.round(cy)) - half_h
            xa, ya = max(x0, 0), max(y0, 0)
            xb, yb = min(x0 + 2 * half_w + 1, w), min(y0 + 2 * half_h + 1, h)
            total = sx = sy = 0.0
            for y in range(ya, yb):
                for x in range(xa, xb):
                    v = float(C[y, x]) ** 2
                    total += v
                    sx += v * (x - xa)
                    sy += v * (y - ya)
            if total < least:
                return False, out
            cx, cy = sx / total + xa, sy / total + ya
        out[k, 0], out[k, 1] = cx, cy
    return True, out


@nb.njit(**KERNEL)
def skin_reference(crop: np.ndarray, cheeks: np.ndarray) -> np.ndarray:
    """(Y, Cr - 128, Cb - 128) medians over the cheek rectangles ``cheeks`` (K, 4) of the crop (H, W, 3) uint8."""
    n = 0
    for b in range(cheeks.shape[0]):
        n += max(cheeks[b, 2] - cheeks[b, 0], 0) * max(cheeks[b, 3] - cheeks[b, 1], 0)
    vals = np.empty((3, max(n, 1)))
    i = 0
    for b in range(cheeks.shape[0]):
        for y in range(max(cheeks[b, 1], 0), min(cheeks[b, 3], crop.shape[0])):
            for x in range(max(cheeks[b, 0], 0), min(cheeks[b, 2], crop.shape[1])):
                r, g, bl = float(crop[y, x, 0]), float(crop[y, x, 1]), float(crop[y, x, 2])
                luma = 0.299 * r + 0.587 * g + 0.114 * bl
                vals[0, i], vals[1, i], vals[2, i] = luma, 0.713 * (r - luma), 0.564 * (bl - luma)
                i += 1
    out = np.zeros(3)
    if i > 0:
        for c in range(3):
            out[c] = np.median(vals[c, :i])
    return out


@nb.njit(**KERNEL)
def darkness(crop: np.ndarray, skin_luma: float, low: float, high: float) -> np.ndarray:
    """(H, W) float32 in [0, 1]: how much darker than the skin each pixel of the crop (H, W, 3) uint8 RGB is, a
    smoothstep of (skin_luma - Y) / skin_luma from ``low`` to ``high`` (luma Y as :func:`skin_reference`'s).

    Lashes, iris and pupil are darker than the skin around them whatever the complexion and the light's colour;
    the contrast C measures a colour feature whose scale is set by the darkest, most saturated pixels of the
    crop, which a dark complexion moves to the lash line and the hair.
    """
    return _darkness_rows(crop, skin_luma, low, high, 0, crop.shape[0])


@nb.njit(**INNER)
def _darkness_rows(crop: np.ndarray, skin_luma: float, low: float, high: float, y0: int, y1: int) -> np.ndarray:
    """:func:`darkness` in the rows ``y0 <= y < y1`` (clipped to the crop); 0 in the others."""
    h, w = crop.shape[:2]
    out = np.zeros((h, w), np.float32)
    inv = 1.0 / max((high - low) * skin_luma, 1e-6)
    for y in range(max(y0, 0), min(y1, h)):
        for x in range(w):
            v = 0.299 * float(crop[y, x, 0]) + 0.587 * float(crop[y, x, 1]) + 0.114 * float(crop[y, x, 2])
            t = min(max((skin_luma * (1.0 - low) - v) * inv, 0.0), 1.0)
            out[y, x] = t * t * (3.0 - 2.0 * t)
    return out


@nb.njit(**KERNEL)
def without_long_runs(D: np.ndarray, level: float, wide: int) -> np.ndarray:
    """A copy of the darkness ``D`` (H, W) float32 with the pixels of its dark runs along a row (consecutive
    pixels with ``D >= level``) longer than ``wide`` pixels set to 0.

    The eye's dark parts (lashes, iris, pupil) make a blob about as wide as the eye; a glasses rim's top and
    bottom and the brows make longer horizontal lines, which may not draw the eye search.
    """
    out = D.copy()
    _clear_long_runs(out, level, wide, 0, D.shape[0])
    return out


@nb.njit(**INNER)
def _clear_long_runs(D: np.ndarray, level: float, wide: int, y0: int, y1: int) -> None:
    """:func:`without_long_runs` on ``D`` itself, in the rows ``y0 <= y < y1`` (clipped to it)."""
    h, w = D.shape
    for y in range(max(y0, 0), min(y1, h)):
        x = 0
        while x < w:
            if D[y, x] < level:
                x += 1
                continue
            e = x
            while e < w and D[y, e] >= level:
                e += 1
            if e - x > wide:
                D[y, x:e] = 0.0
            x = e


@nb.njit(**KERNEL)
def without_tall_runs(C: np.ndarray, level: float, tall: int) -> np.ndarray:
    """A copy of ``C`` (H, W) float32 with the pixels of its runs down a column (consecutive pixels with
    ``C >= level``) longer than ``tall`` pixels set to 0.

    An eye's feature intensity reaches from the upper lashes to the lower lid, and a brow above it is parted
    from it by the lid's skin; the hair or the background beside the face, lit against it, and a glasses rim's
    side make taller lines of C, at the eye window's outer edge on a face a little too large or off centre; they
    are left out so that they do not draw the eye search outward.
    """
    h, w = C.shape
    # Row by row (the array's own order): each pixel's run length so far from the top, then, from the bottom,
    # the whole length of the run it belongs to (its last row's count).
    run = np.zeros((h, w), np.int32)
    for y in range(h):
        for x in range(w):
            if C[y, x] >= level:
                run[y, x] = run[y - 1, x] + 1 if y > 0 else 1
    out = C.copy()
    for y in range(h - 2, -1, -1):
        for x in range(w):
            if run[y, x] > 0 and run[y + 1, x] > 0:
                run[y, x] = run[y + 1, x]
    for y in range(h):
        for x in range(w):
            if run[y, x] > tall:
                out[y, x] = 0.0
    return out


@nb.njit(**KERNEL)
def dark_centres(D: np.ndarray, anchors: np.ndarray, half_w: int, half_h: int, above: int):
    """Eye centres (2, 2) in crop pixels by :data:`EYE_STEPS` mean-shift steps of D² (``D``: (H, W) darkness,
    :func:`darkness`) around the expected ``anchors`` (>= 2, 2), right eye first, in a window ``2 half_w + 1``
    pixels wide reaching ``above`` pixels over its centre and ``half_h`` under it.

    Above the eye lie the brows, as dark as the lashes, at a face's own distance (close on some faces); under
    it nothing as dark down to the nostrils: the window reaches less far up than down.

    Returns (ok, centres): ok is False when a window holds no darkness.
    """
    h, w = D.shape
    out = np.zeros((2, 2))
    for k in range(2):
        cx, cy = anchors[k, 0], anchors[k, 1]
        for _ in range(EYE_STEPS):
            x0 = int(np.round(cx)) - half_w
            yc = int(np.round(cy))
            xa, ya = max(x0, 0), max(yc - above, 0)
            xb, yb = min(x0 + 2 * half_w + 1, w), min(yc + half_h + 1, h)
            total = sx = sy = 0.0
            for y in range(ya, yb):
                for x in range(xa, xb):
                    v = float(D[y, x]) ** 2
                    total += v
                    sx += v * x
                    sy += v * y
            if total <= 0.0:
                return False, out
            cx, cy = sx / total, sy / total
        out[k, 0], out[k, 1] = cx, cy
    return True, out


@nb.njit(**INNER)
def _band(crop: np.ndarray, bt: int, bb: int, gains: np.ndarray, skin: np.ndarray, middle: float, lit: bool):
    """The luma of the crop's rows bt..bb-1 ((bb - bt, W)), its integral image ((bb - bt + 1, W + 1): row i + 1
    sums the band's rows up to i) and each pixel's chroma projected on its side's skin chroma; with ``lit``, of the
    crop's pixels times their side's ``gains`` (2, 3), else as they are (and both sides' ``skin`` the same);
    ``skin`` (2, 3): each side's (luma, Cr - 128, Cb - 128); the sides are the columns left and right of
    ``middle``."""
    w = crop.shape[1]
    n = max(bb - bt, 0)
    luma = np.empty((n, w))
    proj = np.empty((n, w))
    integral = np.zeros((n + 1, w + 1))
    cr, cb = skin[0, 1], skin[0, 2]
    for i in range(n):
        y = bt + i
        row = 0.0
        for x in range(w):
            r, g, bl = float(crop[y, x, 0]), float(crop[y, x, 1]), float(crop[y, x, 2])
            if lit:
                side = 1 if x >= middle else 0
                r, g, bl = r * gains[side, 0], g * gains[side, 1], bl * gains[side, 2]
                cr, cb = skin[side, 1], skin[side, 2]
            v = 0.299 * r + 0.587 * g + 0.114 * bl
            luma[i, x] = v
            proj[i, x] = 0.713 * (r - v) * cr + 0.564 * (bl - v) * cb
            row += v
            integral[i + 1, x + 1] = integral[i, x + 1] + row
    return luma, proj, integral


@nb.njit(**INNER)
def _openings(luma: np.ndarray, proj: np.ndarray, integral: np.ndarray, skin: np.ndarray, middle: float,
              anchors: np.ndarray, out: np.ndarray, rows: tuple, unit: float, table: np.ndarray):
    """Each eye's opening in the band of :func:`_band` (``rows``: the band's top row, the local boxes' bottom row,
    the band's bottom row, the local box's half size, the runs' length and the crop's height, pixels): its ends
    (2, 2) (inner and outer, crop pixels), whether it was read (2,) and its area (2,) (pixels), in the windows of
    :func:`eye_opening_centres`, around ``anchors`` along the eye and at the heights of ``out``."""
    bt, box_bottom, bb, r_box, tall, h = rows
    w = luma.shape[1]
    most_chroma = np.empty(2)
    least_luma = np.empty(2)
    for side in range(2):
        most_chroma[side] = table[0] * (skin[side, 1] * skin[side, 1] + skin[side, 2] * skin[side, 2])
        least_luma[side] = table[1] * skin[side, 0]
    least = table[3] * unit * unit
    half = max(int(np.round(table[11] * unit)), 1)
    cols = np.zeros(2 * half + 1)
    ends = np.zeros((2, 2))                 # each eye's opening: inner and outer end, crop pixels
    seen = np.zeros(2, np.bool_)
    area = np.zeros(2)                      # opening pixels of each eye in the last window read
    for k in range(2):
        cx, cy = anchors[k, 0], out[k, 1]
        out_dir = -1.0 if k == 0 else 1.0   # outward along x: the right eye is at the image's left
        y0 = max(int(np.round(cy - table[7] * unit)), 0)
        y1 = min(int(np.round(cy + table[8] * unit)) + 1, h)
        for _ in range(int(table[6])):
            x0 = int(np.round(cx)) - half
            cols[:] = 0.0
            n = 0.0
            for x in range(max(x0, 0), min(x0 + 2 * half + 1, w)):
                xa, xb = max(x - r_box, 0), min(x + r_box + 1, w)
                side = 1 if x >= middle else 0
                chroma_max, luma_min = most_chroma[side], least_luma[side]
                # A column outward of the eye's expected centre whose pixels of the opening's colour run on for
                # ``tall`` down from the window's bottom row is a light wall beside the face (a turned head's far
                # eye), not an eye's white: under an eye (and under a lens's reflection) lies the cheek. Inward,
                # under the inner corner, a lit nose or cheek may be as pale, and the background never lies there.
                if (x - anchors[k, 0]) * out_dir > 0.0:
                    run = 0
                    for y in range(y1 - 1, min(y1 - 1 + tall, bb)):
                        if proj[y - bt, x] >= chroma_max or luma[y - bt, x] <= luma_min:
                            break
                        run += 1
                    if run >= tall:
                        continue
                for y in range(y0, y1):
                    v = luma[y - bt, x]
                    if proj[y - bt, x] >= chroma_max or v <= luma_min:
                        continue
                    ya, yb = max(y - r_box, bt), min(y + r_box + 1, box_bottom)
                    ia, ib = ya - bt, yb - bt
                    local = (integral[ib, xb] - integral[ia, xb] - integral[ib, xa] + integral[ia, xa]) / (
                        (yb - ya) * (xb - xa))
                    if v >= table[10] * local:
                        cols[x - x0] += 1.0
                        n += 1.0
            if n < least:
                break
            # The columns (interpolated) where the running count passes tail and 1 - tail of the pixels.
            lo, hi = table[2] * n, (1.0 - table[2]) * n
            run = 0.0
            a = b = -1.0
            for j in range(cols.size):
                nxt = run + cols[j]
                if a < 0 and nxt >= lo:
                    a = j + (lo - run) / cols[j]
                if b < 0 and nxt >= hi:
                    b = j + (hi - run) / cols[j]
                run = nxt
            a, b = x0 + a - 0.5, x0 + b - 0.5
            ends[k, 0], ends[k, 1] = (b, a) if k == 0 else (a, b)
            cx = 0.5 * (a + b) - out_dir * table[5] * unit
            seen[k] = True
            area[k] = n
    return ends, seen, area


@nb.njit(**KERNEL)
def eye_opening_centres(C: np.ndarray, crop: np.ndarray, cheeks: np.ndarray, anchors: np.ndarray, half_w: int,
                        half_h: int, unit: float, table: np.ndarray, dark: bool):
    """Eye centres (2, 2) in crop pixels: the height by mean shift of the darkness under the skin's luma
    (:func:`dark_centres`), the position along the eye the midpoint of the extent of the eye's opening, which is
    the midpoint of its corners.

    The contrast C (a colour feature) tells whether a window holds an eye at all (:func:`eye_centres`' test);
    where in it the eye lies is read off the luma: on a dark complexion the iris is as coloured as the skin and C
    carries the lash line and the hair beside the face, off to the eye's upper and outer side, while lashes,
    iris and pupil are darker than the skin on every face. The darkness's dark runs longer than ``dark_wide``
    across (glasses rims, brows; :func:`without_long_runs`) are left out, and the darkness's place is taken only
    within ``dark_agree`` of C's (a lens's reflection weakens the eye, the rims beside it draw the darkness).
    Without ``dark``
    (the acquisition: its candidate frames may sit off the face, where the darkness takes in the hair and the
    face's sides) or without skin luma the mean shift of C places it.

    The opening (white of the eye, a light iris) is told from skin by its colour and from lashes, eyeliner,
    pupil and shadow by its light: a pixel belongs to it when its chroma along the cheeks' (Cr, Cb) direction
    is under ``chroma`` of the cheeks', its luma over ``luma`` of the cheeks' and at least ``lift`` times the
    mean luma of the box of half size ``local`` around it (the white of a shadowed eye is still lighter than
    the lashes and iris beside it; the blurred rim of a dark area is not). An eye whose opening covers less than
    ``full`` so, on a side of the crop whose cheek's colour says the light is coloured, is looked for again in the
    colours that side would have in a white light (:func:`~.white_lit.white_lit`: its cheek brought to an average
    skin's chromaticity, the test against that skin), and that opening is taken where it is larger: a warm lamp
    tints the white with the skin's colour. Dark makeup beyond the corners (an eyeliner's wing) and where the
    iris sits (the gaze) do not move the extent, as they move a mean of the feature intensity. In a window
    ``half_width`` face units either side of the expected centre, from ``above`` over to ``below`` under the
    height found, the extent runs between the columns that leave out
    ``tail`` of the opening's pixels at either end; the window is re-centred on its midpoint ``steps`` times.
    A column outward of the expected centre whose pixels of the opening's chroma and luma run on for ``tall``
    down from the window's bottom row is left out: a light wall beside a turned head's far eye runs on, under an
    eye's white lies the cheek.
    The two eyes are the same size: an opening wider than ``wider`` times the other's has taken in something
    beyond its outer corner (pale makeup or skin, the background by a turned head), and its outer end is cut
    back to that width. The centre is the extent's midpoint moved inward by ``outset`` face units. An eye
    whose opening covers less than ``least`` face units² (closed, or in deep shadow) keeps the mean shift's
    position; from ``least`` to ``full`` the position goes over linearly from that to the opening's,
    which is kept within ``agree`` of the mean shift's (the mean shift holds to the dark eye; a window
    off the eye may see pale skin, hair or the background beside it).
    The names are those of :data:`OPENING`, in ``table`` in :data:`OPENING_TABLE`'s order.

    ``C``: (H, W) float32 contrast C; ``crop``: (H, W, 3) uint8 RGB face crop; ``cheeks``: (K, 4) int64 skin
    rectangles x0, y0, x1, y1; ``anchors``: (>= 2, 2) expected centres, right eye (image left) first;
    ``half_w``, ``half_h``: :func:`eye_centres`' window; ``unit``: crop pixels per face unit; ``dark``: whether
    the darkness places the eye (a followed face).

    Returns (ok, centres): ok as :func:`eye_centres`'.
    """
    ok, out = eye_centres(C, anchors, half_w, half_h)
    if not ok:
        return ok, out
    skin = skin_reference(crop, cheeks)
    # The eye's place by the darkness, in a window reaching dark_above over it (the brows lie above).
    if dark and skin[0] > 1.0:
        above = min(int(np.round(table[16] * unit)), half_h)
        # Only the rows the mean shift can reach: each step's centre lies in its window, which reaches ``above``
        # over it and ``half_h`` under it (and one pixel either way for the rounding of the centre).
        r0 = int(np.floor(min(anchors[0, 1], anchors[1, 1]))) - EYE_STEPS * (above + 1) - 1
        r1 = int(np.ceil(max(anchors[0, 1], anchors[1, 1]))) + EYE_STEPS * (half_h + 1) + 2
        D = _darkness_rows(crop, skin[0], table[14], table[15], r0, r1)
        _clear_long_runs(D, table[18], int(np.round(table[19] * unit)), r0, r1)
        found, dark = dark_centres(D, anchors, half_w, half_h, above)
        if found:
            # Where the two part by more than ``dark_agree``, the darkness has been drawn off the eye (a rim,
            # the hair beside the face) and C's place stands.
            near = table[17] * unit
            for k in range(2):
                if abs(dark[k, 0] - out[k, 0]) <= near and abs(dark[k, 1] - out[k, 1]) <= near:
                    out[k, 0], out[k, 1] = dark[k, 0], dark[k, 1]
    h, w = C.shape
    s2 = skin[1] * skin[1] + skin[2] * skin[2]
    if s2 < 1.0:
        return ok, out                      # no skin chroma to tell the opening from
    r_box = max(int(np.round(table[9] * unit)), 1)
    # The band of rows the two windows and their boxes cover, and ``tall`` further down (the runs' test).
    tall = max(int(np.round(table[20] * unit)), 2)
    bt = max(int(np.round(min(out[0, 1], out[1, 1]) - table[7] * unit)) - r_box, 0)
    box_bottom = min(int(np.round(max(out[0, 1], out[1, 1]) + table[8] * unit)) + 1 + r_box, h)
    bb = min(box_bottom + tall, h)
    middle = 0.5 * (anchors[0, 0] + anchors[1, 0])
    rows = (bt, box_bottom, bb, r_box, tall, h)
    plain = np.empty((2, 3))
    for side in range(2):
        plain[side, 0], plain[side, 1], plain[side, 2] = skin[0], skin[1], skin[2]
    luma, proj, integral = _band(crop, bt, bb, np.ones((2, 3)), plain, middle, False)
    ends, seen, area = _openings(luma, proj, integral, plain, middle, anchors, out, rows, unit, table)
    # An eye whose white is not told from the skin in a coloured light (a warm lamp tints it with the skin) is
    # looked for again in the colours its side would have in a white light (:mod:`.white_lit`).
    full = table[4] * unit * unit
    if area[0] < full or area[1] < full:
        gains, lit, tinted = white_lit(crop, cheeks, middle)
        if tinted[0] or tinted[1]:
            luma, proj, integral = _band(crop, bt, bb, gains, lit, middle, True)
            again = _openings(luma, proj, integral, lit, middle, anchors, out, rows, unit, table)
            for k in range(2):
                side = 1 if anchors[k, 0] >= middle else 0
                if area[k] < full and tinted[side] and again[2][k] > area[k]:
                    ends[k], seen[k], area[k] = again[0][k], again[1][k], again[2][k]
    least = table[3] * unit * unit
    # The two eyes are the same size: an opening much wider than the other's has taken in something beyond
    # its outer corner (pale makeup or skin, a reflection); it is cut to the most the other allows.
    width = np.abs(ends[:, 1] - ends[:, 0])
    for k in range(2):
        if not seen[k]:
            continue
        wk = width[k]
        if seen[1 - k]:
            wk = min(wk, table[12] * width[1 - k])
        out_dir = -1.0 if k == 0 else 1.0
        x = ends[k, 0] + out_dir * 0.5 * wk - out_dir * table[5] * unit
        # Between least and full area the place goes over smoothly from the mean shift's to the opening's.
        share = min(max((area[k] - least) / max(table[4] * unit * unit - least, 1e-9), 0.0), 1.0)
        # The opening lies on the eye's blob: its place at most ``agree`` from the mean shift's, which holds
        # to the dark eye (a window outside the eye may see pale skin, hair or the background).
        agree = table[13] * unit
        x = min(max(x, out[k, 0] - agree), out[k, 0] + agree)
        out[k, 0] = share * x + (1.0 - share) * out[k, 0]
    return ok, out
