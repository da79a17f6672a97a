"""Veiling glare taken off a face crop: a smooth colourless light added over the face (a bright window or lamp
behind or above the performer scattered in the lens, haze) measured on the skin and subtracted.

A veil adds the same light v(x, y) to the three channels, so it lifts the darker ones most and washes the skin's
colour and the features' contrast out where it is strong: Eq. 1 then reads a veiled forehead and eyes as skin
and a clear chin as features, and neither the eye search nor the likeness finds the face. The skin's own colour
tells the veil apart from the face's shading: for skin of one colour under a light of one colour, shading scales
the three channels alike, so blue is a fixed share ``k`` of red minus blue, ``B = k (R - B)``, at any shading;
a veil adds ``v`` to blue and nothing to red minus blue. Over the skin-coloured pixels (red over green over
blue, red over blue by ``chroma``, none clipped: a veil changes neither) of the face's part of the crop
(:data:`VEIL_FACE`) ``B = k (R - B) + v`` is fitted with ``v`` one level per band of rows (:data:`VEIL`
``bands``) plus a slope across, by least squares reweighted against the pixels that are not skin after all
(Huber's weights: hair, lips); the veil is the fitted field less its lowest value (a veil even over the face
only lowers the contrast, which the contrast C and the light's stretch take out). A veil also lifts the black
under it: a band is taken as veiled only as far as its dark level (the ``dark`` quantile of its pixels' darkest
channel) lies above the darkest band's too, which a clear face's dark background or hair above the forehead,
skin-like to the fit, does not show. A veil's light is scattered wide: unless a band rises ``least`` above
the lowest in both and a band next to it half as much (a reflection on a lens, a bright patch, is smaller than
two bands), the crop is left (the skin's own variation, redder cheeks and lips, gives a smaller field on a
clear face); otherwise the veil is subtracted and the crop stretched back so that its brightest (``top``)
level is where the light's stretch keeps a face's. A veil even over the face (haze, a bright scene scattered
in the lens) lifts the black of every band alike, which the light's stretch (a gain) cannot take off: on a
clear face each band of rows holding the eyes, nostrils or mouth has its darkest pixels (pupils, lashes,
nostrils, the mouth's opening) well under ``black``; the darkest band's dark level above ``black`` is taken off
everywhere, with the band veil if there is one, and the crop stretched back the same way. Where the joint fit
cannot tell a veil from the shading (its ``k`` not positive, or no spread of red minus blue to fit) but the black
rises under some bands, ``k`` is read on the bands whose black is the camera's (no veil
there) and each band's level is the median of ``B - k (R - B)`` over its skin (:func:`clear_band_levels`), taken
only where those levels rise over the bands with the dark levels (correlation ``together``).

Conventions: RGB uint8 face crops (H, W, 3) of ``px`` crop pixels per face unit, the face frame's origin at
:data:`~.face.CROP_EXTENT`; levels 8-bit.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from facepuppet._util.jit import INNER, KERNEL
from facepuppet.capture.color.face import CROP_EXTENT

__all__ = ["VEIL", "VEIL_FACE", "clear_band_levels", "veil_rows", "warmup", "without_veil"]

#: The veil's measure: name -> (value, unit, meaning).
VEIL = {
    "bands": (7, "bands", "rows of the measured part, top to bottom, each with a veil level of its own"),
    "stride": (4, "pixels", "every this many rows and columns of the crop are measured"),
    "huber": (8.0, "8-bit levels", "a pixel off the fit by more than this weighs less (not skin)"),
    "iterations": (3, "fits", "least-squares fits, each reweighted by the last one's residuals"),
    "least": (60.0, "8-bit levels", "a veil rising less than this over the face is left"),
    "chroma": (10.0, "8-bit levels", "least red over blue of a pixel measured (skin's colour; a veil keeps it)"),
    "pixels": (8, "pixels", "fewest measured pixels of a band with a level of its own"),
    "dark": (0.05, "share", "of a band's pixels darker (darkest channel) than its dark level"),
    "top": (230.0, "8-bit level", "the crop's 99th-percentile level once the veil is off"),
    "black": (60.0, "8-bit level", "the darkest band's dark level above this is an even veil"),
    "clear": (10.0, "8-bit levels", "a band whose dark level lies this near the darkest band's has no veil"),
    "together": (0.8, "correlation", "least correlation over the bands of the levels read on the clear bands' "
                 "share with the dark levels"),
}
#: The part of the crop the veil is measured on (face units x0, y0, x1, y1): the face within its outline.
VEIL_FACE = (-0.95, -0.8, 0.95, 1.7)


_BANDS, _STRIDE, _ITERATIONS, _PIXELS = (int(VEIL[k][0]) for k in ("bands", "stride", "iterations", "pixels"))
_HUBER, _LEAST, _TOP, _CHROMA, _DARK, _BLACK, _CLEAR, _TOGETHER = (
    float(VEIL[k][0]) for k in ("huber", "least", "top", "chroma", "dark", "black", "clear", "together"))


@nb.njit(**INNER)
def _skin_coloured(r, g, b, chroma: float) -> bool:
    """Whether a pixel (r, g, b uint8) has skin's order of channels, red over green over blue, red over blue by
    ``chroma`` at least (a colourless veil changes neither), no channel clipped (red under 250, blue over 5)."""
    return r < 250 and b > 5 and r >= g and g >= b and float(r) - float(b) >= chroma


@nb.njit(**KERNEL)
def veil_rows(crop: np.ndarray, x0: int, y0: int, x1: int, y1: int, bands: int, stride: int, huber: float,
              iterations: int, chroma: float, least_pixels: int, dark_share: float, least: float):
    """The veil fitted on the skin-coloured pixels (:func:`_skin_coloured` with ``chroma``) of
    ``crop[y0:y1, x0:x1]`` (every ``stride``-th row and column): ``B = k (R - B) + v_b + s (x - xc)`` by
    Huber-reweighted (``huber`` levels) least squares, ``iterations`` fits; ``v_b`` one level per band of
    ``bands`` equal bands of rows, ``s`` the slope across (per crop pixel, ``xc`` the part's middle column).

    Returns (ok, levels (bands,) float64 the bands' v_b, dark (bands,) float64 the ``dark_share`` quantile of each
    band's pixels' darkest channel (all pixels sampled), slope s, k); a band of fewer than ``least_pixels``
    skin-coloured pixels takes its nearest measured neighbour's level; ok False (nothing fitted) where no band
    has that many, or the bands' dark levels rise by less than ``least`` (no veil that large can lie over them),
    and where the fit is degenerate (no spread of red minus blue) or k is not positive.
    """
    levels = np.full(bands, np.nan)
    xc = 0.5 * (x0 + x1 - 1)
    span = max(y1 - y0, 1)
    cnt = np.zeros(bands, np.int64)
    hist = np.zeros((bands, 256), np.int64)
    ny, nx = (y1 - y0 + stride - 1) // stride, (x1 - x0 + stride - 1) // stride
    skin = np.zeros((ny, nx), np.bool_)
    for i in range(ny):
        y = y0 + i * stride
        band = min((y - y0) * bands // span, bands - 1)
        for j in range(nx):
            x = x0 + j * stride
            r, g, b = crop[y, x, 0], crop[y, x, 1], crop[y, x, 2]
            hist[band, min(r, g, b)] += 1
            if _skin_coloured(r, g, b, chroma):
                skin[i, j] = True
                cnt[band] += 1
    # Each band's dark level: the ``dark_share`` quantile of its pixels' darkest channel.
    dark = np.zeros(bands)
    for j in range(bands):
        total = hist[j].sum()
        n = 0
        for i in range(256):
            n += hist[j, i]
            if n > dark_share * total:
                dark[j] = i
                break
    if cnt.max() < least_pixels or dark.max() - dark.min() < least:
        return False, levels, dark, 0.0, 0.0
    k = 0.0
    s = 0.0
    for it in range(iterations):
        sw = np.zeros(bands)
        sa = np.zeros(bands)
        sx = np.zeros(bands)
        sb = np.zeros(bands)
        saa = sax = sxx = sab = sxb = 0.0
        for i in range(ny):
            y = y0 + i * stride
            band = min((y - y0) * bands // span, bands - 1)
            if cnt[band] < least_pixels:
                continue
            for j in range(nx):
                if not skin[i, j]:
                    continue
                x = x0 + j * stride
                r, b = float(crop[y, x, 0]), float(crop[y, x, 2])
                a, u = r - b, float(x) - xc
                w = 1.0
                if it > 0:
                    e = abs(b - k * a - s * u - levels[band])
                    w = 1.0 if e <= huber else huber / e
                sw[band] += w
                sa[band] += w * a
                sx[band] += w * u
                sb[band] += w * b
                saa += w * a * a
                sax += w * a * u
                sxx += w * u * u
                sab += w * a * b
                sxb += w * u * b
        # The bands' levels eliminated: the sums about each band's weighted means.
        for j in range(bands):
            if cnt[j] >= least_pixels:
                saa -= sa[j] * sa[j] / sw[j]
                sax -= sa[j] * sx[j] / sw[j]
                sxx -= sx[j] * sx[j] / sw[j]
                sab -= sa[j] * sb[j] / sw[j]
                sxb -= sx[j] * sb[j] / sw[j]
        det = saa * sxx - sax * sax
        if det <= 1e-9 * max(saa * sxx, 1e-12):
            return False, levels, dark, 0.0, 0.0
        k = (sab * sxx - sxb * sax) / det
        s = (sxb * saa - sab * sax) / det
        for j in range(bands):
            if cnt[j] >= least_pixels:
                levels[j] = (sb[j] - k * sa[j] - s * sx[j]) / sw[j]
    return k > 0.0, _from_neighbours(levels, cnt, least_pixels)[1], dark, s, k


@nb.njit(**KERNEL)
def clear_band_levels(crop: np.ndarray, x0: int, y0: int, x1: int, y1: int, bands: int, stride: int, chroma: float,
                      least_pixels: int, dark: np.ndarray, clear: float):
    """The bands' veil levels with the skin's blue share ``k`` read where there is no veil: on the bands whose
    dark level lies within ``clear`` of the darkest band's (the camera's black), ``k`` is the median of blue over
    red minus blue of the skin-coloured pixels sampled as in :func:`veil_rows`; each band's level is then the
    median of ``B - k (R - B)`` over its skin-coloured pixels (a band of fewer than ``least_pixels`` takes its
    nearest measured neighbour's). It serves where the joint fit cannot tell a veil from the shading (its ``k``
    not positive, or no spread of red minus blue to fit it on); it has no slope across.

    Returns (ok, levels (bands,) float64, k): ok False where the clear bands, or all the bands, hold fewer than
    ``least_pixels`` skin-coloured pixels.
    """
    span = max(y1 - y0, 1)
    ny, nx = (y1 - y0 + stride - 1) // stride, (x1 - x0 + stride - 1) // stride
    # The skin-coloured pixels sampled: red minus blue, blue, band.
    rb = np.empty(ny * nx)
    blue = np.empty(ny * nx)
    of = np.empty(ny * nx, np.int64)
    n = 0
    for i in range(ny):
        y = y0 + i * stride
        band = min((y - y0) * bands // span, bands - 1)
        for j in range(nx):
            x = x0 + j * stride
            r, g, b = crop[y, x, 0], crop[y, x, 1], crop[y, x, 2]
            if _skin_coloured(r, g, b, chroma):
                rb[n], blue[n], of[n] = float(r) - float(b), float(b), band
                n += 1
    rb, blue, of = rb[:n], blue[:n], of[:n]
    levels = np.full(bands, np.nan)
    clear_band = dark[of] <= dark.min() + clear
    if clear_band.sum() < least_pixels:
        return False, levels, 0.0
    k = np.median(blue[clear_band] / rb[clear_band])
    cnt = np.zeros(bands, np.int64)
    for band in range(bands):
        mine = of == band
        cnt[band] = mine.sum()
        if cnt[band] >= least_pixels:
            levels[band] = np.median(blue[mine] - k * rb[mine])
    ok, out = _from_neighbours(levels, cnt, least_pixels)
    return ok, (out if ok else levels), k


@nb.njit(**INNER)
def _from_neighbours(levels: np.ndarray, cnt: np.ndarray, least_pixels: int):
    """The bands' levels (bands,) with each band of fewer than ``least_pixels`` pixels (``cnt``) given its nearest
    measured neighbour's (the upper one first at equal distance). Returns (ok, levels): ok False where no band
    is measured."""
    bands = levels.size
    out = levels.copy()
    for j in range(bands):
        if cnt[j] < least_pixels:
            best = -1
            for d in range(1, bands):
                for m in (j - d, j + d):
                    if best < 0 and 0 <= m < bands and cnt[m] >= least_pixels:
                        best = m
            if best < 0:
                return False, levels
            out[j] = levels[best]
    return True, out


@nb.njit(**KERNEL)
def _take_off(crop: np.ndarray, field_rows: np.ndarray, slope: float, xc: float, low: float, top: float) -> np.ndarray:
    """The crop less the veil ``field_rows[y] + slope (x - xc) - low`` (clipped at 0), stretched so that the
    99th-percentile level of its every other row and column is ``top``."""
    h, w = crop.shape[:2]
    across = np.empty(w, np.float32)
    for x in range(w):
        across[x] = slope * (x - xc) - low
    hist = np.zeros(256, np.int64)
    n_all = 0
    for y in range(0, h, 2):
        for x in range(0, w, 2):
            v = field_rows[y] + across[x]
            for c in range(3):
                hist[int(min(max(crop[y, x, c] - v, 0.0), 255.0))] += 1
            n_all += 3
    target = 0.99 * n_all
    n = 0
    level = 255
    for i in range(256):
        n += hist[i]
        if n >= target:
            level = i
            break
    gain = np.float32(top / max(level, 1))
    out = np.empty_like(crop)
    for y in range(h):
        row = np.float32(field_rows[y])
        for x in range(w):
            v = row + across[x]
            for c in range(3):
                out[y, x, c] = np.uint8(min(max((np.float32(crop[y, x, c]) - v) * gain + np.float32(0.5),
                                                np.float32(0.0)), np.float32(255.0)))
    return out


def _broad(rise: np.ndarray) -> bool:
    """Whether a veil of the bands' rises (bands,) is broad enough to be one: :data:`VEIL` ``least`` or more in a
    band and half that in a band next to it (a veil's light is scattered wide; a reflection on a lens or a bright
    patch is smaller than two bands)."""
    half = 0.5 * _LEAST
    for j in np.flatnonzero(rise >= _LEAST):
        if (j > 0 and rise[j - 1] >= half) or (j + 1 < len(rise) and rise[j + 1] >= half):
            return True
    return False


def _together(levels: np.ndarray, dark: np.ndarray) -> bool:
    """Whether the bands' veil levels and dark levels, (bands,) float64 each, both vary (standard deviation over 0)
    and correlate by :data:`VEIL` ``together`` or more (Pearson's r). The same arithmetic as ``np.std`` and
    ``np.corrcoef`` of the two, in fewer numpy calls: the rows' means and squared deviations summed in one call
    each, the covariances as one product of the deviations with their transpose, scaled by 1 / (bands - 1)."""
    X = np.array([levels, dark])                            # (2, bands)
    n = X.shape[1]
    X -= X.mean(axis=1)[:, None]
    if not (np.sqrt((X * X).sum(axis=1) / n) > 0.0).all():
        return False
    c = np.dot(X, X.T)
    c *= np.true_divide(1, n - 1)
    s = np.sqrt(np.diag(c))
    return float(c[0, 1] / s[0] / s[1]) >= _TOGETHER


def without_veil(crop: np.ndarray, px: float) -> np.ndarray:
    """The face crop (H, W, 3) uint8 with its veil (module docstring) taken off and stretched back; the crop
    itself where no band veil is broad (:func:`_broad`) or can be measured and the darkest band's black lies at
    or under :data:`VEIL` ``black``."""
    h, w = crop.shape[:2]
    fx0, fy0, fx1, fy1 = VEIL_FACE
    x0, x1 = max(int((fx0 - CROP_EXTENT[0]) * px), 0), min(int((fx1 - CROP_EXTENT[0]) * px), w)
    y0, y1 = max(int((fy0 - CROP_EXTENT[1]) * px), 0), min(int((fy1 - CROP_EXTENT[1]) * px), h)
    if x1 - x0 < 4 or y1 - y0 < 4:
        return crop
    ok, levels, dark, slope, _ = veil_rows(crop, x0, y0, x1, y1, _BANDS, _STRIDE, _HUBER, _ITERATIONS, _CHROMA,
                                           _PIXELS, _DARK, _LEAST)
    dark_list = dark.tolist()
    dark_low, dark_high = min(dark_list), max(dark_list)
    # The darkest band's black lifted: an even veil.
    even = max(dark_low - _BLACK, 0.0)
    if not ok and dark_high - dark_low >= _LEAST:
        # The joint fit failed where the black rises: the levels on the clear bands' blue share, no slope across.
        ok, levels, _ = clear_band_levels(crop, x0, y0, x1, y1, _BANDS, _STRIDE, _CHROMA, _PIXELS, dark, _CLEAR)
        slope = 0.0
        # A veil lifts a band's black as it lifts its skin's blue: the two rise together over the bands (a dark
        # scene beside the face, a hand over it, lift one and not the other).
        ok = ok and _together(levels, dark)
    if ok:
        # Between the bands' middle rows the veil runs linearly from one level to the next: over the face it
        # rises from the lowest band level to the highest (the slope across, which a face's shading also gives,
        # is taken off with a veil found but finds none). A veil lifts the darkest pixels under it with the rest:
        # a band is veiled only as far as its dark level too lies above the darkest band's.
        levels = levels - levels.min()
        if _broad(np.minimum(levels, dark - dark_low)):
            centres = y0 + (np.arange(_BANDS) + 0.5) * (y1 - y0) / _BANDS
            rows = np.interp(np.arange(h, dtype=float), centres, levels)        # level beyond the first and last
            # The lowest level over the whole crop is no veil (but for the even veil).
            low = float(rows.min() - abs(slope) * 0.5 * w) - even
            return _take_off(np.ascontiguousarray(crop), rows, float(slope), 0.5 * (x0 + x1 - 1), low, _TOP)
    if even <= 0.0:
        return crop
    return _take_off(np.ascontiguousarray(crop), np.full(h, even), 0.0, 0.5 * w, 0.0, _TOP)


def warmup(size: tuple[int, int]) -> None:
    """Run the veil's kernels once on a blank crop of ``size`` (W, H) with the tracking types (numba compiles or
    loads them; :mod:`~facepuppet.capture.color.precompile`)."""
    w, h = size
    crop = np.zeros((h, w, 3), np.uint8)
    veil_rows(crop, 0, 0, w, h, _BANDS, _STRIDE, _HUBER, _ITERATIONS, _CHROMA, _PIXELS, _DARK, _LEAST)
    clear_band_levels(crop, 0, 0, w, h, _BANDS, _STRIDE, _CHROMA, _PIXELS, np.zeros(_BANDS), _CLEAR)
    _take_off(crop, np.zeros(h), 0.0, 0.5 * w, 0.0, _TOP)
