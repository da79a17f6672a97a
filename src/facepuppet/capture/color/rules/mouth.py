"""The mouth's rule of §3.2 (Fig. 3): the lip curves moved onto the mouth blob and the opening inside it.

Corners and outer lips come from the blob's outline, inner lips from the mouth opening inside it (dark pixels,
or pixels the blob leaves out between its top and bottom, as teeth), or the lip crease when the mouth is closed.
Both lips keep at least the layout's thickness (pale lips outside a blob that is the opening alone, an upper
lip's pale top left out of it); an open mouth's lower lip at most :data:`LOWER_THICKNESS` of it (a tongue the
colour of the lips filling the opening below its dark part).

Conventions: crop pixels, x right, y down; curves (C, 4, 2) in :data:`~facepuppet.capture.curves.CURVE_NAMES`
order; ``unit`` is crop pixels per face unit; ``value`` the HSV value V (0..255).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from facepuppet._util.jit import INNER, KERNEL
from facepuppet.capture.color.blobs import blob_kernel
from facepuppet.capture.color.eye_anchors import skin_reference
from facepuppet.capture.color.rules.hair import hair_trim, is_grey, red_chroma
from facepuppet.capture.color.rules.kernels import MID_SHARE, median, median_of_boxes, mid_shift, mid_y, sample_profile
from facepuppet.capture.color.rules.opening import OPENING_MIN_WIDTH, TEETH_SATURATION, mouth_opening, saturation
from facepuppet.capture.curves import CURVE_NAMES

__all__ = ["mouth_outlines"]

_I = {n: i for i, n in enumerate(CURVE_NAMES)}
_LIPS = np.array([_I["lip_upper_outer"], _I["lip_lower_outer"], _I["lip_upper_inner"], _I["lip_lower_inner"]])

#: Bounds (face units) of the lips' middle points around the layout: outer upper, outer lower, inner upper,
#: inner lower (the lower lips move down with the jaw).
LIP_LOW = np.array([-0.15, -0.15, -0.15, -0.15])
LIP_HIGH = np.array([0.15, 0.8, 0.15, 0.8])

# Tuning constants         unit          what it does
MOUTH_NEAR = 0.3           # face units    radius around the layout's mouth centre where the lip blob is preferred
BLOB_MIN_AREA = 3          # pixels        smallest blob that counts (:func:`~.blobs.blob_kernel`)
MOUTH_MIN_COLUMNS = 4      # columns       fewest columns of the mouth blob for the lips to be read
MOUTH_FOLLOW = 0.3         # face units    farthest the lips' and corners' bounds follow the blob (up, down, sideways)
FOLLOW_SPAN = 0.6          # fraction      of the layout's mouth width the blob must span for the bounds to follow it
LIP_GAP = 0.1              # face units    gap in a column across which a lip part beyond the blob joins it
LIP_EXTEND = 0.25          # face units    farthest a column's outer lip edge is moved out across such gaps
LOWER_THICKNESS = 1.5      # fraction      of the layout's lower lip thickness an open mouth's lower lip keeps at most
OPEN_HEIGHT = 1.3          # fraction      of the layout's mouth height (outer lips) past which the mouth is open
CORNER_SEARCH = 0.15       # face units    farthest inside the blob's end a column crossing the lips' line is looked for
CORNER_DEPTH = 0.08        # fraction      of the skin's V the line is darker than the lip above and below it


@nb.njit(**INNER)
def _extend(sub: np.ndarray, level: float, cols: np.ndarray, top: np.ndarray, bottom: np.ndarray, hair: np.ndarray,
            beard: np.ndarray, gap: int, most: int):
    """The blob's column profile moved out across short gaps onto lip parts the blob left out.

    A glossy lower lip's highlight or the upper teeth can cut a lip off the blob (the blob then ends at the
    mouth opening): in each column, a run of pixels above ``level`` that starts within ``gap`` pixels beyond
    the blob's top (bottom) moves the top (bottom) to the run's far end, at most ``most`` pixels out; not over
    hair above (``hair`` (W,) bool) or below (``beard``).
    Returns the new (top, bottom), (W,) float32.
    """
    h, w = sub.shape
    otop = top.copy()
    obot = bottom.copy()
    for x in range(w):
        if not cols[x]:
            continue
        # Downwards from the blob's bottom (not over a beard).
        y = int(bottom[x])
        limit = y if beard[x] else min(y + most, h)
        start = -1
        for yy in range(y, min(y + gap, limit)):
            if sub[yy, x] > level:
                start = yy
                break
        if start >= 0:
            yy = start
            while yy < limit and sub[yy, x] > level:
                yy += 1
            obot[x] = yy
        # Upwards from the blob's top (not over hair, ``hair`` (W,) bool).
        if hair[x]:
            continue
        y = int(top[x]) - 1
        limit = max(int(top[x]) - most, 0)
        start = -1
        for yy in range(y, max(y - gap, limit - 1), -1):
            if sub[yy, x] > level:
                start = yy
                break
        if start >= 0:
            yy = start
            while yy >= limit and sub[yy, x] > level:
                yy -= 1
            otop[x] = yy + 1
    return otop, obot


@nb.njit(**INNER)
def _darkest_row(value: np.ndarray, cols: np.ndarray, top: np.ndarray, bottom: np.ndarray, xa: int, xb: int) -> float:
    """Mean over the columns ``xa`` .. ``xb - 1`` holding the blob of the centre of each one's darkest pixel
    (lowest V) between its ``top`` and ``bottom`` (rectangle pixels)."""
    total = 0.0
    n = 0
    for x in range(max(xa, 0), min(xb, len(cols))):
        if not cols[x] or bottom[x] <= top[x]:
            continue
        best = np.inf
        arg = int(top[x])
        for y in range(int(top[x]), min(int(bottom[x]), value.shape[0])):
            if value[y, x] < best:
                best = value[y, x]
                arg = y
        total += arg + 0.5
        n += 1
    return total / n if n else 0.5 * (top[xa] + bottom[xa])


@nb.njit(**INNER)
def _corner_row(value: np.ndarray, cols: np.ndarray, top: np.ndarray, bottom: np.ndarray, end: int, step: int,
                reach: int, depth: float) -> float:
    """y (rectangle pixels) of the line where the lips meet next to one end of the blob: the mean centre of the
    darkest pixel of the first 3 columns from ``end`` going ``step`` (1 from the left end, -1 from the right),
    within ``reach`` columns, whose darkest pixel is ``depth`` darker (V) than the brightest pixel of the column
    both above and below it; without such columns, of the 3 end columns' darkest pixels (:func:`_darkest_row`)."""
    total = 0.0
    n = 0
    x = end
    for _ in range(reach + 1):
        if n == 3 or not 0 <= x < len(cols):
            break
        if cols[x] and bottom[x] - top[x] >= 3:
            a, b = int(top[x]), min(int(bottom[x]), value.shape[0])
            arg = a
            for y in range(a, b):
                if value[y, x] < value[arg, x]:
                    arg = y
            above = 0.0
            below = 0.0
            for y in range(a, arg):
                above = max(above, float(value[y, x]))
            for y in range(arg + 1, b):
                below = max(below, float(value[y, x]))
            low = float(value[arg, x])
            if above - low >= depth and below - low >= depth:
                total += arg + 0.5
                n += 1
        x += step
    if n:
        return total / n
    if step > 0:
        return _darkest_row(value, cols, top, bottom, end, end + 3)
    return _darkest_row(value, cols, top, bottom, max(end - 2, 0), end + 1)


@nb.njit(**KERNEL)
def mouth_outlines(C: np.ndarray, value: np.ndarray, rgb: np.ndarray, layout: np.ndarray, offset: np.ndarray,
                   out: np.ndarray, boxes: np.ndarray, params: np.ndarray, unit: float, reach: float) -> None:
    """Lips from the mouth blob (§3.2, Fig. 3): corners and outer lips from its outline, inner lips from the
    mouth opening inside it, written into ``out`` (C, 4, 2). ``rgb`` (H, W, 3) uint8 is the crop. ``boxes``: the
    rectangles in :data:`~.outline.BOX_NAMES` order (the mouth is row 4, the cheeks rows 5 and 6). ``offset`` (2,)
    moves the layout's lips (where the mouth was seen at acquisition);
    the corners stay within ``reach`` face units of the layout's.
    """
    x0, y0, x1, y1 = boxes[4]
    lay = layout.copy()
    for c in _LIPS:
        for j in range(4):
            lay[c, j, 0] += offset[0]
            lay[c, j, 1] += offset[1]
    uo, lo, ui, li = _LIPS[0], _LIPS[1], _LIPS[2], _LIPS[3]
    cx = 0.125 * (lay[ui, :, 0].sum() + lay[li, :, 0].sum())
    cy = 0.125 * (lay[ui, :, 1].sum() + lay[li, :, 1].sum())
    sub = np.ascontiguousarray(C[y0:y1, x0:x1])
    found, mask, _, _, _, cols, top, bottom = blob_kernel(sub, params, cx - x0, cy - y0, MOUTH_NEAR * unit,
                                                          BLOB_MIN_AREA)
    if not found:
        return
    xs = np.nonzero(cols)[0]
    if len(xs) < MOUTH_MIN_COLUMNS:
        return
    # The mouth's height on the face differs between people: the bounds of the upper lips and the corners
    # follow the mouth's upper edge (the blob's, or the opening's where teeth put it higher; the upper lip
    # moves least with the expressions) at the layout's middle columns, within MOUTH_FOLLOW.
    # A blob much narrower than the mouth is a part of it (a corner's shadow, a moustache's tip, a greyscale
    # face's crease): where it lies says nothing of where the mouth is, and the bounds stay the layout's.
    lx_l, lx_r = lay[uo, 0, 0], lay[uo, 3, 0]
    ly_l, ly_r = lay[uo, 0, 1], lay[uo, 3, 1]
    spans = xs[-1] + 1 - xs[0] >= FOLLOW_SPAN * (lx_r - lx_l)
    skin = median_of_boxes(value, boxes[5:7])
    # Teeth are the mouth's unsaturated pixels: on a face whose skin is grey itself (a greyscale picture) there
    # is no telling them from the skin, and no teeth are taken.
    cheeks = np.empty(2)
    for i in range(2):
        bx0, by0, bx1, by1 = boxes[5 + i]
        cs = saturation(rgb, bx0, by0, bx1, by1)
        cheeks[i] = median(cs.ravel()) if cs.size else 0.0
    sat_max = TEETH_SATURATION * median(cheeks)
    # Hair above and below the lips (less red than the cheeks, the lips redder) is left out of the blob.
    cr = red_chroma(rgb, x0, y0, x1, y1)
    skin_cr = 128.0 + skin_reference(rgb, boxes[5:7])[1]
    top, bottom, hair_top, beard = hair_trim(cr, cols, top, bottom, skin_cr, cy - y0, unit)
    for x in range(len(cols)):
        if hair_top[x] or beard[x]:
            mask[:int(top[x]), x] = 0
            mask[int(bottom[x]):, x] = 0
    itop, ibot, ltop, lit = mouth_opening(mask, cols, top, bottom, value[y0:y1, x0:x1],
                                     saturation(rgb, x0, y0, x1, y1), skin, sat_max, cy - y0, unit, cr, skin_cr)
    hair = (ltop > top) | hair_top
    top = ltop
    if hair.sum() >= MOUTH_MIN_COLUMNS:
        # A moustache reaches past the mouth's corners: the corners lie at the last columns holding lip.
        lips_at = np.nonzero(cols & lit)[0]
        if len(lips_at) >= MOUTH_MIN_COLUMNS:
            xs = lips_at
    xc = int(0.5 * (lx_l + lx_r)) - x0
    half = max(int(0.1 * unit), 1)
    n_top = 0
    tops = np.empty(2 * half + 1)
    for x in range(max(xc - half, 0), min(xc + half + 1, len(cols))):
        if cols[x]:
            tops[n_top] = min(top[x], itop[x]) + y0
            n_top += 1
    dy = 0.0
    if n_top and spans:
        dy = min(max(median(tops[:n_top]) - mid_y(lay[uo]), -MOUTH_FOLLOW * unit), MOUTH_FOLLOW * unit)
    b = reach * unit
    # Sideways too (the mouth slides across the face frame when the head turns): the corners' bounds follow
    # the blob's middle.
    dx = 0.0
    if spans:
        dx = min(max(0.5 * (xs[0] + xs[-1] + 1) + x0 - 0.5 * (lx_l + lx_r), -MOUTH_FOLLOW * unit),
                 MOUTH_FOLLOW * unit)
    xl = min(max(xs[0] + x0, lx_l + dx - b), lx_l + dx + b)
    xr = min(max(xs[-1] + 1 + x0, lx_r + dx - b), lx_r + dx + b)
    # The corners lie where the lips meet: a column whose darkest pixel has brighter lip both above and below it
    # crosses that line (the corner's shadow); the blob's last columns may be only the lower lip's rim or the
    # shade beyond it (a slope, no line): the corners lie on the line in the outermost columns that cross it.
    vsub = value[y0:y1, x0:x1]
    reach_cols = int(CORNER_SEARCH * unit + 0.5)
    depth = CORNER_DEPTH * skin
    yl = _corner_row(vsub, cols, top, bottom, xs[0], 1, reach_cols, depth)
    yr = _corner_row(vsub, cols, top, bottom, xs[-1], -1, reach_cols, depth)
    yl = min(max(yl + y0, ly_l + dy - b), ly_l + dy + b)
    yr = min(max(yr + y0, ly_r + dy - b), ly_r + dy + b)
    for c in _LIPS:
        l0, l1 = lay[c, 0, 0], lay[c, 3, 0]
        # Each curve keeps its end offsets from the outer corners (inner lip ends lie inside the mouth).
        a0, a1 = xl + (l0 - lx_l), xr + (l1 - lx_r)
        for j in range(4):
            out[c, j, 0] = a0 + (lay[c, j, 0] - l0) * (a1 - a0) / max(l1 - l0, 1e-6)
        out[c, 0, 1] = yl + (lay[c, 0, 1] - ly_l)
        out[c, 3, 1] = yr + (lay[c, 3, 1] - ly_r)
    etop, ebot = _extend(sub, params[1], cols, top, bottom, hair, beard, int(LIP_GAP * unit + 0.5),
                         int(LIP_EXTEND * unit + 0.5))
    # Outer lips: the blob's outline, moved out across gaps; inner lips: the opening inside it.
    profiles = np.empty((4, len(top)), np.float32)
    for x in range(len(top)):
        profiles[0, x], profiles[1, x], profiles[2, x], profiles[3, x] = etop[x], ebot[x], itop[x], ibot[x]
    for i in range(4):
        c = _LIPS[i]
        ok, y = sample_profile(out[c], cols, profiles[i] + y0, x0)
        if ok:
            d = mid_shift(out[c], y)
            centre = dy if c == uo or c == ui else 0.0
            for j in (1, 2):
                lo_b, hi_b = lay[c, j, 1] + centre + LIP_LOW[i] * unit, lay[c, j, 1] + centre + LIP_HIGH[i] * unit
                out[c, j, 1] = min(max(out[c, j, 1] + d, lo_b), hi_b)
    for j in (1, 2):
        out[ui, j, 1] = min(out[ui, j, 1], out[lo, j, 1])
        out[li, j, 1] = min(max(out[li, j, 1], out[ui, j, 1]), out[lo, j, 1])
        # Both lips keep at least the layout's thickness beyond the inner ones (the blob may be the opening
        # alone, its lips pale; a pale lower lip, or the upper lip's pale top, is left out of the blob).
        out[lo, j, 1] = max(out[lo, j, 1], out[li, j, 1] + lay[lo, j, 1] - lay[li, j, 1])
        out[uo, j, 1] = min(out[uo, j, 1], out[ui, j, 1] - max(lay[ui, j, 1] - lay[uo, j, 1], 0.0))
    # An open mouth (a dark gap between the inner lips, or the outer lips much farther apart than the layout's)
    # has lips of about their own thickness. Its lower lip is no thicker than LOWER_THICKNESS of the layout's:
    # a tongue or lower teeth that are not dark fill the opening under its dark part, and the inner lower lip
    # lies that far above the outer one.
    height = mid_y(out[lo]) - mid_y(out[uo])
    grey = is_grey(skin_cr)
    if mid_y(out[li]) - mid_y(out[ui]) > OPENING_MIN_WIDTH * unit or \
            height > OPEN_HEIGHT * (mid_y(lay[lo]) - mid_y(lay[uo])):
        extra = mid_y(out[lo]) - mid_y(out[li]) - LOWER_THICKNESS * (mid_y(lay[lo]) - mid_y(lay[li]))
        if extra > 0 and not grey:
            for j in (1, 2):
                out[li, j, 1] += extra / MID_SHARE
