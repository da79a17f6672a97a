"""The feature-curve vocabulary (DESIGN.md) and cubic Bezier helpers (paper §3.3).

Conventions: image pixels, x right, y down; left and right are the performer's own (as in ARKit).
A curve is its four control points, shape (4, 2); a set of curves is (C, 4, 2).
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "CURVE_NAMES",
    "IBUG_CURVES",
    "POINT_SAMPLES",
    "POINT_NAMES",
    "bernstein",
    "bezier_points",
    "fit_bezier",
    "curve_points",
]

#: Curve names in the order of the track file's ``curves`` axis.
CURVE_NAMES: tuple[str, ...] = (
    "brow_left",
    "brow_right",
    "eye_left_upper",
    "eye_left_lower",
    "eye_right_upper",
    "eye_right_lower",
    "lip_upper_outer",
    "lip_lower_outer",
    "lip_upper_inner",
    "lip_lower_inner",
    "nostril_left",
    "nostril_right",
)

#: iBUG-68 landmarks (0-based) along each curve, in the curve's direction.
IBUG_CURVES: dict[str, tuple[int, ...]] = {
    "brow_left": (22, 23, 24, 25, 26),
    "brow_right": (21, 20, 19, 18, 17),
    "eye_left_upper": (42, 43, 44, 45),
    "eye_left_lower": (42, 47, 46, 45),
    "eye_right_upper": (39, 38, 37, 36),
    "eye_right_lower": (39, 40, 41, 36),
    "lip_upper_outer": (48, 49, 50, 51, 52, 53, 54),
    "lip_lower_outer": (48, 59, 58, 57, 56, 55, 54),
    "lip_upper_inner": (60, 61, 62, 63, 64),
    "lip_lower_inner": (60, 67, 66, 65, 64),
    "nostril_left": (33, 34, 35),
    "nostril_right": (31, 32, 33),
}

#: Curve parameters at which each curve is sampled to give the feature points handed to the mapping.
POINT_SAMPLES: tuple[float, ...] = (0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0)

#: Names of the feature points, ``"<curve>:<k>"`` for sample k of each curve, curve-major.
POINT_NAMES: tuple[str, ...] = tuple(f"{c}:{k}" for c in CURVE_NAMES for k in range(len(POINT_SAMPLES)))


def bernstein(s: np.ndarray) -> np.ndarray:
    """Cubic Bernstein basis at parameters ``s`` (K,) -> (K, 4); ``bernstein(s) @ ctrl`` samples a curve."""
    s = np.asarray(s, dtype=float)[:, None]
    t = 1.0 - s
    return np.hstack([t**3, 3.0 * s * t**2, 3.0 * s**2 * t, s**3])


_SAMPLE_BASIS = bernstein(np.asarray(POINT_SAMPLES))


def bezier_points(ctrl: np.ndarray, n: int = 32) -> np.ndarray:
    """Sample ``n`` points evenly in the parameter of cubic Bezier curves (Eq. 2's v(s)).

    Parameters
    ----------
    ctrl : (..., 4, 2) float
        Control points.
    n : int
        Number of samples, s = 0 .. 1.

    Returns
    -------
    (..., n, 2) float
    """
    return np.einsum("kj,...jd->...kd", bernstein(np.linspace(0.0, 1.0, n)), np.asarray(ctrl, dtype=float))


def curve_points(curves: np.ndarray) -> np.ndarray:
    """The feature points of a set of curves: each curve sampled at ``POINT_SAMPLES``.

    Parameters
    ----------
    curves : (..., C, 4, D) float

    Returns
    -------
    (..., C * len(POINT_SAMPLES), D) float, ordered as ``POINT_NAMES`` when C = len(CURVE_NAMES).
    """
    curves = np.asarray(curves, dtype=float)
    pts = np.einsum("kj,...cjd->...ckd", _SAMPLE_BASIS, curves)
    return pts.reshape(*curves.shape[:-3], -1, curves.shape[-1])


def fit_bezier(points: np.ndarray, iterations: int = 4) -> np.ndarray:
    """Least-squares cubic Bezier through ordered points, ends fixed at the first and last point.

    The points start parameterised by chord length; the two inner control points solve the linear
    least-squares problem of the Bernstein basis; then each point's parameter is moved to its nearest point on
    the curve by a Newton step and the solve repeated (``iterations`` times). With two points the curve is the
    straight line through them, with three the quadratic through them (as a cubic).

    Parameters
    ----------
    points : (K, D) float, K >= 2
    iterations : int
        Reparameterisation rounds (0 keeps the chord-length parameters).

    Returns
    -------
    (4, D) float
    """
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or len(pts) < 2:
        raise ValueError(f"points must be (K, D) with K >= 2, got shape {pts.shape}")
    p0, p3 = pts[0], pts[-1]
    chord = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))]
    line = np.stack([p0, p0 + (p3 - p0) / 3.0, p0 + 2.0 * (p3 - p0) / 3.0, p3])
    if len(pts) == 2 or chord[-1] <= 0:
        return line
    s = chord / chord[-1]
    if len(pts) == 3:
        # Two unknowns, one equation: take the quadratic through the three points, raised to cubic degree.
        u = min(max(s[1], 1e-3), 1.0 - 1e-3)
        c = (pts[1] - (1 - u) ** 2 * p0 - u**2 * p3) / (2.0 * u * (1 - u))
        return np.stack([p0, p0 + 2.0 * (c - p0) / 3.0, p3 + 2.0 * (c - p3) / 3.0, p3])
    ctrl = line
    for it in range(iterations + 1):
        B = bernstein(s)
        rhs = pts - np.outer(B[:, 0], p0) - np.outer(B[:, 3], p3)
        inner, *_ = np.linalg.lstsq(B[:, 1:3], rhs, rcond=None)
        ctrl = np.vstack([p0, inner, p3])
        if it == iterations:
            break
        # Newton step on each inner parameter towards the foot of the perpendicular from its point.
        d1 = 3.0 * np.diff(ctrl, axis=0)
        d2 = 2.0 * np.diff(d1, axis=0)
        t = s[:, None]
        c = B @ ctrl - pts
        c1 = (1 - t) ** 2 * d1[0] + 2 * t * (1 - t) * d1[1] + t**2 * d1[2]
        c2 = (1 - t) * d2[0] + t * d2[1]
        num = (c * c1).sum(1)
        den = (c1 * c1).sum(1) + (c * c2).sum(1)
        step = np.where(np.abs(den) > 1e-12, num / np.where(den == 0, 1, den), 0.0)
        s_new = np.clip(s - step, 0.0, 1.0)
        s_new[0], s_new[-1] = 0.0, 1.0
        s = np.maximum.accumulate(s_new)
    return ctrl
