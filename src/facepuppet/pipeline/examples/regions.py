"""Which feature points each ARKit blendshape moves, and the regression of ``--auto`` held to those points.

A blendshape moves one part of the face: a blink the eyelids, a brow raise the brows, the jaw and the mouth's
shapes the lips. The feature points are grouped by the curve they sample (``"<curve>:<k>"``, see
:data:`facepuppet.capture.curves.POINT_NAMES`): a point on ``eye_left_upper`` is in the region ``eye``.
:func:`movable` says which points a group of blendshapes may move; :func:`regional_fit` fits every frame's
displacement as a blend of the groups' scores, each group's displacement zero outside its region, so that
motion in one part of the face that happens to rise with another part's score (a performer who opens the
mouth while blinking) is not taken into the other part's key expression.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["BLENDSHAPE_REGIONS", "POINT_REGIONS", "point_region", "movable", "regional_fit"]

#: The regions of the face each ARKit blendshape moves, by the blendshape name's prefix (first match wins).
#: ``cheekSquint`` and ``eyeSquint`` push the lower lids; ``noseSneer`` lifts the nostrils and the upper lip.
BLENDSHAPE_REGIONS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("brow", ("brow",)),
    ("eye", ("eye",)),
    ("cheekSquint", ("eye",)),
    ("cheekPuff", ("lip",)),
    ("noseSneer", ("nostril", "lip")),
    ("jaw", ("lip",)),
    ("mouth", ("lip",)),
)

#: The region of a feature point, by the prefix of the curve it samples (first match wins).
POINT_REGIONS: tuple[tuple[str, str], ...] = (
    ("brow", "brow"),
    ("eye", "eye"),
    ("lip", "lip"),
    ("mouth", "lip"),
    ("nostril", "nostril"),
    ("nose", "nostril"),
)


def point_region(point_name: str) -> str | None:
    """The region (``brow``, ``eye``, ``lip``, ``nostril``) of a feature point by its curve's name, or None."""
    curve = str(point_name).split(":", 1)[0].lower()
    return next((region for prefix, region in POINT_REGIONS if curve.startswith(prefix)), None)


def blendshape_regions(name: str) -> tuple[str, ...] | None:
    """The regions an ARKit blendshape (ARKit's spelling) moves, or None when unknown."""
    return next((regions for prefix, regions in BLENDSHAPE_REGIONS if name.startswith(prefix)), None)


def movable(groups: Sequence[Sequence[str]], point_names: Sequence[str]) -> np.ndarray:
    """Which points each group of blendshapes may move.

    Parameters
    ----------
    groups : sequence of G sequences of str
        ARKit blendshape names (ARKit's spelling) shown together as one key expression.
    point_names : sequence of P str

    Returns
    -------
    (G, P) bool
        True where a point lies in a region one of the group's blendshapes moves; a point in no known region,
        or a group of no known region, is movable by (moves) everything.
    """
    regions = [point_region(n) for n in point_names]
    out = np.ones((len(groups), len(point_names)), bool)
    for j, group in enumerate(groups):
        known = [blendshape_regions(b) for b in group]
        if any(k is None for k in known):
            continue
        moves = {r for k in known for r in k}
        out[j] = [r is None or r in moves for r in regions]
    return out


def regional_fit(scores: np.ndarray, displacements: np.ndarray, allowed: np.ndarray, ridge: float, *,
                 intercept: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares blend ``Y ≈ c + X B`` of the displacements by the scores, each group's row of B zero on
    the points it may not move.

    The points that the same groups may move are fitted together, by ridge least squares on those groups'
    scores only (ridge ``ridge`` times the mean diagonal of their Gram matrix, the scores and displacements
    centred first when ``intercept``). A point no group moves gets its mean displacement as c (or 0).

    Parameters
    ----------
    scores : (F, G) float
        X: each group's score per frame.
    displacements : (F, P, D) float
        Y: each frame's feature points minus the neutral face.
    allowed : (G, P) bool
        :func:`movable`.
    ridge : float
    intercept : bool
        Fit the offset c too (else c = 0).

    Returns
    -------
    B : (G, P, D) float
        Each group's displacement at score 1.
    c : (P, D) float
        The displacement at zero scores.
    """
    F, P, D = displacements.shape
    G = scores.shape[1]
    B = np.zeros((G, P, D))
    c = np.zeros((P, D))
    patterns, owner = np.unique(allowed.T, axis=0, return_inverse=True)          # (U, G), (P,)
    for u, pattern in enumerate(patterns):
        cols = np.flatnonzero(pattern)
        pts = np.flatnonzero(owner.ravel() == u)
        Y = displacements[:, pts].reshape(F, -1)
        if not len(cols):
            if intercept:
                c[pts] = Y.mean(axis=0).reshape(len(pts), D)
            continue
        X = scores[:, cols]
        xm, ym = (X.mean(axis=0), Y.mean(axis=0)) if intercept else (np.zeros(len(cols)), np.zeros(Y.shape[1]))
        Xc, Yc = X - xm, Y - ym
        gram = Xc.T @ Xc
        lam = ridge * max(float(np.trace(gram)) / len(cols), 1e-12)
        coef = np.linalg.solve(gram + lam * np.eye(len(cols)), Xc.T @ Yc)       # (g, p*D)
        B[np.ix_(cols, pts)] = coef.reshape(len(cols), len(pts), D)
        c[pts] = (ym - xm @ coef).reshape(len(pts), D)
    return B, c
