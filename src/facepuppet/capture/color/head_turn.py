"""The head's turn (yaw and pitch) read from the look of the face crop: a linear model learnt with the profile.

The colour tracker's face frame is an in-plane similarity (the eyes' centres): it gives the head's roll, size
and place, not its turn. A turn shows in the upright crop as the face's look changing around the eyes: the
nose and mouth move sideways or up and down against them, one cheek widens as the other narrows, the outline of
the face moves across the crop. So a trained profile carries a ridge regression from the crop, resampled over
the whole face and normalised, to (yaw, pitch); it is learnt on the tracker's own crops of the labelled frames
(and jittered copies, so that a face frame a little off reads the same turn), with the labels' head poses as
targets (the landmark backend's, solved with the same generic face and angle convention,
:meth:`~facepuppet.capture.pose.HeadPose.angles`).

Geometry: each patch of :data:`PATCHES` spans its box (face units) placed on the crop by the tracker's placement
of the layout (the eyes' correction of the face frame, a similarity in crop pixels), resampled to its size
(bilinear), each RGB channel given zero mean and unit variance (plus one level); the patches are concatenated
into p. Prediction ``ŷ = W p + b`` in radians.
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["PATCHES", "N_FEATURES", "JITTER", "head_patch", "training_pairs", "fit_turn_model",
           "apply_turn_model", "check_turn_model", "READS"]

#: The patches read, each its extent in face units (x0, y0, x1, y1) and its size in pixels (width, height): the
#: whole face, both cheeks and brows to chin, coarsely (the outline and the place of the features: the yaw);
#: the eyes, nose and upper lip, finer (the nose's shading and length: the pitch).
PATCHES = (((-1.2, -0.75, 1.2, 1.85), (10, 11)), ((-0.8, -0.4, 0.8, 1.1), (16, 14)))
#: Length of the model's input: all patches' RGB values.
N_FEATURES = sum(w * h * 3 for _, (w, h) in PATCHES)
#: Jittered copies of each labelled crop, their largest shift (face units) and scale change (ratio).
JITTER = (4, 0.04, 0.04)
#: Per angle (yaw, pitch): the patches of :data:`PATCHES` its regression reads, and its ridge penalty (on
#: patches of unit-variance channels). The pitch reads the middle of the face only: the outline and the chin
#: move with the expression as much as with a nod.
READS = (((0, 1), 300.0), ((1,), 100.0))


def head_patch(crop: np.ndarray, S_px: np.ndarray, px: float) -> np.ndarray:
    """The model's input (N_FEATURES,) float64: each of :data:`PATCHES` of the face in a crop, normalised.

    Parameters
    ----------
    crop : (H, W, 3) uint8
        The tracker's upright face crop.
    S_px : (2, 3) float
        The placement of the layout on the crop (crop pixels of the unmoved crop -> crop pixels).
    px : float
        Crop pixels per face unit of the unmoved crop.
    """
    from facepuppet.capture.color.face import CROP_EXTENT

    S_px = np.asarray(S_px, dtype=float)
    out = []
    for (x0, y0, x1, y1), size in PATCHES:
        # patch pixel -> unmoved crop pixel -> crop pixel
        sx, sy = (x1 - x0) * px / size[0], (y1 - y0) * px / size[1]
        P = np.array([[sx, 0.0, (x0 - CROP_EXTENT[0]) * px], [0.0, sy, (y0 - CROP_EXTENT[1]) * px]])
        M = S_px[:, :2] @ P
        M[:, 2] += S_px[:, 2]
        p = cv2.warpAffine(crop, M, size, flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                           borderMode=cv2.BORDER_REPLICATE)
        p = p.reshape(-1, 3).astype(np.float64)
        p -= p.mean(axis=0)
        p /= p.std(axis=0) + 1.0
        out.append(p.ravel())
    return np.concatenate(out)


def training_pairs(crop: np.ndarray, S_px: np.ndarray, px: float, angles: np.ndarray,
                   rng: np.random.Generator) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Patches and targets (yaw, pitch) of one labelled crop: where the tracker placed it, and :data:`JITTER`
    copies shifted and scaled about the eyes' midpoint."""
    count, shift, scale = JITTER
    S_px = np.asarray(S_px, dtype=float)
    xs, ys = [], []
    for j in range(count + 1):
        S = S_px.copy()
        if j:
            s = rng.uniform(1.0 - scale, 1.0 + scale)
            S[:, :2] *= s
            S[:, 2] += rng.uniform(-shift, shift, 2) * px
        xs.append(head_patch(crop, S, px))
        ys.append(np.asarray(angles, dtype=float)[:2])
    return xs, ys


def fit_turn_model(patches: np.ndarray, angles: np.ndarray) -> dict:
    """Ridge regressions from inputs (N, N_FEATURES) to yaw and to pitch (N, 2) radians, each on the patches
    and with the penalty of :data:`READS` (the coefficients of the patches an angle does not read are zero);
    the arrays of the performer profile.

    Returns
    -------
    dict
        ``{"coef": (2, N_FEATURES), "intercept": (2,)}``.
    """
    from sklearn.linear_model import Ridge

    patches = np.asarray(patches, dtype=np.float64)
    angles = np.asarray(angles, dtype=np.float64)
    if patches.ndim != 2 or patches.shape[1] != N_FEATURES or angles.shape != (len(patches), 2):
        raise ValueError(f"patches (N, {N_FEATURES}) and angles (N, 2) expected, got {patches.shape} and "
                         f"{angles.shape}")
    ends = np.cumsum([0] + [w * h * 3 for _, (w, h) in PATCHES])
    coef, intercept = np.zeros((2, N_FEATURES)), np.zeros(2)
    for k, (parts, alpha) in enumerate(READS):
        cols = np.concatenate([np.arange(ends[p], ends[p + 1]) for p in parts])
        model = Ridge(alpha=alpha).fit(patches[:, cols], angles[:, k])
        coef[k, cols] = model.coef_
        intercept[k] = float(model.intercept_)
    return {"coef": coef, "intercept": intercept}


def apply_turn_model(model: dict, crop: np.ndarray, S_px: np.ndarray, px: float) -> np.ndarray:
    """(yaw, pitch) (2,) radians the model reads off the crop (placement ``S_px``, see :func:`head_patch`)."""
    return model["coef"] @ head_patch(crop, S_px, px) + model["intercept"]


def check_turn_model(model: dict, where: str) -> dict:
    """``model`` if it has the arrays of :func:`fit_turn_model` of this patch size; ValueError naming ``where``."""
    n = N_FEATURES
    coef, intercept = model.get("coef"), model.get("intercept")
    if coef is None or intercept is None or np.shape(coef) != (2, n) or np.shape(intercept) != (2,):
        raise ValueError(f"{where}: the profile's head-turn model is damaged or of another kind")
    return model
