"""The nuisance metric: motion of the feature points that is no expression counts less (``nuisance`` option).

A tracker's feature points move even when the face does not: the head turns and the pose removes it only
approximately (the colour tracker's yaw and pitch are read off the nose's tip or the crop's look, a landmark
model's depth is a guess), the face frame slips, the light changes. Frames in which the performer keeps a
neutral face while the head moves show, point by point, how: with their displacement vectors ``n_k`` from the
neutral face (divided by the ``point_scale`` like every other), the nuisance covariance is
``Σ = (1/K) Σ_k n_k n_kᵀ``, with eigenvalues ``λ_j`` and eigenvectors ``u_j``. Every displacement vector, the
examples' (Eq. 5) and each frame's (Eq. 13), is multiplied by

    T = Σ_j √(f / (λ_j + f)) u_j u_jᵀ,   f = floor · max_j λ_j,

before the method sees it. Directions the nuisance never takes keep their length; one it takes with variance
λ shrinks by √(f / (λ + f)). The least squares of every method then weighs the residual by ``(f I + Σ)⁻¹``
up to a constant: a generalised least squares whose noise is isotropic plus the nuisance. ``T`` is
symmetric and invertible, so every method's guarantees (neutral and each example exact, blends of the
examples reproduced) hold unchanged.
"""

from __future__ import annotations

import numpy as np

__all__ = ["nuisance_transform"]


def nuisance_transform(displacements: np.ndarray, floor: float) -> np.ndarray:
    """The symmetric matrix T of the module docstring from nuisance displacement vectors.

    Parameters
    ----------
    displacements : (K, N) float
        Nuisance displacement vectors n_k (already divided by the point scale).
    floor : float in (0, 1]
        f as a share of the largest nuisance eigenvalue.

    Returns
    -------
    (N, N) float
        T; the identity when the nuisance does not move at all.
    """
    n_k = np.asarray(displacements, dtype=float)
    cov = n_k.T @ n_k / len(n_k)
    lam, u = np.linalg.eigh(cov)
    lam = np.clip(lam, 0.0, None)
    if lam[-1] <= 0.0:
        return np.eye(cov.shape[0])
    f = floor * lam[-1]
    return (u * np.sqrt(f / (lam + f))) @ u.T
