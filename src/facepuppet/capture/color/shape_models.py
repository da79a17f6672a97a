"""The performer's lips, brows and eyes read from the look of the face crop: linear models learnt with the profile.

The colour tracker's rules (:mod:`~facepuppet.capture.color.rules`) move each lip and brow curve of the layout by
a few numbers read off its blob: the mouth's corners and one shift per curve, the brow's height and tilt. The
blob's edges follow the light and the head's turn as much as the expression, and a curve's shape beyond those
few numbers is the layout's. So with the performer profile (§3.1, trained on frames labelled by the landmark
backend or, in the demo, by the true curves) comes, per family, a ridge regression from the look of the face
crop around the family to its curves, as the eyelid model (:mod:`~facepuppet.capture.color.lids`) does for the
lids. Each eye has one too (both lids and their corners): the rules read the eyes on the contrast C, whose
weights the colour network predicts, and so depend on that network's training; the eyes' models do not.

Geometry, for one family (:data:`FAMILIES`): its box is the bounding box of its curves in the layout as the
tracker placed it on the crop (the face frame with the eyes' correction), widened by :data:`MARGINS` (shares
of the box's width: sideways, up, down; a lower lip and jaw fall far below the neutral mouth). The patch is
that box resampled to :data:`PATCH_SIZE` (bilinear), each RGB channel given zero mean and unit variance
(plus one level, so a flat patch stays near zero). The targets are the family's control points in the box,
``((x − x₀) / w, (y − y₀) / w)`` with w the box's width; prediction ``ŷ = W p + b``. Training patches are cut
from the tracker's own crops (where it will cut them at run time) and from jittered copies of the box
(:data:`JITTER`), so that a face frame a little off reads the same curves.
"""

from __future__ import annotations

import cv2
import numpy as np

from facepuppet.capture.curves import CURVE_NAMES

__all__ = ["FAMILIES", "MARGINS", "PATCH_SIZE", "JITTER", "family_box", "family_patch", "box_targets",
           "training_pairs", "fit_shape_model", "apply_shape_models"]

#: Curves read by each family's model, CURVE_NAMES indices. Each brow has its own: one model over both
#: brows lets one brow's motion read as the other's.
FAMILIES: dict[str, np.ndarray] = {
    "lips": np.array([i for i, n in enumerate(CURVE_NAMES) if n.startswith("lip_")]),
    "brow_left": np.array([CURVE_NAMES.index("brow_left")]),
    "brow_right": np.array([CURVE_NAMES.index("brow_right")]),
    "eye_left": np.array([i for i, n in enumerate(CURVE_NAMES) if n.startswith("eye_left_")]),
    "eye_right": np.array([i for i, n in enumerate(CURVE_NAMES) if n.startswith("eye_right_")]),
}
#: Widening of each family's box: (each side, above, below), shares of the box's width.
MARGINS: dict[str, tuple[float, float, float]] = {"lips": (0.15, 0.35, 0.6), "brow_left": (0.15, 0.25, 0.2),
                                                  "brow_right": (0.15, 0.25, 0.2), "eye_left": (0.15, 0.3, 0.3),
                                                  "eye_right": (0.15, 0.3, 0.3)}
#: Width and height of the resampled patch (pixels).
PATCH_SIZE = (24, 16)
#: Jittered copies of each labelled frame, and their largest shift (share of the box's width) and scale change.
JITTER = (6, 0.05, 0.05)
#: Ridge penalty of the regression (on patches of unit-variance channels).
ALPHA = 30.0


def family_box(layout_px: np.ndarray, family: str) -> np.ndarray:
    """(x₀, y₀, x₁, y₁) of ``family``'s patch from the layout placed on the crop, (C, 4, 2) crop pixels."""
    pts = np.asarray(layout_px, dtype=float)[FAMILIES[family]].reshape(-1, 2)
    (x0, y0), (x1, y1) = pts.min(axis=0), pts.max(axis=0)
    w = x1 - x0
    side, up, down = MARGINS[family]
    return np.array([x0 - side * w, y0 - up * w, x1 + side * w, y1 + down * w])


def family_patch(crop: np.ndarray, box: np.ndarray) -> np.ndarray:
    """The normalised patch (PATCH_SIZE[0] * PATCH_SIZE[1] * 3,) float64 of ``box`` in the crop (H, W, 3)."""
    x0, y0, x1, y1 = (float(v) for v in box)
    sx, sy = PATCH_SIZE[0] / max(x1 - x0, 1e-6), PATCH_SIZE[1] / max(y1 - y0, 1e-6)
    M = np.array([[sx, 0.0, -x0 * sx], [0.0, sy, -y0 * sy]])
    p = cv2.warpAffine(crop, M, PATCH_SIZE, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    p = p.reshape(-1, 3).astype(np.float64)
    p -= p.mean(axis=0)
    p /= p.std(axis=0) + 1.0
    return p.ravel()


def box_targets(curves_px: np.ndarray, box: np.ndarray, family: str) -> np.ndarray:
    """The family's control points of ``curves_px`` (C, 4, 2) in box units, flattened."""
    x0, y0, x1, _ = box
    return ((np.asarray(curves_px, dtype=float)[FAMILIES[family]] - [x0, y0]) / (x1 - x0)).ravel()


def training_pairs(crop: np.ndarray, layout_px: np.ndarray, labels_px: np.ndarray, family: str,
                   rng: np.random.Generator) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Patches and targets of one labelled crop: the box where the tracker put it, and :data:`JITTER` copies."""
    box = family_box(layout_px, family)
    count, shift, scale = JITTER
    centre = 0.5 * (box[:2] + box[2:])
    half = 0.5 * (box[2:] - box[:2])
    xs, ys = [], []
    for j in range(count + 1):
        d = rng.uniform(-shift, shift, 2) * (box[2] - box[0]) if j else np.zeros(2)
        s = rng.uniform(1.0 - scale, 1.0 + scale) if j else 1.0
        b = np.concatenate([centre + d - s * half, centre + d + s * half])
        xs.append(family_patch(crop, b))
        ys.append(box_targets(labels_px, b, family))
    return xs, ys


def fit_shape_model(patches: np.ndarray, targets: np.ndarray, alpha: float = ALPHA) -> dict:
    """Ridge regression from patches (N, P) to targets (N, T); the arrays of the performer profile.

    Returns
    -------
    dict
        ``{"coef": (T, P), "intercept": (T,)}``.
    """
    from sklearn.linear_model import Ridge

    patches = np.asarray(patches, dtype=np.float64)
    targets = np.asarray(targets, dtype=np.float64)
    if patches.ndim != 2 or targets.ndim != 2 or len(targets) != len(patches):
        raise ValueError(f"patches (N, P) and targets (N, T) expected, got {patches.shape} and {targets.shape}")
    model = Ridge(alpha=alpha).fit(patches, targets)
    return {"coef": model.coef_.astype(np.float64), "intercept": np.asarray(model.intercept_, dtype=np.float64)}


def apply_shape_models(curves_px: np.ndarray, crop: np.ndarray, layout_px: np.ndarray, models: dict) -> None:
    """Replace each modelled family's curves in ``curves_px`` (C, 4, 2, crop pixels; in place) by its reading.

    ``models`` maps a family name to ``{"coef", "intercept"}``; families it lacks keep their curves.
    """
    for family, model in models.items():
        box = family_box(layout_px, family)
        y = model["coef"] @ family_patch(crop, box) + model["intercept"]
        idx = FAMILIES[family]
        curves_px[idx] = y.reshape(len(idx), 4, 2) * (box[2] - box[0]) + box[:2]
