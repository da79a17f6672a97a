"""Each key-model represented by its wires: wire curves W_i plus (r, s) per wire, fitted to reproduce it.

For key-model T_i and the character's vertex paths P_k (reference curves R_k = T_B[P_k]) the wire curves are
W_ik = T_i[P_k]. A wire is active for T_i when its curve moves (max ||W_ik - R_k|| > ``options.active`` times
T_i's largest vertex motion); the active wires' radii r_ik and scales s_ik minimise

    sum_v || D_i(T_B)(v) - T_i(v) ||^2,

D_i the wire deformation of T_B by the active wires (:class:`~facepuppet.synthesis.WireDeformer`), by
bounded least squares (``scipy.optimize.least_squares``) from the best of a small grid of common radii.
The relative reproduction error of T_i is ||D_i(T_B) - T_i|| / ||T_i - T_B|| (Frobenius norms over all
vertices; 0 for a key-model that moves nothing and is reproduced exactly).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import least_squares

from facepuppet.io.character import Character
from facepuppet.synthesis.deformer import DEFAULT_EXPONENT, WireDeformer
from facepuppet.synthesis.paths import FindOptions, check_paths, find_wire_paths
from facepuppet.synthesis.regions import region_masks

__all__ = ["CharacterWires", "FitOptions", "fit_wires", "reproduction_errors"]


@dataclass(frozen=True, kw_only=True)
class FitOptions:
    """Options of :func:`fit_wires`.

    Attributes
    ----------
    max_radius : float
        Largest radius, as a fraction of the neutral mesh's bounding-box diagonal (dimensionless).
    min_radius : float
        Smallest radius, same unit.
    scale_bounds : (float, float)
        Bounds of the scales s (dimensionless).
    radius_grid : tuple of float
        Starting radii tried (all active wires alike), as fractions of the largest radius.
    active : float
        A wire takes part when its curve moves by more than this fraction of the key-model's largest vertex
        motion (dimensionless).
    exponent : float
        m of the combination of several wires.
    max_nfev : int
        Most residual evaluations of each key-model's least-squares fit.
    fit_points : int
        Most vertices in each fit's residual (an even stride through the vertices the active wires reach);
        the reported errors use every vertex.
    """

    max_radius: float = 0.2
    min_radius: float = 0.005
    scale_bounds: tuple[float, float] = (0.25, 4.0)
    radius_grid: tuple[float, ...] = (0.05, 0.1, 0.2, 0.35, 0.5, 0.75, 1.0)
    active: float = 0.1
    exponent: float = DEFAULT_EXPONENT
    max_nfev: int = 40
    fit_points: int = 1000


@dataclass(frozen=True)
class CharacterWires:
    """A character's key-models represented by wires.

    Attributes
    ----------
    neutral : (V, 3) float
        T_B.
    names : tuple of str
        Wire names (n_wires).
    paths : tuple of (K_k,) int arrays
        Vertex paths; the reference curves are ``neutral[paths[k]]``.
    key_names : tuple of str
        Key-model names (M).
    curves : tuple of (M, K_k, 3) float arrays
        Wire curves W_ik = T_i[paths[k]] per wire k.
    radii : (M, n_wires) float
        Fitted r_ik (the mesh's units; inactive wires: the largest radius).
    scales : (M, n_wires) float
        Fitted s_ik (inactive wires: 1).
    active : (M, n_wires) bool
        Wires taking part in each key-model.
    exponent : float
        m of the combination.
    errors : (M,) float
        Relative reproduction error of each key-model.
    """

    neutral: np.ndarray
    names: tuple[str, ...]
    paths: tuple[np.ndarray, ...]
    key_names: tuple[str, ...]
    curves: tuple[np.ndarray, ...]
    radii: np.ndarray
    scales: np.ndarray
    active: np.ndarray
    exponent: float
    errors: np.ndarray

    @property
    def references(self) -> list[np.ndarray]:
        """Reference curves R_k = T_B[P_k], each (K_k, 3)."""
        return [self.neutral[p] for p in self.paths]

    def wire_curves(self, i: int) -> list[np.ndarray]:
        """Wire curves of key-model ``i``, each (K_k, 3)."""
        return [c[i] for c in self.curves]

    def reproduce(self, i: int) -> np.ndarray:
        """(V, 3) float: T_B deformed by key-model ``i``'s active wires with their fitted (r, s)."""
        act = np.flatnonzero(self.active[i])
        if len(act) == 0:
            return self.neutral.copy()
        refs = self.references
        d = WireDeformer(self.neutral, [refs[k] for k in act], self.radii[i, act], exponent=self.exponent)
        return d.deform([self.curves[k][i] for k in act], self.scales[i, act])


    def regions(self) -> tuple[np.ndarray, tuple[str, ...]]:
        """Region masks from the wires' influence, for the regional mapping (``fit(..., regions=...)``).

        Each wire's influence F_k at its largest fitted radius over the key-models it takes part in
        (:meth:`WireDeformer.influence`), made a partition of unity by :func:`region_masks` (background first).
        Names: ``background``, then each wire's name by its leading lowercase word and side (``jawOpen`` ->
        ``jaw``, ``eyeBlink_L`` -> ``eye_L``; repeated ones numbered ``_2``, ``_3``).

        Returns
        -------
        masks : (n_wires + 1, V) float
        names : tuple of n_wires + 1 str
        """
        radii = np.where(self.active, self.radii, 0.0).max(axis=0)
        radii = np.where(radii > 0, radii, self.radii.max(axis=0))
        influence = WireDeformer(self.neutral, self.references, radii, exponent=self.exponent).influence()
        names = ["background"]
        for n in self.names:
            side = n[-2:] if n.endswith(("_L", "_R")) else ""
            word = re.match(r"[a-z]+", n)
            name = base = (word.group(0) if word else n[: len(n) - len(side)]) + side
            j = 2
            while name in names:
                name, j = f"{base}_{j}", j + 1
            names.append(name)
        return region_masks(influence), tuple(names)

    def with_curve(self, i: int, k: int, curve) -> CharacterWires:
        """A copy whose key-model ``i`` has wire ``k``'s curve replaced by ``curve`` (K_k, 3) (an edit).

        The wire becomes active for key-model ``i`` (with its fitted or the largest radius). Only the
        vertices that wire reaches (closer than its radius to R_k) can change in :meth:`reproduce`.
        """
        c = np.asarray(curve, dtype=float)
        if c.shape != self.curves[k].shape[1:] or not np.isfinite(c).all():
            raise ValueError(f"curve must be a finite {self.curves[k].shape[1:]} array, got shape {c.shape}")
        curves = list(self.curves)
        curves[k] = curves[k].copy()
        curves[k][i] = c
        active = self.active.copy()
        active[i, k] = True
        return replace(self, curves=tuple(curves), active=active)

    def synthesize(self, weights) -> np.ndarray:
        """The paper's wire-based synthesis: blend the key-models' wires, then deform T_B with them.

        For weights w (M,): W_k(w) = R_k + sum_i w_i a_ik (W_ik - R_k), s_k(w) = 1 + sum_i w_i a_ik (s_ik - 1)
        and r_k(w) = sum_i w_i a_ik r_ik / sum_i w_i a_ik (the bound radius when no active key-model has
        weight), a_ik = ``active``; the mesh is T_B deformed by all wires (:class:`WireDeformer`, bound once at
        the largest radii). With w = e_i it is :meth:`reproduce` (i); with w = 0 it is T_B.

        Parameters
        ----------
        weights : (M,) or (F, M) float

        Returns
        -------
        (V, 3) or (F, V, 3) float
        """
        w = np.asarray(weights, dtype=float)
        m = len(self.key_names)
        if w.shape[-1:] != (m,) or w.ndim not in (1, 2) or not np.isfinite(w).all():
            raise ValueError(f"weights must be finite with shape ({m},) or (F, {m}), got {w.shape}")
        frames = np.atleast_2d(w)
        refs = self.references
        bound = np.where(self.active, self.radii, 0.0).max(axis=0)
        bound = np.where(bound > 0, bound, self.radii.max(axis=0))
        deformer = WireDeformer(self.neutral, refs, bound, exponent=self.exponent, names=self.names)
        a = self.active.astype(float)
        out = np.empty((len(frames), len(self.neutral), 3))
        for f, wf in enumerate(frames):
            wa = wf[:, None] * a                                                   # (M, n_wires)
            curves = [r + np.tensordot(wa[:, k], c - r[None], 1) for k, (r, c) in enumerate(zip(refs, self.curves,
                                                                                              strict=True))]
            scales = 1.0 + (wa * (self.scales - 1.0)).sum(axis=0)
            tot = wa.sum(axis=0)
            radii = np.where(tot != 0, (wa * self.radii).sum(axis=0) / np.where(tot != 0, tot, 1.0), bound)
            out[f] = deformer.deform(curves, scales, radii=np.clip(radii, 1e-12, bound))
        return out[0] if w.ndim == 1 else out


def reproduction_errors(character: Character, wires: CharacterWires) -> np.ndarray:
    """Relative reproduction error of each key-model: ||D_i(T_B) - T_i|| / ||T_i - T_B||.

    Parameters
    ----------
    character : Character
        The character ``wires`` was fitted to (same vertices and key-models).
    wires : CharacterWires

    Returns
    -------
    (M,) float
        0 where a key-model that moves nothing is reproduced exactly (inf if it is not).
    """
    base = np.asarray(character.neutral, dtype=float)
    if base.shape != wires.neutral.shape or len(character.targets) != len(wires.key_names):
        raise ValueError("wires: fitted to another character (vertex or key-model counts differ)")
    out = np.empty(len(character.targets))
    for i, target in enumerate(np.asarray(character.targets, dtype=float)):
        out[i] = _relative(wires.reproduce(i), target, base)
    return out


def _relative(got: np.ndarray, target: np.ndarray, base: np.ndarray) -> float:
    num = np.linalg.norm(got - target)
    den = np.linalg.norm(target - base)
    if den == 0:
        return 0.0 if num == 0 else float("inf")
    return float(num / den)


def fit_wires(character: Character, paths: Mapping | None = None, options: FitOptions | None = None, *,
              find: FindOptions | None = None) -> CharacterWires:
    """Represent each key-model of a character by its wire curves and fitted (r, s) per wire.

    Parameters
    ----------
    character : Character
    paths : mapping of str to (K,) int, optional
        Named vertex paths (e.g. from :func:`~facepuppet.synthesis.read_wire_paths`); default: found with
        :func:`~facepuppet.synthesis.find_wire_paths` (``find`` options).
    options : FitOptions, optional
    find : FindOptions, optional

    Returns
    -------
    CharacterWires
        With ``errors`` the relative reproduction error per key-model (module docstring).
    """
    opts = options or FitOptions()
    lo_s, hi_s = (float(v) for v in opts.scale_bounds)
    if not 0 < lo_s <= 1 <= hi_s:
        raise ValueError(f"options.scale_bounds must satisfy 0 < low <= 1 <= high, got {opts.scale_bounds}")
    if not 0 < opts.min_radius < opts.max_radius:
        raise ValueError("options: need 0 < min_radius < max_radius")
    base = np.asarray(character.neutral, dtype=float)
    targets = np.asarray(character.targets, dtype=float)
    if paths is None:
        paths = find_wire_paths(character, find)
    checked = check_paths(paths, len(base), character.faces, where="paths")
    names = tuple(checked)
    plist = tuple(checked[n] for n in names)
    refs = [base[p] for p in plist]
    diag = float(np.linalg.norm(base.max(axis=0) - base.min(axis=0)))
    r_hi, r_lo = opts.max_radius * diag, opts.min_radius * diag
    whole = WireDeformer(base, refs, r_hi, exponent=opts.exponent, names=names)
    m, n = len(targets), len(refs)
    radii, scales = np.full((m, n), r_hi), np.ones((m, n))
    active = np.zeros((m, n), dtype=bool)
    errors = np.zeros(m)
    curves = tuple(targets[:, p] for p in plist)
    for i in range(m):
        motion = np.linalg.norm(targets[i] - base, axis=1).max()
        moved = np.array([np.linalg.norm(c[i] - r, axis=1).max() for c, r in zip(curves, refs, strict=True)])
        act = np.flatnonzero((moved > opts.active * motion) & (moved > 0))
        active[i, act] = True
        if len(act) == 0:
            errors[i] = _relative(base, targets[i], base)
            continue
        r, s = _fit_one(whole, base, targets[i], refs, [c[i] for c in curves], act, (r_lo, r_hi), (lo_s, hi_s),
                        opts)
        radii[i, act], scales[i, act] = r, s
    result = CharacterWires(neutral=base, names=names, paths=plist, key_names=tuple(character.names),
                            curves=curves, radii=radii, scales=scales, active=active, exponent=opts.exponent,
                            errors=errors)
    for i in range(m):
        if active[i].any():
            errors[i] = _relative(result.reproduce(i), targets[i], base)
    return result


def _fit_one(whole: WireDeformer, base, target, refs, wires, act, r_bounds, s_bounds, opts: FitOptions):
    """Least-squares (r, s) of the active wires ``act`` for one key-model."""
    reach = np.isin(whole.pair_wire, act)
    near = np.unique(whole.pair_point[reach])
    if len(near) > opts.fit_points:
        near = near[np.linspace(0, len(near) - 1, opts.fit_points).round().astype(np.intp)]
    sub = WireDeformer(base[near], [refs[k] for k in act], r_bounds[1], exponent=opts.exponent)
    w = [wires[k] for k in act]
    goal = target[near]
    n = len(act)

    def residual(x):
        return (sub.deform(w, x[n:], radii=x[:n]) - goal).ravel()

    best, start = np.inf, None
    for frac in opts.radius_grid:
        r0 = np.full(n, np.clip(frac * r_bounds[1], *r_bounds))
        x0 = np.concatenate([r0, np.ones(n)])
        cost = float(np.sum(residual(x0) ** 2))
        if cost < best:
            best, start = cost, x0
    lo = np.concatenate([np.full(n, r_bounds[0]), np.full(n, s_bounds[0])])
    hi = np.concatenate([np.full(n, r_bounds[1]), np.full(n, s_bounds[1])])
    fit = least_squares(residual, np.clip(start, lo, hi), bounds=(lo, hi), x_scale="jac", max_nfev=opts.max_nfev)
    x = fit.x if 2 * fit.cost <= best else start
    return x[:n], x[n:]
