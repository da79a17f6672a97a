"""The performer's eyelids read from the look of the eye: a linear model learnt with the performer profile.

The colour tracker's rules (:mod:`~facepuppet.capture.color.rules`) place the lids on the eye blob's edges. On
a closing eye the blob does not shrink with the lid: the lid's crease and the lash line stay as dark as the
open eye, so the rules' eye opening follows a blink poorly.
What does change is the eye's appearance: the sclera and iris disappear under skin. So with the performer
profile (§3.1, trained on frames labelled by the landmark backend) comes a ridge regression from the grey
patch of each eye, normalised for level and contrast, to where the middle of each lid sits.

Geometry, for one eye with corners c₀, c₁ (the upper lid's end points): centre m = (c₀ + c₁)/2, span
s = |c₁ − c₀|, axis a = (c₁ − c₀)/s turned to point to the image's right, normal n = (−a_y, a_x) (down in the
image). The lid's middle is the mean of its two middle control points, P = (P₁ + P₂)/2, and its offset is
o = (P − m)·n / s. The patch is the axis-aligned ``PATCH_SPAN`` · s box centred on m in the face crop (the
crop is already turned upright), resampled to ``PATCH_SIZE`` and turned grey; the left eye's patch is
mirrored so that both eyes share one model. Targets (upper offset, lower offset) per eye; prediction
ŷ = W x + b.
"""

from __future__ import annotations

import cv2
import numba as nb
import numpy as np

from facepuppet._util.jit import KERNEL
from facepuppet.capture.curves import CURVE_NAMES

__all__ = ["PATCH_SIZE", "PATCH_SPAN", "EYES", "eye_geometry", "eye_patch", "lid_offsets", "fit_lid_model",
           "apply_lid_model"]

_IDX = {n: i for i, n in enumerate(CURVE_NAMES)}

#: Width and height of the resampled eye patch (pixels).
PATCH_SIZE = (16, 8)
#: Width and height of the eye patch in eye spans (corner to corner).
PATCH_SPAN = (0.8, 0.45)
#: (upper lid, lower lid) curve indices of each eye, right then left.
EYES = ((_IDX["eye_right_upper"], _IDX["eye_right_lower"]), (_IDX["eye_left_upper"], _IDX["eye_left_lower"]))


def eye_geometry(curves: np.ndarray, eye: int) -> tuple[np.ndarray, float, np.ndarray]:
    """Centre m (2,), span s and downward normal n (2,) of eye ``eye`` (0 right, 1 left) of curves (C, 4, 2)."""
    g = _geometry(np.ascontiguousarray(curves, dtype=np.float64), EYES[eye][0])
    return g[:2].copy(), float(g[2]), g[3:].copy()


def lid_offsets(curves: np.ndarray, eye: int) -> np.ndarray:
    """(upper, lower) offsets of the lids' middles from the eye's centre along its normal, in eye spans."""
    m, s, n = eye_geometry(curves, eye)
    return np.array([(0.5 * (curves[k, 1] + curves[k, 2]) - m) @ n / max(s, 1e-9) for k in EYES[eye]])


def eye_patch(rgb: np.ndarray, centre: np.ndarray, span: float, mirror: bool) -> np.ndarray | None:
    """The normalised eye patch (PATCH_SIZE[0] * PATCH_SIZE[1],) float64, or None when it would be too small.

    ``rgb`` (H, W, 3) uint8 is the face crop; the patch is ``PATCH_SPAN`` spans wide and high around
    ``centre``, resampled by area, turned grey (ITU-R BT.601 weights), mirrored left-right when ``mirror``,
    then given zero mean and unit variance (plus one grey level, so a flat patch stays near zero).
    """
    w, h = int(round(PATCH_SPAN[0] * span)), int(round(PATCH_SPAN[1] * span))
    if w < PATCH_SIZE[0] // 2 or h < PATCH_SIZE[1] // 2:
        return None
    p = cv2.getRectSubPix(rgb, (w, h), (float(centre[0]), float(centre[1])))
    return _normalise(cv2.resize(p, PATCH_SIZE, interpolation=cv2.INTER_AREA), mirror)


@nb.njit(**KERNEL)
def _geometry(curves: np.ndarray, upper: int) -> np.ndarray:
    """(m_x, m_y, s, n_x, n_y) of the eye whose upper lid is curve ``upper`` (module docstring)."""
    x0, y0 = curves[upper, 0, 0], curves[upper, 0, 1]
    ax, ay = curves[upper, 3, 0] - x0, curves[upper, 3, 1] - y0
    s = np.sqrt(ax * ax + ay * ay)
    if ax < 0:
        ax, ay = -ax, -ay
    s_safe = max(s, 1e-9)
    out = np.empty(5)
    out[0], out[1], out[2] = x0 + 0.5 * (curves[upper, 3, 0] - x0), y0 + 0.5 * (curves[upper, 3, 1] - y0), s
    out[3], out[4] = -ay / s_safe, ax / s_safe
    return out


@nb.njit(**KERNEL)
def _normalise(p: np.ndarray, mirror: bool) -> np.ndarray:
    """Grey, mirrored if asked, zero mean and unit variance (+1 grey level): (h, w, 3) uint8 -> (h * w,)."""
    h, w = p.shape[0], p.shape[1]
    out = np.empty(h * w)
    for y in range(h):
        for x in range(w):
            sx = w - 1 - x if mirror else x
            out[y * w + x] = 0.299 * p[y, sx, 0] + 0.587 * p[y, sx, 1] + 0.114 * p[y, sx, 2]
    mean = out.mean()
    out -= mean
    sd = np.sqrt((out * out).mean())
    out /= sd + 1.0
    return out


@nb.njit(**KERNEL)
def _move_lids(curves: np.ndarray, up: int, lo: int, g: np.ndarray, x: np.ndarray, W: np.ndarray, b: np.ndarray,
               min_gap: float) -> None:
    """Predict the two offsets from patch ``x`` and move the lids' middle control points there (in place)."""
    o_up = b[0] + (W[0] * x).sum()
    o_lo = b[1] + (W[1] * x).sum()
    o_up = min(o_up, o_lo - min_gap)
    mx, my, s, nx, ny = g[0], g[1], g[2], g[3], g[4]
    for k, o in ((up, o_up), (lo, o_lo)):
        px = 0.5 * (curves[k, 1, 0] + curves[k, 2, 0]) - mx
        py = 0.5 * (curves[k, 1, 1] + curves[k, 2, 1]) - my
        d = o * s - (px * nx + py * ny)
        for j in (1, 2):
            curves[k, j, 0] += d * nx
            curves[k, j, 1] += d * ny


def fit_lid_model(patches: np.ndarray, offsets: np.ndarray, alpha: float = 100.0) -> dict:
    """Ridge regression from eye patches (N, P) to lid offsets (N, 2); the arrays of the performer profile.

    Returns
    -------
    dict
        ``{"coef": (2, P), "intercept": (2,)}``.
    """
    from sklearn.linear_model import Ridge

    patches = np.asarray(patches, dtype=np.float64)
    offsets = np.asarray(offsets, dtype=np.float64)
    if patches.ndim != 2 or offsets.shape != (len(patches), 2):
        raise ValueError(f"patches (N, P) and offsets (N, 2) expected, got {patches.shape} and {offsets.shape}")
    model = Ridge(alpha=alpha).fit(patches, offsets)
    return {"coef": model.coef_.astype(np.float64), "intercept": np.asarray(model.intercept_, dtype=np.float64)}


def apply_lid_model(curves: np.ndarray, rgb: np.ndarray, model: dict, min_gap: float = 0.02) -> None:
    """Move the lids' middle control points of ``curves`` (C, 4, 2, crop pixels; in place) where the model reads them.

    ``rgb`` is the face crop (H, W, 3) uint8. Each lid's two middle control points move together along the
    eye's normal so that their mean sits at the predicted offset; the upper lid stays at least ``min_gap``
    spans above the lower one.
    """
    W, b = model["coef"], model["intercept"]
    for eye in (0, 1):
        up, lo = EYES[eye]
        g = _geometry(curves, up)
        x = eye_patch(rgb, g[:2], g[2], mirror=eye == 1)
        if x is not None:
            _move_lids(curves, up, lo, g, x, W, b, min_gap)
