"""The head's turn (yaw and pitch) read from the look of the face crop: a linear model learnt with the profile.

The colour tracker's face frame is an in-plane similarity (the eyes' centres): it gives the head's roll, size
and place, not its turn. A turn shows in the upright crop as the face's look changing around the eyes: the
nose and mouth move sideways or up and down against them, one cheek widens as the other narrows, the outline of
the face moves across the crop, the shading of the nose changes. So a trained profile carries a ridge
regression from the crop's grey-level gradients to (yaw, pitch); it is learnt on the tracker's own crops of the
labelled frames (and jittered copies, so that a face frame a little off reads the same turn, and mirrored
copies, whose yaw is the opposite: a face is nearly symmetric, so the model sees turns to both sides even when
the labelled frames turn one way only), with the labels' head poses as targets (the landmark backend's, solved
with the same generic face and angle convention, :meth:`~facepuppet.capture.pose.HeadPose.angles`).

The crop, cut around the eyes, hides where the head is in the frame, and that place goes with the turn: a head
turning about the neck (or with the body) moves across the image the way it turns. So the model reads the
turn less :data:`RAY_SHARE` of the direction of the head's place from the optical axis (:func:`ray_angles`),
and :func:`turn_angles` adds that share back.

Geometry: each patch of :data:`PATCHES` spans its box (face units) placed on the crop by the tracker's placement
of the layout (the eyes' correction of the face frame, a similarity in crop pixels), resampled in grey
(bilinear) at a few pixels per cell; its horizontal and vertical Sobel gradients are
averaged over each cell and divided by the patch's root-mean-square gradient (so a change of the light's
strength does not change them); the patches are concatenated into p. Prediction ``ŷ = W p + b`` in radians.
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["PATCHES", "N_FEATURES", "JITTER", "READS", "RAY_SHARE", "MODEL_KIND",
           "head_patch", "training_pairs", "fit_turn_model", "apply_turn_model", "check_turn_model", "ray_angles",
           "turn_angles", "turn_rotation"]

#: The patches read, each its extent in face units (x0, y0, x1, y1), its grid of cells (columns, rows) and the
#: grey pixels sampled per cell along each axis before the gradients are taken and averaged over the cells:
#: the whole face, both cheeks and brows to chin, coarsely (the outline and the place of the features: the
#: yaw); the eyes, nose and upper lip, finer (the nose's shading and length: the pitch). Both are symmetric
#: about x = 0 (the eyes' midpoint), so that a mirrored crop gives the mirrored patch.
PATCHES = (((-1.2, -0.75, 1.2, 1.85), (10, 11), 4), ((-0.8, -0.4, 0.8, 1.1), (16, 14), 2))
#: Length of the model's input: two gradient components per cell of every patch.
N_FEATURES = sum(w * h * 2 for _, (w, h), _ in PATCHES)
#: Jittered copies of each labelled crop, their largest shift (face units) and scale change (ratio). The
#: copies are random draws: enough of them that the fit hardly depends on the draw (each copy costs one
#: :func:`head_patch` at training time, nothing per tracked frame).
JITTER = (12, 0.04, 0.04)
#: Per angle (yaw, pitch): the patches of :data:`PATCHES` its regression reads, and its ridge penalty (on
#: gradients normalised per patch). The pitch reads the middle of the face only: the outline and the chin
#: move with the expression as much as with a nod.
READS = (((0, 1), 300.0), ((1,), 100.0))
#: Share (yaw, pitch) of the direction of the head's place from the optical axis (:func:`ray_angles`) that is
#: added to the turn the model reads. The coupling of place and turn depends on how the performer moves (about
#: the neck alone it is small, with the body larger); half is a middle one, the same for both angles.
RAY_SHARE = (0.5, 0.5)
#: Kind of the model's input, saved with the model (``head_kind``): the grey gradients of :func:`head_patch`.
#: A profile's model of another kind (an older one, on RGB values) is not used.
MODEL_KIND = 2



def head_patch(crop: np.ndarray, S_px: np.ndarray, px: float, *, mirror: bool = False) -> np.ndarray:
    """The model's input (N_FEATURES,) float64: the normalised grey gradients of each of :data:`PATCHES`.

    Parameters
    ----------
    crop : (H, W, 3) uint8
        The tracker's upright face crop.
    S_px : (2, 3) float
        The placement of the layout on the crop (crop pixels of the unmoved crop -> crop pixels).
    px : float
        Crop pixels per face unit of the unmoved crop.
    mirror : bool
        Read the crop mirrored about the eyes' midpoint (the patches flipped left to right, the horizontal
        gradients with the opposite sign): the input of the same face turned the other way.
    """
    from facepuppet.capture.color.face import CROP_EXTENT

    S_px = np.asarray(S_px, dtype=float)
    out = []
    for (x0, y0, x1, y1), (cw, ch), n in PATCHES:
        size = (cw * n, ch * n)
        # patch pixel (its centre) -> unmoved crop pixel -> crop pixel
        sx, sy = (x1 - x0) * px / size[0], (y1 - y0) * px / size[1]
        P = np.array([[sx, 0.0, (x0 - CROP_EXTENT[0]) * px + 0.5 * sx],
                      [0.0, sy, (y0 - CROP_EXTENT[1]) * px + 0.5 * sy]])
        M = S_px[:, :2] @ P
        M[:, 2] += S_px[:, 2]
        g = cv2.cvtColor(cv2.warpAffine(crop, M, size, flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                        borderMode=cv2.BORDER_REPLICATE), cv2.COLOR_RGB2GRAY)
        if mirror:      # the mirrored face's grey; its horizontal gradients come out with the opposite sign
            g = np.ascontiguousarray(g[:, ::-1])
        gx, gy = cv2.spatialGradient(g, ksize=3, borderType=cv2.BORDER_REPLICATE)     # Sobel, int16
        gx, gy = gx.astype(np.float32), gy.astype(np.float32)
        fx, fy = gx.ravel(), gy.ravel()
        scale = float(np.sqrt((np.dot(fx, fx) + np.dot(fy, fy)) / len(fx))) + 1e-3
        cells = np.stack([cv2.resize(gx, (cw, ch), interpolation=cv2.INTER_AREA),       # cell means
                          cv2.resize(gy, (cw, ch), interpolation=cv2.INTER_AREA)], axis=-1).ravel()
        out.append(cells / scale)
    return np.concatenate(out).astype(np.float64)


def training_pairs(crop: np.ndarray, S_px: np.ndarray, px: float, angles: np.ndarray,
                   rng: np.random.Generator) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Inputs and targets (yaw, pitch) of one labelled crop: where the tracker placed it, and :data:`JITTER`
    copies shifted and scaled about the eyes' midpoint; each also mirrored, with the opposite yaw.

    ``angles`` (>= 2,) radians: the turn the model reads (the label's yaw and pitch less :data:`RAY_SHARE` of
    :func:`ray_angles`)."""
    count, shift, scale = JITTER
    S_px = np.asarray(S_px, dtype=float)
    target = np.asarray(angles, dtype=float)[:2]
    xs, ys = [], []
    for j in range(count + 1):
        S = S_px.copy()
        if j:
            s = rng.uniform(1.0 - scale, 1.0 + scale)
            S[:, :2] *= s
            S[:, 2] += rng.uniform(-shift, shift, 2) * px
        for mirror in (False, True):
            xs.append(head_patch(crop, S, px, mirror=mirror))
            ys.append(target * (-1.0, 1.0) if mirror else target.copy())
    return xs, ys


def fit_turn_model(patches: np.ndarray, angles: np.ndarray) -> dict:
    """Ridge regressions from inputs (N, N_FEATURES) to yaw and to pitch (N, 2) radians, each on the patches
    and with the penalty of :data:`READS` (the coefficients of the patches an angle does not read are zero);
    the arrays of the performer profile.

    Returns
    -------
    dict
        ``{"coef": (2, N_FEATURES), "intercept": (2,), "kind": () MODEL_KIND}``.
    """
    from sklearn.linear_model import Ridge

    patches = np.asarray(patches, dtype=np.float64)
    angles = np.asarray(angles, dtype=np.float64)
    if patches.ndim != 2 or patches.shape[1] != N_FEATURES or angles.shape != (len(patches), 2):
        raise ValueError(f"patches (N, {N_FEATURES}) and angles (N, 2) expected, got {patches.shape} and "
                         f"{angles.shape}")
    ends = np.cumsum([0] + [w * h * 2 for _, (w, h), _ in PATCHES])
    coef, intercept = np.zeros((2, N_FEATURES)), np.zeros(2)
    for k, (parts, alpha) in enumerate(READS):
        cols = np.concatenate([np.arange(ends[p], ends[p + 1]) for p in parts])
        model = Ridge(alpha=alpha).fit(patches[:, cols], angles[:, k])
        coef[k, cols] = model.coef_
        intercept[k] = float(model.intercept_)
    return {"coef": coef, "intercept": intercept, "kind": np.float64(MODEL_KIND)}


def apply_turn_model(model: dict, crop: np.ndarray, S_px: np.ndarray, px: float) -> np.ndarray:
    """(yaw, pitch) (2,) radians that the model reads off the crop (placement ``S_px``, see :func:`head_patch`),
    before :func:`turn_angles`."""
    return model["coef"] @ head_patch(crop, S_px, px) + model["intercept"]


def check_turn_model(model: dict, where: str) -> dict:
    """``model`` if it has the arrays of :func:`fit_turn_model`; ``{}`` for a model of another kind (an older
    profile's: no ``kind``, or another); ValueError naming ``where`` for a damaged one."""
    kind = model.get("kind")
    if kind is None or np.shape(kind) != () or int(kind) != MODEL_KIND:
        return {}
    n = N_FEATURES
    coef, intercept = model.get("coef"), model.get("intercept")
    if coef is None or intercept is None or np.shape(coef) != (2, n) or np.shape(intercept) != (2,):
        raise ValueError(f"{where}: the profile's head-turn model is damaged or of another kind")
    return model


def ray_angles(uv: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Direction (2,) radians of the line of sight through the image point ``uv`` (2,) pixels from the optical
    axis: ``atan((u - c_x) / f_x)``, ``atan((v - c_y) / f_y)`` (positive to the right of and below the image
    centre)."""
    return np.array([np.arctan((uv[0] - K[0, 2]) / K[0, 0]), np.arctan((uv[1] - K[1, 2]) / K[1, 1])])


def turn_angles(turn: np.ndarray, uv: np.ndarray, K: np.ndarray,
                share: tuple[float, float] = RAY_SHARE) -> tuple[float, float]:
    """The head's (yaw, pitch) radians (:meth:`~facepuppet.capture.pose.HeadPose.angles`): the model's ``turn``
    (2,) plus ``share`` (default :data:`RAY_SHARE`) of :func:`ray_angles` of the inner eye corners' midpoint
    ``uv`` (2,) pixels (the point the training takes the labels' share at) in the camera ``K`` (3, 3)."""
    ray = ray_angles(uv, K)
    return float(turn[0]) + share[0] * float(ray[0]), float(turn[1]) + share[1] * float(ray[1])


def turn_rotation(yaw: float, pitch: float, roll: float) -> np.ndarray:
    """``Ry(yaw) @ Rx(pitch) @ Rz(roll)`` (3, 3), the convention of :meth:`~facepuppet.capture.pose.HeadPose.angles`
    (the head's rotation is ``FRONTAL_ROTATION`` times it)."""
    cy, sy, cp, sp, cr, sr = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch), np.cos(roll), np.sin(roll)
    Ry = np.array([[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]])
    Rx = np.array([[1.0, 0.0, 0.0], [0.0, cp, -sp], [0.0, sp, cp]])
    Rz = np.array([[cr, -sr, 0.0], [sr, cr, 0.0], [0.0, 0.0, 1.0]])
    return Ry @ Rx @ Rz
