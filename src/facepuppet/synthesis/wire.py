"""One wire (Singh & Fiume, SIGGRAPH 98): curves, the bind, the falloff and the deformation of points.

Conventions used by every function here
---------------------------------------
- A curve is a polyline of K >= 2 points, shape (K, 3). Its parameter is u in [0, K - 1]: u = j + t with
  segment j in {0, ..., K - 2} and t in [0, 1], so C(u) = (1 - t) C_j + t C_{j+1}. A reference curve R and its
  wire curve W share this parameterisation (the same K), which is what makes W(u) "the point of W that
  corresponds to R(u)".
- The unit tangent at a vertex is the normalised sum of the unit directions of its (one or two) segments; the
  tangent at u is the normalised linear interpolation of the tangents at the segment's ends. It is continuous
  along the curve, so the rotation below does not jump where a point's closest parameter crosses a vertex.
- Distances and the radius r are in the mesh's own units.

Formulas (the paper's notation)
-------------------------------
For a point p bound to the reference curve R (closest parameter u_p, so that R(u_p) is the point of R nearest
p), with radius r, scale s and falloff f:

    F(p) = f(||p - R(u_p)|| / r)                                  (influence, 1 on R, 0 beyond r)
    p_s  = R(u_p) + (1 + (s - 1) F) (p - R(u_p))                  (scale about R(u_p))
    p_r  = R(u_p) + Rot(a, F theta) (p_s - R(u_p))                (rotate about R(u_p))
    p_def = p_r + F (W(u_p) - R(u_p))                             (translate)

where a = R'(u_p) x W'(u_p) / ||...|| and theta = angle(R'(u_p), W'(u_p)) are the axis and angle of the
rotation that takes the reference tangent to the wire tangent. Antiparallel or degenerate tangents give no
rotation.

Falloff: the default is f(x) = (1 - x^2)^2 on [0, 1) and 0 for x >= 1: f(0) = 1, f'(0) = 0, f(1) = f'(1) = 0,
so the deformation is C1 across the boundary of the wire's reach.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "WireBind",
    "bind_points",
    "curve_at",
    "curve_tangents",
    "displace",
    "check_curve",
    "check_points",
    "check_positive",
    "falloff",
    "vertex_tangents",
    "wire_deform",
]

#: Below this length (in the curve's units) a tangent or a rotation axis counts as degenerate.
_EPS = 1e-12


def falloff(x: np.ndarray) -> np.ndarray:
    """Default falloff f(x) = (1 - x^2)^2 for 0 <= x < 1, else 0.

    Parameters
    ----------
    x : (...) float
        Distance to the reference curve divided by the radius (>= 0).

    Returns
    -------
    (...) float
        f(x): 1 at x = 0, 0 for x >= 1, C1 everywhere (f'(0) = f'(1) = 0).
    """
    x = np.asarray(x, dtype=float)
    y = np.clip(1.0 - x * x, 0.0, None)
    return y * y


def check_curve(curve, name: str, *, k: int | None = None, distinct: bool = False) -> np.ndarray:
    """Return ``curve`` as a (K, 3) float array, or raise ValueError naming ``name``.

    Parameters
    ----------
    curve : (K, 3) array_like
        Polyline points.
    name : str
        Argument name used in the error message.
    k : int, optional
        Required number of points.
    distinct : bool
        Require every segment to have a non-zero length (a reference curve must, to define its tangent).
    """
    c = np.asarray(curve, dtype=float)
    if c.ndim != 2 or c.shape[1] != 3 or c.shape[0] < 2:
        raise ValueError(f"{name} must have shape (K, 3) with K >= 2, got {np.shape(curve)}")
    if k is not None and c.shape[0] != k:
        raise ValueError(f"{name} must have {k} points (as the reference curve), got {c.shape[0]}")
    if not np.isfinite(c).all():
        raise ValueError(f"{name} must be finite")
    if distinct and (np.linalg.norm(np.diff(c, axis=0), axis=1) <= _EPS).any():
        raise ValueError(f"{name} has a zero-length segment (two equal consecutive points)")
    return c


def check_points(points, name: str = "points") -> np.ndarray:
    """Return ``points`` as an (N, 3) finite float array, or raise ValueError naming ``name``."""
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"{name} must have shape (N, 3), got {np.shape(points)}")
    if not np.isfinite(p).all():
        raise ValueError(f"{name} must be finite")
    return p


def check_positive(value, name: str) -> float:
    """Return ``value`` as a float > 0 (finite), or raise ValueError naming ``name``."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if not np.isfinite(v) or v <= 0:
        raise ValueError(f"{name} must be finite and > 0, got {value!r}")
    return v


def vertex_tangents(curve: np.ndarray) -> np.ndarray:
    """Unit tangents at a polyline's vertices.

    Parameters
    ----------
    curve : (K, 3) float

    Returns
    -------
    (K, 3) float
        Normalised sum of the unit directions of the segments meeting at each vertex; zero where degenerate.
    """
    e = np.diff(curve, axis=0)
    n = np.linalg.norm(e, axis=1, keepdims=True)
    e = np.divide(e, n, out=np.zeros_like(e), where=n > _EPS)
    t = np.zeros_like(curve)
    t[:-1] += e
    t[1:] += e
    n = np.linalg.norm(t, axis=1, keepdims=True)
    return np.divide(t, n, out=np.zeros_like(t), where=n > _EPS)


def curve_at(curve: np.ndarray, seg: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Points C(u) of a polyline at u = seg + t.

    Parameters
    ----------
    curve : (K, 3) float
    seg : (P,) int
        Segment index j in [0, K - 2].
    t : (P,) float
        Position in the segment, in [0, 1].

    Returns
    -------
    (P, 3) float
    """
    t = t[:, None]
    return (1.0 - t) * curve[seg] + t * curve[seg + 1]


def curve_tangents(tangents: np.ndarray, seg: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Unit tangents at u = seg + t, interpolated from the vertex tangents (zero where degenerate).

    Parameters
    ----------
    tangents : (K, 3) float
        From :func:`vertex_tangents`.
    seg : (P,) int
    t : (P,) float

    Returns
    -------
    (P, 3) float
    """
    v = curve_at(tangents, seg, t)
    n = np.linalg.norm(v, axis=1, keepdims=True)
    return np.divide(v, n, out=np.zeros_like(v), where=n > _EPS)


@dataclass(frozen=True)
class WireBind:
    """The bind of points to one reference curve: closest parameters and distances.

    Attributes
    ----------
    seg : (N,) int
        Segment j of the closest point R(u_p), u_p = seg + t.
    t : (N,) float
        Position in that segment, in [0, 1].
    closest : (N, 3) float
        R(u_p).
    distance : (N,) float
        ||p - R(u_p)||.
    """

    seg: np.ndarray
    t: np.ndarray
    closest: np.ndarray
    distance: np.ndarray

    @property
    def u(self) -> np.ndarray:
        """(N,) float closest parameter u_p in [0, K - 1]."""
        return self.seg + self.t


def bind_points(points: np.ndarray, reference: np.ndarray) -> WireBind:
    """Closest parameter u_p on the polyline ``reference`` for each point (the bind).

    Parameters
    ----------
    points : (N, 3) float
    reference : (K, 3) float
        Polyline (a zero-length segment binds at its start).

    Returns
    -------
    WireBind
        Ties between segments go to the lower segment index.
    """
    px, py, pz = (np.ascontiguousarray(points[:, c]) for c in range(3))
    n = len(points)
    best = np.full(n, np.inf)
    seg = np.zeros(n, dtype=np.intp)
    tt = np.zeros(n)
    for j in range(len(reference) - 1):
        a, e = reference[j], reference[j + 1] - reference[j]
        ee = float(e @ e)
        rx, ry, rz = px - a[0], py - a[1], pz - a[2]
        t = (rx * e[0] + ry * e[1] + rz * e[2]) / ee if ee > 0 else np.zeros(n)
        np.clip(t, 0.0, 1.0, out=t)
        rx -= t * e[0]
        ry -= t * e[1]
        rz -= t * e[2]
        d2 = rx * rx + ry * ry + rz * rz
        better = d2 < best
        best[better], seg[better], tt[better] = d2[better], j, t[better]
    closest = curve_at(reference, seg, tt)
    return WireBind(seg=seg, t=tt, closest=closest, distance=np.linalg.norm(points - closest, axis=1))


def displace(offset: np.ndarray, influence: np.ndarray, ref_tangent: np.ndarray, translate: np.ndarray,
             wire_tangent: np.ndarray, scale: np.ndarray | float) -> np.ndarray:
    """Deformed position minus R(u_p) of bound points: the scale, rotation and translation of one wire.

    Arrays are component-major (3, P): row c holds coordinate c of every point, so each step is a pass over
    contiguous rows.

    Parameters
    ----------
    offset : (3, P) float
        p - R(u_p).
    influence : (P,) float
        F(p).
    ref_tangent, wire_tangent : (3, P) float
        Unit tangents R'(u_p), W'(u_p) (zero columns: no rotation).
    translate : (3, P) float
        W(u_p) - R(u_p).
    scale : float or (P,) float
        s.

    Returns
    -------
    (3, P) float
        p_def - R(u_p) (see the module's formulas).
    """
    f = influence
    g = 1.0 + (scale - 1.0) * f
    v = offset * g                                                               # scaled offset (3, P)
    (ax, ay, az), (bx, by, bz) = ref_tangent, wire_tangent
    k = np.empty_like(v)                                                         # R' x W'
    np.multiply(ay, bz, out=k[0])
    k[0] -= az * by
    np.multiply(az, bx, out=k[1])
    k[1] -= ax * bz
    np.multiply(ax, by, out=k[2])
    k[2] -= ay * bx
    sin = np.sqrt(k[0] * k[0] + k[1] * k[1] + k[2] * k[2])
    cos = ax * bx + ay * by + az * bz
    turn = sin > _EPS
    k *= turn / np.maximum(sin, _EPS)                                            # unit axis (0: no turn)
    phi = np.arctan2(sin, cos)
    phi *= f * turn                                                              # F theta (0: no turn)
    c, s = np.cos(phi), np.sin(phi)
    kv = k[0] * v[0] + k[1] * v[1] + k[2] * v[2]
    kv *= 1.0 - c
    out = v * c
    out[0] += (k[1] * v[2] - k[2] * v[1]) * s
    out[1] += (k[2] * v[0] - k[0] * v[2]) * s
    out[2] += (k[0] * v[1] - k[1] * v[0]) * s
    out += k * kv
    out += translate * f
    return out


def wire_deform(points, reference, wire, radius, *, scale: float = 1.0) -> np.ndarray:
    """Deform points with one wire (Singh & Fiume): reference curve R, wire curve W, radius r, scale s.

    Parameters
    ----------
    points : (N, 3) array_like
        Points to deform (mesh vertices).
    reference : (K, 3) array_like
        Reference curve R, a polyline of K >= 2 points with non-zero segments.
    wire : (K, 3) array_like
        Wire curve W, the same K points moved.
    radius : float
        Influence radius r > 0 (the points' units).
    scale : float
        Scale s about R(u_p) (1: no scaling).

    Returns
    -------
    (N, 3) float
        p_def per point; points farther than r from R are returned unchanged.

    Notes
    -----
    The bind, the falloff f(x) = (1 - x^2)^2 and the formulas are in the module docstring
    (:mod:`facepuppet.synthesis.wire`). With W = R and s = 1 nothing moves; with W = R + d every point at
    distance x r from R moves by f(x) d.

    Example
    -------
    >>> R = [[0, 0, 0], [1, 0, 0]]
    >>> wire_deform([[0.5, 0, 0]], R, [[0, 1, 0], [1, 1, 0]], 0.5)
    array([[0.5, 1. , 0. ]])
    """
    p = check_points(points)
    r_curve = check_curve(reference, "reference", distinct=True)
    w_curve = check_curve(wire, "wire", k=len(r_curve))
    r = check_positive(radius, "radius")
    s = float(scale)
    if not np.isfinite(s):
        raise ValueError(f"scale must be finite, got {scale!r}")
    out = p.copy()
    if len(p) == 0:
        return out
    b = bind_points(p, r_curve)
    near = b.distance < r
    if not near.any():
        return out
    seg, t = b.seg[near], b.t[near]
    f = falloff(b.distance[near] / r)
    ref_t = curve_tangents(vertex_tangents(r_curve), seg, t)
    wire_t = curve_tangents(vertex_tangents(w_curve), seg, t)
    rp = b.closest[near]
    move = displace((p[near] - rp).T, f, ref_t.T, (curve_at(w_curve, seg, t) - rp).T, wire_t.T, s)
    out[near] = rp + move.T
    return out
