"""The parameter space (paper §4.1, Eqs. 5–7) and the diagnosis of examples the feature points cannot separate.

Eigenvalue threshold: *relative* to the largest eigenvalue. The paper's 0.00001 is stated without units, but
an absolute threshold on a covariance depends on the units of the feature points (pixels, centimetres, metres
change it by 10⁴–10⁸), so the same performance would keep a different number of axes depending on how it was
measured. Relative to the largest eigenvalue the threshold means what the paper uses it for: drop the axes that
carry a negligible share (here 10⁻⁵ of the variance of the strongest axis, i.e. singular values under
√10⁻⁵ ≈ 0.3 % of the largest) and keep every axis that carries real motion, whatever the units.
"""

from __future__ import annotations

import numpy as np

from facepuppet.errors import FacepuppetError

__all__ = ["feature_matrix", "check_examples", "example_label"]

# An example whose displacement is under this share of the largest example's "barely moves" the points.
STILL_SHARE = 1e-3


def example_label(i: int, names: tuple[str, ...] | None) -> str:
    """``"3 ('jawOpen')"`` or ``"3"``."""
    return f"{i} ({names[i]!r})" if names else str(i)


def feature_matrix(V: np.ndarray, threshold: float, *, centred: bool) -> tuple[np.ndarray, np.ndarray]:
    """PCA feature matrix ``F`` (Eq. 6) of the displacement vectors.

    Parameters
    ----------
    V : (M, N) float
        Displacement vectors v_i = s_i − s_B (Eq. 5), one per row.
    threshold : float
        Keep eigenvectors whose eigenvalue is at least ``threshold`` times the largest eigenvalue.
    centred : bool
        True: eigenvectors of the covariance about the mean of the v_i (the paper's "component covariance
        matrix"). False: of the second moments about the source base (v = 0), which keeps every direction an
        example moves in, so that the neutral face stays apart from every blend of examples.

    Returns
    -------
    F : (N̄, N) float
        Rows are the kept eigenvectors e_1..e_N̄, largest eigenvalue first (Eq. 6).
    eigenvalues : (N̄,) float
    """
    X = V - V.mean(axis=0) if centred else V
    _, s, vt = np.linalg.svd(X, full_matrices=False)
    ev = s**2 / len(V)
    if ev.size == 0 or ev[0] <= 0.0:
        return np.zeros((0, V.shape[1])), np.zeros(0)
    keep = ev >= threshold * ev[0]
    return vt[keep], ev[keep]


def check_examples(V: np.ndarray, names: tuple[str, ...] | None, threshold: float) -> None:
    """Raise FacepuppetError, in words, if the feature points cannot tell the examples apart.

    Parameters
    ----------
    V : (M, N) float
        Displacement vectors of the source examples (Eq. 5).
    names : tuple of M str, optional
        Example names for the message.
    threshold : float
        The relative eigenvalue threshold of :func:`feature_matrix`.
    """
    norms = np.linalg.norm(V, axis=1)
    top = norms.max()
    if top == 0.0:
        raise FacepuppetError("source_examples: no example moves the feature points away from source_base")
    still = np.flatnonzero(norms < STILL_SHARE * top)
    if still.size:
        i = int(still[0])
        raise FacepuppetError(
            f"source_examples: example {example_label(i, names)} barely moves the feature points "
            f"({norms[i] / top:.2g} of the largest example's displacement); the mapping cannot see it")
    # Two examples the points cannot tell apart: their displacements (almost) coincide.
    diff = np.linalg.norm(V[:, None, :] - V[None, :, :], axis=2)
    scale = np.maximum(norms[:, None], norms[None, :])
    close = np.argwhere(np.triu(diff < np.sqrt(threshold) * scale, 1))
    if close.size:
        i, j = (int(k) for k in close[0])
        raise FacepuppetError(
            f"source_examples: examples {example_label(i, names)} and {example_label(j, names)} move the feature "
            f"points (almost) identically (difference {diff[i, j] / scale[i, j]:.2g} of their size); "
            "the mapping cannot tell them apart: drop one or capture it again")
    # More generally: one example is (almost) a blend of others.
    u, s, vt = np.linalg.svd(V / norms[:, None], full_matrices=False)
    if len(V) > V.shape[1] or s[-1] ** 2 < threshold * s[0] ** 2:
        null = u[:, -1] if len(V) <= V.shape[1] else _null_combination(V / norms[:, None])
        involved = np.flatnonzero(np.abs(null) > 0.1 * np.abs(null).max())
        listed = ", ".join(example_label(int(i), names) for i in involved)
        raise FacepuppetError(
            f"source_examples: examples {listed} are (almost) linearly dependent in the feature points: one of "
            "them is a blend of the others, so the mapping cannot tell them apart: drop one or capture it again")


def _null_combination(Vn: np.ndarray) -> np.ndarray:
    """Coefficients c with cᵀ Vn ≈ 0 (more examples than point coordinates)."""
    _, _, vt = np.linalg.svd(Vn.T, full_matrices=True)
    return vt[-1]
