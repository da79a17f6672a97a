"""Cardinal basis functions (paper §5, Eqs. 8–12): linear bases plus cubic B-spline radial bases."""

from __future__ import annotations

import numpy as np

from facepuppet.errors import FacepuppetError
from facepuppet.mapping._params import example_label

__all__ = ["cubic_bspline", "nearest_separation", "radial_matrix", "pairwise_distances"]


def cubic_bspline(t: np.ndarray) -> np.ndarray:
    """The uniform cubic B-spline B(t) (Eq. 11): C², bell-shaped, B(0) = 2/3, zero for |t| ≥ 2.

    Parameters
    ----------
    t : array of float

    Returns
    -------
    array of float, same shape
    """
    a = np.abs(t)
    inner = 2.0 / 3.0 - a * a + 0.5 * a * a * a
    outer = (np.maximum(2.0 - a, 0.0) ** 3) / 6.0
    return np.where(a < 1.0, inner, outer)


def pairwise_distances(X: np.ndarray, C: np.ndarray) -> np.ndarray:
    """(F, K) Euclidean distances between the rows of X (F, n) and of C (K, n)."""
    d2 = (X * X).sum(1)[:, None] - 2.0 * X @ C.T + (C * C).sum(1)[None, :]
    return np.sqrt(np.maximum(d2, 0.0))


def nearest_separation(C: np.ndarray, labels: list[str]) -> np.ndarray:
    """α_j: distance from each centre to the nearest other centre (the dilation of Eq. 11).

    Raises FacepuppetError naming the two centres when two coincide (a singular radial system).

    Parameters
    ----------
    C : (K, n) float
        Centres in the parameter space.
    labels : list of K str
        How each centre is named in messages.
    """
    D = pairwise_distances(C, C)
    np.fill_diagonal(D, np.inf)
    alpha = D.min(axis=1)
    scale = max(float(np.linalg.norm(C, axis=1).max()), np.finfo(float).tiny)
    j = int(np.argmin(alpha))
    if alpha[j] <= 1e-9 * scale:
        k = int(np.argmin(D[j]))
        a, b = sorted((j, k))
        raise FacepuppetError(
            f"source_examples: {labels[a]} and {labels[b]} fall on the same point of the parameter space; "
            "the feature points cannot tell them apart")
    return alpha


def radial_matrix(P: np.ndarray, C: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """(F, K) radial bases R_j(p) = B(‖p − c_j‖ / α_j) (Eq. 11) at the rows p of P."""
    return cubic_bspline(pairwise_distances(P, C) / alpha[None, :])


def center_labels(m: int, names: tuple[str, ...] | None) -> list[str]:
    """Labels of the centres [neutral, example 0, ..., example M−1]."""
    return ["the neutral face (source_base)"] + [f"example {example_label(i, names)}" for i in range(m)]
