"""The performer's eyelids read from the look of the eye: a linear model learnt with the performer profile.

The colour tracker's rules (:mod:`~facepuppet.capture.outlines`) place the lids on the eye blob's edges. On
a closing eye the blob does not shrink with the lid: the lid's crease and the lash line stay as dark as the
open eye (measured on the shared clips, the rules' eye opening correlates with MediaPipe's at 0.3 or below).
What does change is the eye's appearance: the sclera and iris disappear under skin. So with the performer
profile (§3.1, trained on frames labelled by the landmark backend) comes a ridge regression from the grey
patch of each eye, normalised for level and contrast, to where the middle of each lid sits.

Geometry, for one eye with corners c₀, c₁ (the upper lid's end points): centre m = (c₀ + c₁)/2, span
s = |c₁ − c₀|, axis a = (c₁ − c₀)/s turned to point to the image's right, normal n = (−a_y, a_x) (down in the
image). The lid's middle is the mean of its two middle control points, P = (P₁ + P₂)/2, and its offset is
o = (P − m)·n / s. The patch is the axis-aligned ``PATCH_SPAN`` · s box centred on m in the face crop (the crop
is already turned upright), resampled to ``PATCH_SIZE``; the left eye's patch is mirrored so that both eyes
share one model. Targets (upper offset, lower offset) per eye; prediction ŷ = W x + b.
"""

from __future__ import annotations

import cv2
import numpy as np

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
    up = curves[EYES[eye][0]]
    axis = up[3] - up[0]
    span = float(np.hypot(axis[0], axis[1]))
    if axis[0] < 0:
        axis = -axis
    axis = axis / max(span, 1e-9)
    return 0.5 * (up[0] + up[3]), span, np.array([-axis[1], axis[0]])


def lid_offsets(curves: np.ndarray, eye: int) -> np.ndarray:
    """(upper, lower) offsets of the lids' middles from the eye's centre along its normal, in eye spans."""
    m, s, n = eye_geometry(curves, eye)
    return np.array([(0.5 * (curves[k, 1] + curves[k, 2]) - m) @ n / max(s, 1e-9) for k in EYES[eye]])


def eye_patch(grey: np.ndarray, centre: np.ndarray, span: float, mirror: bool) -> np.ndarray | None:
    """The normalised eye patch (PATCH_SIZE[0] * PATCH_SIZE[1],) float32, or None when it would be too small.

    ``grey`` (H, W) float32 is the face crop's grey level; the patch is ``PATCH_SPAN`` spans wide and high around
    ``centre``, resampled by area, mirrored left-right when ``mirror``, then given zero mean and unit variance.
    """
    w, h = int(round(PATCH_SPAN[0] * span)), int(round(PATCH_SPAN[1] * span))
    if w < PATCH_SIZE[0] // 2 or h < PATCH_SIZE[1] // 2:
        return None
    p = cv2.getRectSubPix(grey, (w, h), (float(centre[0]), float(centre[1])))
    p = cv2.resize(p, PATCH_SIZE, interpolation=cv2.INTER_AREA)
    if mirror:
        p = p[:, ::-1]
    p = p - p.mean()
    return (p / (p.std() + 1.0)).ravel()


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


def apply_lid_model(curves: np.ndarray, grey: np.ndarray, model: dict, min_gap: float = 0.02) -> None:
    """Move the lids' middle control points of ``curves`` (C, 4, 2, crop pixels; in place) where the model reads them.

    Each lid's two middle control points move together along the eye's normal so that their mean sits at the
    predicted offset; the upper lid stays at least ``min_gap`` spans above the lower one.
    """
    W, b = model["coef"], model["intercept"]
    for eye in (0, 1):
        m, s, n = eye_geometry(curves, eye)
        x = eye_patch(grey, m, s, mirror=eye == 1)
        if x is None:
            continue
        up_o, lo_o = W @ x + b
        up_o = min(up_o, lo_o - min_gap)
        for k, o in zip(EYES[eye], (up_o, lo_o), strict=True):
            now = (0.5 * (curves[k, 1] + curves[k, 2]) - m) @ n / s
            d = (o - now) * s * n
            curves[k, 1] += d
            curves[k, 2] += d
