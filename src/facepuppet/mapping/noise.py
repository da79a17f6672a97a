"""Statistics of the performer's feature points that weigh the mapping: each coordinate's noise, and the nuisance.

:func:`coordinate_noise` gives each feature coordinate a noise scale, how much of its motion the shown
expressions leave unexplained; the mapping divides displacements by it (the mapper's ``point_scale``).
:func:`noise_from_examples` does the same with the key expressions' own blends as the scores.
:func:`head_turn_nuisance` gives the motion of the points that follows the head's turns, as nuisance points
(the mapper's ``nuisance`` option) for a tracker whose head pose does not turn.

All functions take feature points in head coordinates, ``points`` (F, P, D) with D = 2 or 3, and the
performer's neutral face ``neutral`` (P, D) (the source base S_B); they use numpy only.
"""

from __future__ import annotations

import numpy as np

__all__ = ["coordinate_noise", "noise_from_examples", "head_turn_nuisance", "NOISE_FLOOR", "MOTION_FLOOR",
           "CHI2_1_MEDIAN", "MIN_EXTRA_FRAMES"]

#: Floor of :func:`coordinate_noise`, as a share of the median point's noise (RMS over its coordinates).
NOISE_FLOOR = 0.1
#: Floor of :func:`coordinate_noise`, as a share of the median point's motion per unit score (RMS).
MOTION_FLOOR = 0.05
#: Median of a χ² variable of one degree of freedom: turns a median of squared residuals into a variance.
CHI2_1_MEDIAN = 0.455
#: :func:`noise_from_examples` needs at least this many frames beyond one per key expression.
MIN_EXTRA_FRAMES = 10


def coordinate_noise(points: np.ndarray, scores: np.ndarray, neutral: np.ndarray,
                     floor: float = NOISE_FLOOR, motion_floor: float = MOTION_FLOOR) -> np.ndarray:
    """Each feature coordinate's noise scale: how much of its motion the shown expressions' scores leave
    unexplained.

    Over the frames f, the displacements are fitted as an affine function of the scores,
    ``x_f − S_B ≈ c + Σ_g s_g(f) B_g`` (least squares); the scale of coordinate j is the robust standard
    deviation of its residuals, ``σ_j = (median_f r_fj² / 0.455)^½`` (0.455: the median of a χ²₁ variable),
    raised to at least a floor, ``σ_j ← (σ_j² + σ₀²)^½``, ``σ₀ = max(floor · σ̃, motion_floor · b̃)`` with σ̃
    the median over points of their RMS σ and b̃ the median over points of their RMS motion per unit score
    (B_g): a coordinate that never moves would otherwise count infinitely, and noise far below the
    expressions' own motion does not matter. The mapping divides displacements by it (the mapper's
    ``point_scale``): tracking noise and motion no key-model explains weigh less.

    Parameters
    ----------
    points : (F, P, D) float
        Feature points of the frames with a face and scores.
    scores : (F, G) float
        Their scores, one column per expression kept (blendshape scores, or blend weights of the examples).
    neutral : (P, D) float
    floor, motion_floor : float
        The floors' shares of the median point's noise and of its motion (:data:`NOISE_FLOOR`,
        :data:`MOTION_FLOOR`).

    Returns
    -------
    (P, D) float, positive
    """
    F = len(points)
    Y = (np.asarray(points, dtype=float) - neutral[None]).reshape(F, -1)
    X = np.column_stack([np.asarray(scores, dtype=float), np.ones(F)])
    coef, *_ = np.linalg.lstsq(X, Y, rcond=None)
    resid = Y - X @ coef
    sigma = np.sqrt(np.median(resid ** 2, axis=0) / CHI2_1_MEDIAN).reshape(neutral.shape)
    per_point = np.sqrt((sigma ** 2).mean(axis=1))
    motion = np.sqrt((coef[:-1].reshape(len(coef) - 1, *neutral.shape) ** 2).mean(axis=(0, 2)))
    least = max(floor * float(np.median(per_point)), motion_floor * float(np.median(motion)))
    if not least > 0:
        least = max(float(per_point.max()), float(motion.max()), 1e-9)
    return np.sqrt(sigma ** 2 + least ** 2)


def noise_from_examples(points: np.ndarray, neutral: np.ndarray, examples: np.ndarray) -> np.ndarray | None:
    """:func:`coordinate_noise` with each frame's blend of the key expressions as its scores: what the key
    expressions cannot express in the footage they were taken from.

    Each frame's weights are the least-squares blend ``x_f − S_B ≈ Σ_i w_i(f) (S_i − S_B)``.

    Parameters
    ----------
    points : (F, P, D) float
        Feature points of the frames with a face.
    neutral : (P, D) float
    examples : (M, P, D) float
        The key expressions S_i.

    Returns
    -------
    (P, D) float, positive, or None
        None with fewer than ``M + MIN_EXTRA_FRAMES`` frames.
    """
    if len(points) < len(examples) + MIN_EXTRA_FRAMES:
        return None
    E = (examples - neutral[None]).reshape(len(examples), -1)
    W, *_ = np.linalg.lstsq(E.T, (points - neutral[None]).reshape(len(points), -1).T, rcond=None)
    return coordinate_noise(points, W.T, neutral)


def head_turn_nuisance(points: np.ndarray, rotation: np.ndarray, scores: np.ndarray,
                       neutral: np.ndarray) -> np.ndarray | None:
    """The motion of the feature points that follows the head's turns, as nuisance points for the mapping.

    Over the frames whose ``rotation`` is finite, the displacements are fitted as an affine function of the
    blendshape scores and of the head's small-angle yaw, pitch and roll (entries (0, 2), (1, 2) and (1, 0)
    of the rotation, centred), ``x_f − S_B ≈ c + Σ_b s_b(f) E_b + Σ_a θ_a(f) H_a`` (least squares); the
    nuisance points are ``S_B + Σ_a θ_a(f) H_a``, the turns with the expressions taken out.

    Parameters
    ----------
    points : (F, P, D) float
        Feature points of a tracker whose own head pose does not turn (a turn moves its points).
    rotation : (F, 3, 3) float
        The head-to-camera rotation of the same frames as another tracker (the landmark backend) sees it.
    scores : (F, B) float
        Blendshape scores of the same frames.
    neutral : (P, D) float

    Returns
    -------
    (K, P, D) float, or None
        One row per frame with a finite rotation; None when the rotations never turn or there are fewer than
        twice as many such frames as terms of the fit (``1 + B + 3``).
    """
    use = np.isfinite(rotation).all(axis=(1, 2))
    R = rotation[use]
    angles = np.stack([R[:, 0, 2], R[:, 1, 2], R[:, 1, 0]], axis=1)
    if len(angles) < 2 * (1 + scores.shape[1] + angles.shape[1]) or float(np.ptp(angles, axis=0).max()) < 1e-6:
        return None
    angles -= angles.mean(axis=0)
    X = np.hstack([np.ones((len(angles), 1)), scores[use], angles])
    Y = (points[use] - neutral[None]).reshape(len(angles), -1)
    coef, *_ = np.linalg.lstsq(X, Y, rcond=None)
    return neutral[None] + (angles @ coef[-angles.shape[1]:]).reshape(len(angles), *neutral.shape)
