"""Several wires on one bound mesh: bind once, then deform every frame with vectorised numpy.

Several wires combine by Singh & Fiume's displacement-weighted rule. With Delta p_k = p_def,k - p the
displacement wire k alone gives a point p (see :mod:`facepuppet.synthesis.wire`),

    p_def = p + sum_k Delta p_k ||Delta p_k||^m / sum_k ||Delta p_k||^m,

the sums running over the wires whose radius reaches p (F_k(p) > 0); a point that no wire moves stays put.
m = 0 averages the wires' displacements, larger m lets the wire that moves a point most dominate it. The
default exponent is :data:`DEFAULT_EXPONENT`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from facepuppet.synthesis._kernels import deform_pairs
from facepuppet.synthesis.wire import (
    bind_points,
    check_curve,
    check_points,
    check_positive,
    curve_tangents,
    displace,
    falloff,
    vertex_tangents,
)

__all__ = ["DEFAULT_EXPONENT", "WireDeformer", "combine_displacements"]

#: Exponent m of the displacement-weighted combination of several wires (dimensionless).
DEFAULT_EXPONENT = 1.0


def combine_displacements(point_index: np.ndarray, delta: np.ndarray, n_points: int,
                          exponent: float = DEFAULT_EXPONENT, active: np.ndarray | None = None) -> np.ndarray:
    """Combine per-(wire, point) displacements into one displacement per point.

    Parameters
    ----------
    point_index : (P,) int
        The point each pair belongs to.
    delta : (P, 3) float
        Delta p_k of each pair.
    n_points : int
        N.
    exponent : float
        m >= 0.
    active : (P,) bool, optional
        Pairs whose wire reaches the point (F > 0); default all.

    Returns
    -------
    (N, 3) float
        sum_k Delta p_k ||Delta p_k||^m / sum_k ||Delta p_k||^m per point (0 where the denominator is 0).
    """
    d = np.ascontiguousarray(np.asarray(delta, dtype=float).T)
    return _combine(np.asarray(point_index), d, n_points, float(exponent), active).T.copy()


def _combine(point_index: np.ndarray, delta: np.ndarray, n_points: int, exponent: float,
             active: np.ndarray | None) -> np.ndarray:
    """:func:`combine_displacements` on component-major (3, P) displacements; returns (3, N)."""
    sq = delta[0] * delta[0] + delta[1] * delta[1] + delta[2] * delta[2]
    if exponent == 0:
        w = np.ones(len(sq))
    elif exponent == 1:
        w = np.sqrt(sq)
    elif exponent == 2:
        w = sq
    else:
        w = sq ** (0.5 * exponent)
    if active is not None:
        w = w * active
    den = np.bincount(point_index, weights=w, minlength=n_points)
    inv = (den > 0) / np.maximum(den, np.finfo(float).tiny)
    out = np.empty((3, n_points))
    for c in range(3):
        out[c] = np.bincount(point_index, weights=w * delta[c], minlength=n_points) * inv
    return out


class WireDeformer:
    """A mesh bound to several reference curves; deforms it for any wire curves, scales and smaller radii.

    Parameters
    ----------
    points : (N, 3) array_like
        The undeformed mesh vertices (e.g. the neutral T_B).
    references : sequence of (K_k, 3) array_like
        Reference curves R_k (polylines, K_k >= 2, non-zero segments).
    radii : float or (n_wires,) array_like
        Bound radii r_k > 0: the bind keeps the (wire, point) pairs closer than r_k. :meth:`deform` accepts
        radii up to these.
    exponent : float
        m >= 0 of the combination rule (module docstring).
    names : sequence of str, optional
        Wire names (default ``wire0``, ``wire1``, ...).
    dtype : float64 or float32
        Precision of the numpy per-frame passes (the bind and the output are float64). float32 is several
        times faster (numpy vectorises its trigonometry) at about 1e-7 of the mesh's size.
    compiled : bool
        :meth:`deform` by the compiled float64 pass (:mod:`facepuppet.synthesis._kernels`, one loop over
        the pairs, the fastest); False: the numpy passes (the reference, in ``dtype``).

    Notes
    -----
    The bind stores, for each pair with ||p - R_k(u_p)|| < r_k: the point, the wire, u_p, R_k(u_p),
    p - R_k(u_p), the distance and the unit reference tangent R_k'(u_p). :meth:`deform` then costs a few
    vectorised passes over those pairs and 4 ``bincount`` calls, with no loop over points.

    Example
    -------
    >>> import numpy as np
    >>> R = np.array([[0.0, 0, 0], [1, 0, 0]])
    >>> d = WireDeformer([[0.5, 0, 0], [0.5, 2, 0]], [R], 0.5)
    >>> d.deform([R + [0, 0, 1]])
    array([[0.5, 0. , 1. ],
           [0.5, 2. , 0. ]])
    """

    def __init__(self, points, references: Sequence, radii, *, exponent: float = DEFAULT_EXPONENT,
                 names: Sequence[str] | None = None, dtype=np.float64, compiled: bool = True) -> None:
        self.points = np.ascontiguousarray(check_points(points), dtype=np.float64)
        self.compiled = bool(compiled)
        if isinstance(references, np.ndarray) and references.ndim == 2:
            references = [references]
        refs = [check_curve(c, f"references[{k}]", distinct=True) for k, c in enumerate(references)]
        if not refs:
            raise ValueError("references must hold at least one curve")
        self.references = refs
        self.radii = self._check_radii(radii, None)
        m = float(exponent)
        if not np.isfinite(m) or m < 0:
            raise ValueError(f"exponent must be finite and >= 0, got {exponent!r}")
        self.exponent = m
        if names is None:
            names = [f"wire{k}" for k in range(len(refs))]
        if len(names) != len(refs):
            raise ValueError(f"names must hold {len(refs)} names, got {len(names)}")
        self.names = tuple(str(n) for n in names)
        self.dtype = np.dtype(dtype)
        if self.dtype not in (np.dtype(np.float64), np.dtype(np.float32)):
            raise ValueError(f"dtype must be float64 or float32, got {dtype!r}")
        self.sizes = np.array([len(c) for c in refs])
        self._start = np.concatenate([[0], np.cumsum(self.sizes)[:-1]])
        self._bind()

    @property
    def n_wires(self) -> int:
        """Number of wires."""
        return len(self.references)

    def _check_radii(self, radii, bound: np.ndarray | None) -> np.ndarray:
        n = len(self.references)
        r = np.asarray(radii, dtype=float)
        if r.ndim == 0:
            r = np.full(n, float(r))
        if r.shape != (n,):
            raise ValueError(f"radii must be a number or have shape ({n},), got {np.shape(radii)}")
        for k, v in enumerate(r):
            check_positive(v, f"radii[{k}]")
        if bound is not None and (r > bound * (1 + 1e-12)).any():
            k = int(np.argmax(r > bound * (1 + 1e-12)))
            raise ValueError(f"radii[{k}] = {r[k]:g} exceeds the bound radius {bound[k]:g}; bind again with it")
        return r

    def _bind(self) -> None:
        idx, wire, seg, t, dist, closest, tangent = [], [], [], [], [], [], []
        for k, ref in enumerate(self.references):
            b = bind_points(self.points, ref)
            near = np.flatnonzero(b.distance < self.radii[k])
            idx.append(near)
            wire.append(np.full(len(near), k, dtype=np.intp))
            seg.append(b.seg[near] + self._start[k])
            t.append(b.t[near])
            dist.append(b.distance[near])
            closest.append(b.closest[near])
            tangent.append(curve_tangents(vertex_tangents(ref), b.seg[near], b.t[near]))
        self.pair_point = np.concatenate(idx)
        self.pair_wire = np.concatenate(wire)
        self._seg = np.concatenate(seg)
        self._seg1 = self._seg + 1
        self._t = np.concatenate(t)
        self._1t = 1.0 - self._t
        self.pair_distance = np.concatenate(dist)
        closest = np.concatenate(closest).reshape(-1, 3)
        # component-major (3, P) copies for the per-frame passes
        self._closest = np.ascontiguousarray(closest.T)
        self._offset = np.ascontiguousarray((self.points[self.pair_point] - closest).T)
        self._tangent = np.ascontiguousarray(np.concatenate(tangent).reshape(-1, 3).T)
        self._influence = falloff(self.pair_distance / self.radii[self.pair_wire])
        # The compiled pass's layout (``_kernels``): pairs sorted by point, one row of PAIR_COLUMNS each.
        self._order = np.argsort(self.pair_point, kind="stable")
        rows = np.column_stack([self._t, closest, self._offset.T, self._tangent.T])
        self._rows64 = np.ascontiguousarray(rows[self._order], dtype=np.float64)
        self._by_point = {"point": self.pair_point[self._order].astype(np.int64),
                          "wire": self.pair_wire[self._order].astype(np.int64),
                          "seg": self._seg[self._order].astype(np.int64)}
        self._influence64 = np.ascontiguousarray(self._influence[self._order], dtype=np.float64)
        self.pair_point = self.pair_point.astype(np.int64)
        self.pair_wire = self.pair_wire.astype(np.int64)
        self._seg = self._seg.astype(np.int64)
        for name in ("_t", "_1t", "_closest", "_offset", "_tangent", "_influence"):
            setattr(self, name, getattr(self, name).astype(self.dtype))

    def influence(self, radii=None) -> np.ndarray:
        """Each wire's influence F_k on each point.

        Parameters
        ----------
        radii : float or (n_wires,) array_like, optional
            Radii <= the bound ones (default the bound ones).

        Returns
        -------
        (n_wires, N) float
            F_k(p) = f(||p - R_k(u_p)|| / r_k), 0 where wire k does not reach.
        """
        f = self._pair_influence(radii)
        out = np.zeros((self.n_wires, len(self.points)))
        out[self.pair_wire, self.pair_point] = f
        return out

    def _pair_influence(self, radii) -> np.ndarray:
        if radii is None:
            return self._influence
        r = self._check_radii(radii, self.radii)
        return falloff(self.pair_distance / r[self.pair_wire])

    def _wire_arrays(self, wires) -> tuple[np.ndarray, np.ndarray]:
        """Concatenated wire curves (sum K_k, 3) and their unit vertex tangents, checked."""
        if isinstance(wires, np.ndarray) and wires.ndim == 3:
            if wires.shape[0] != self.n_wires or wires.shape[2] != 3 or (self.sizes != wires.shape[1]).any():
                raise ValueError(f"wires must hold {self.n_wires} curves of sizes {self.sizes.tolist()}, "
                                 f"got shape {wires.shape}")
            pts = wires.reshape(-1, 3).astype(float, copy=False)
        else:
            if len(wires) != self.n_wires:
                raise ValueError(f"wires must hold {self.n_wires} curves, got {len(wires)}")
            curves = [np.asarray(c, dtype=float) for c in wires]
            for k, c in enumerate(curves):
                if c.shape != (self.sizes[k], 3):
                    check_curve(c, f"wires[{k}]", k=int(self.sizes[k]))       # raises, naming the curve
            pts = np.concatenate(curves)
        if not np.isfinite(pts).all():
            k = int(np.searchsorted(np.cumsum(self.sizes), np.flatnonzero(~np.isfinite(pts).all(1))[0], "right"))
            raise ValueError(f"wires[{k}] must be finite")
        # unit vertex tangents of every curve at once: segments joining two curves are left out
        e = np.diff(pts, axis=0)
        e[self._start[1:] - 1] = 0.0
        n = np.sqrt(np.einsum("ij,ij->i", e, e))[:, None]
        e = np.divide(e, n, out=np.zeros_like(e), where=n > 1e-12)
        tan = np.zeros_like(pts)
        tan[:-1] += e
        tan[1:] += e
        n = np.sqrt(np.einsum("ij,ij->i", tan, tan))[:, None]
        return pts, np.divide(tan, n, out=np.zeros_like(tan), where=n > 1e-12)

    def _deltas(self, wires, scales, radii) -> tuple[np.ndarray, np.ndarray]:
        """(3, P) displacements Delta p_k of the pairs and (P,) F."""
        w_pts, w_tan = self._wire_arrays(wires)
        if scales is None:
            s = 1.0
        else:
            sv = np.asarray(scales, dtype=float)
            if sv.ndim == 0:
                sv = np.full(self.n_wires, float(sv))
            if sv.shape != (self.n_wires,) or not np.isfinite(sv).all():
                raise ValueError(f"scales must be a finite number or have shape ({self.n_wires},), "
                                 f"got {np.shape(scales)}")
            s = sv[self.pair_wire].astype(self.dtype)
        f = self._pair_influence(radii).astype(self.dtype, copy=False)
        both = np.concatenate([w_pts.T, w_tan.T]).astype(self.dtype)       # (6, sum K): W and W'
        g = both.take(self._seg, axis=1)
        g *= self._1t
        g1 = both.take(self._seg1, axis=1)
        g1 *= self._t
        g += g1                                                             # W(u_p) and the lerped W'(u_p)
        translate, tangent = g[:3], g[3:]
        translate -= self._closest
        norm = np.sqrt(tangent[0] * tangent[0] + tangent[1] * tangent[1] + tangent[2] * tangent[2])
        tangent *= (norm > 1e-12) / np.maximum(norm, 1e-12)
        moved = displace(self._offset, f, self._tangent, translate, tangent, s)
        moved -= self._offset
        return moved, f

    def pair_displacements(self, wires, scales=None, *, radii=None) -> tuple[np.ndarray, np.ndarray]:
        """Each wire's own displacement Delta p_k of each bound pair.

        Parameters
        ----------
        wires : sequence of (K_k, 3) array_like, or (n_wires, K, 3) array
            Wire curves W_k, point for point with the reference curves.
        scales : float or (n_wires,) array_like, optional
            s_k (default 1).
        radii : float or (n_wires,) array_like, optional
            r_k <= the bound radii (default the bound radii).

        Returns
        -------
        delta : (P, 3) float
            p_def,k - p for each pair (``pair_point``, ``pair_wire``).
        influence : (P,) float
            F_k(p) of each pair.
        """
        delta, f = self._deltas(wires, scales, radii)
        return delta.T.copy(), f

    def deform(self, wires, scales=None, *, radii=None) -> np.ndarray:
        """Deformed mesh for the given wire curves.

        Parameters
        ----------
        wires : sequence of (K_k, 3) array_like, or (n_wires, K, 3) array
            Wire curves W_k.
        scales : float or (n_wires,) array_like, optional
            s_k (default 1).
        radii : float or (n_wires,) array_like, optional
            r_k <= the bound radii (default the bound radii).

        Returns
        -------
        (N, 3) float
            p + the combined displacement (module docstring).
        """
        if self.compiled:
            return self._deform_compiled(wires, scales, radii)
        delta, f = self._deltas(wires, scales, radii)
        active = None if radii is None else f > 0
        return self.points + _combine(self.pair_point, delta, len(self.points), self.exponent, active).T

    def _deform_compiled(self, wires, scales, radii) -> np.ndarray:
        w_pts, w_tan = self._wire_arrays(wires)
        if scales is None:
            sv = np.ones(self.n_wires)
        else:
            sv = np.asarray(scales, dtype=float)
            if sv.ndim == 0:
                sv = np.full(self.n_wires, float(sv))
            if sv.shape != (self.n_wires,) or not np.isfinite(sv).all():
                raise ValueError(f"scales must be a finite number or have shape ({self.n_wires},), "
                                 f"got {np.shape(scales)}")
        f = self._influence64 if radii is None else self._pair_influence(radii)[self._order].astype(np.float64)
        out = np.empty_like(self.points)
        b = self._by_point
        deform_pairs(self.points, b["point"], b["wire"], b["seg"], self._rows64, f, radii is not None,
                     np.ascontiguousarray(w_pts, dtype=np.float64), np.ascontiguousarray(w_tan, dtype=np.float64),
                     np.ascontiguousarray(sv, dtype=np.float64), float(self.exponent), out)
        return out
