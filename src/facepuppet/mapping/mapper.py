"""ExpressionMapper: the public face of the mapping stage (DESIGN.md, "Python")."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from facepuppet._util.atomic import atomic_path
from facepuppet.errors import FacepuppetError
from facepuppet.mapping._methods import DEFAULT_METHOD, METHODS, SOLVERS
from facepuppet.mapping._metric import nuisance_transform

__all__ = ["ExpressionMapper", "MapperOptions", "FORMAT", "FORMAT_VERSION"]

FORMAT = "facepuppet.ExpressionMapper"
FORMAT_VERSION = 1
_SOLVER_PREFIX = "solver_"
_REQUIRED = ("format", "version", "method", "solver", "source_base", "source_examples", "target_base",
             "target_deltas", "names")


@dataclass(frozen=True, kw_only=True)
class MapperOptions:
    """Options of :meth:`ExpressionMapper.fit`; ``None`` means "the method's own value".

    Attributes
    ----------
    method : str
        A name in ``facepuppet.mapping.METHODS`` (see :class:`ExpressionMapper`).
    bounds : (float, float), optional
        Box on every weight; must hold 0 and 1 (neutral and examples). Bounded methods only.
    ridge : float, optional
        Constant shrinkage of each weight towards zero, relative to the example's strength (``ridge``: 0.1).
    angle_ridge : float, optional
        Shrinkage that grows with the sine of the angle between a frame and the examples' span
        (``adaptive``: 0.2, ``bounded``: 0.3).
    noise_ridge : float, optional
        Inverse prior variance of the weights in the Bayesian ridge that grows with the noise variance
        estimated per frame (``adaptive``: 4, i.e. prior standard deviation 0.5).
    shrinkage : float in [0, 1], optional
        Share of the identity in the noise covariance of the metric (``bounded``: 0.7; 1 = Euclidean).
    correct : bool, optional
        Add the radial correction that makes the examples exact again after a constant ridge (by default
        on exactly when ``ridge`` > 0).
    threshold : float
        Relative eigenvalue threshold of the PCA (Eq. 6) and of the "cannot tell apart" diagnosis.
    names : tuple of M str, optional
        Names of the examples, used in messages and kept in the saved file.
    point_scale : (P, D) float, optional
        Noise scale of each feature coordinate (positive): every displacement, the examples' (Eq. 5) and the
        frames' (Eq. 13), is divided by it before the method sees it, so coordinates a tracker follows
        poorly count less (a generalised least squares with a diagonal noise covariance). None: all equal.
        Scaling keeps the guarantees (neutral and examples exact).
    nuisance : (K, P, D) float, optional
        Feature points of frames showing the performer's neutral face while the head moves (or the light
        changes): the directions in which they move away from ``source_base`` count less, in proportion to
        how much they move (a generalised least squares, :mod:`facepuppet.mapping._metric`).
    nuisance_floor : float in (0, 1]
        How far the nuisance directions are discounted: the noise floor as a share of the largest nuisance
        variance (smaller discounts more).
    """

    method: str = DEFAULT_METHOD
    bounds: tuple[float, float] | None = None
    ridge: float | None = None
    angle_ridge: float | None = None
    noise_ridge: float | None = None
    shrinkage: float | None = None
    correct: bool | None = None
    threshold: float = 1e-5
    names: tuple[str, ...] | None = None
    point_scale: object = None
    nuisance: object = None
    nuisance_floor: float = 1e-4


def _array(x, name: str, ndim: int, last: int | tuple[int, ...] | None = None) -> np.ndarray:
    try:
        a = np.asarray(x, dtype=float)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{name} must be an array of numbers ({e})") from e
    if a.ndim != ndim:
        raise ValueError(f"{name} must have {ndim} dimensions, got shape {a.shape}")
    if last is not None and a.shape[-1] not in np.atleast_1d(last):
        raise ValueError(f"{name} must have last dimension {' or '.join(map(str, np.atleast_1d(last)))}, "
                         f"got shape {a.shape}")
    if 0 in a.shape:
        raise ValueError(f"{name} is empty (shape {a.shape})")
    if not np.isfinite(a).all():
        bad = np.argwhere(~np.isfinite(a))[0]
        raise ValueError(f"{name} holds NaN or inf (first at index {tuple(int(i) for i in bad)})")
    return a


def _resolve(opts: MapperOptions, m: int) -> dict:
    """The option values the method runs with, checked."""
    if opts.method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)}; got {opts.method!r}")
    spec = METHODS[opts.method]
    out = dict(spec.defaults)
    for key in ("bounds", "ridge", "angle_ridge", "noise_ridge", "shrinkage", "correct"):
        value = getattr(opts, key)
        if value is None:
            continue
        if key not in out:
            raise ValueError(f"option {key!r} does not apply to method {opts.method!r}")
        out[key] = value
    if "bounds" in out:
        lo, hi = (float(b) for b in out["bounds"])
        if math.isnan(lo) or math.isnan(hi) or not (lo <= 0.0 and hi >= 1.0):
            raise ValueError(f"bounds must hold 0 and 1 (neutral and examples), got {out['bounds']}")
        out["bounds"] = (lo, hi)
    for key in ("ridge", "angle_ridge", "noise_ridge"):
        if key in out and not (0.0 <= float(out[key]) < math.inf):
            raise ValueError(f"{key} must be a finite number >= 0, got {out[key]}")
    if "correct" in out and out["correct"] is None:
        out["correct"] = float(out["ridge"]) > 0.0
    if "shrinkage" in out and not (0.0 <= float(out["shrinkage"]) <= 1.0):
        raise ValueError(f"shrinkage must lie in [0, 1], got {out['shrinkage']}")
    if not (0.0 < opts.threshold < 1.0):
        raise ValueError(f"threshold must lie in (0, 1), got {opts.threshold}")
    out["threshold"] = float(opts.threshold)
    if not (0.0 < opts.nuisance_floor <= 1.0):
        raise ValueError(f"nuisance_floor must lie in (0, 1], got {opts.nuisance_floor}")
    if opts.names is not None:
        names = tuple(str(n) for n in opts.names)
        if len(names) != m:
            raise ValueError(f"names must hold {m} example names (one per example), got {len(names)}")
        if len(set(names)) != m:
            raise ValueError(f"names must be unique; repeated: {sorted({n for n in names if names.count(n) > 1})}")
    return out


class ExpressionMapper:
    """Blend weights of a character's key-models from a performer's feature points (paper §4–5).

    Fit once from paired examples, then map every frame: ``weights`` (Eq. 13 and a weight function per
    key-model) and ``synthesize`` (Eq. 14).

    Methods (``fit(..., method=NAME)``; the table is ``facepuppet.mapping.METHODS``):

    ``"adaptive"`` (default)
        The most accurate mapping here, over many held-out ICT scenes (``benchmarks/eval_mapping_variants.py``).
        ``bounded`` (below) with a smaller angle ridge (0.2) plus a Bayesian ridge: the frame's noise variance
        is estimated from the part of its motion the examples cannot express, and the weights get a Gaussian
        prior (standard deviation 0.5) weighed against it, so noisy frames shrink most the weights of the
        examples that barely move the points. Same guarantees as ``bounded``.
    ``"bounded"``
        Least squares of the frame's feature displacement on the examples' displacements, in the PCA
        parameter space with a shrinkage-whitened metric (30 % the examples' own covariance, 70 % isotropic),
        weights kept in [0, 1], and a ridge relative to each example's strength that grows with the sine of
        the angle between the frame and the examples' span: motion the examples cannot express is damped
        instead of turned into spurious weights.
        Guarantees: neutral → all-zero weights, example i → e_i, every blend of the examples with weights
        in [0, 1] reproduced exactly, continuous in the input.
    ``"ridge"``
        As ``bounded`` but with a constant ridge (0.1) instead of the angle-dependent one, and cubic B-spline
        radial bases at the examples (paper §5.3) that restore exact interpolation there. Neutral and
        examples exact; blends are shrunk, not reproduced.
    ``"lsq"``
        Least squares of the feature displacements with weights in [0, 1] (Euclidean metric, no ridge).
        Reproduces every blend with weights in [0, 1] exactly; neutral and examples exact.
    ``"linear"``
        Unbounded least squares (the orthogonal projection on the examples). Reproduces every blend, even
        with negative weights or weights over 1; extrapolates freely.
    ``"paper"``
        The paper exactly: centred PCA with the eigenvalue threshold relative to the largest (Eqs. 5–7),
        linear bases by least squares (Eq. 9) and cubic B-spline radial bases with α = distance to the
        nearest other example (Eqs. 10–12), unbounded. The neutral face is one more data point with weights
        zero, so neutral → neutral and example → key-model are exact. It does not reproduce blends in general.

    Attributes
    ----------
    n_examples, n_points, dim, n_vertices : int
        M, P, D and V.
    method : str
    names : tuple of str or None
    options : dict
        The option values the method ran with.
    feature_matrix : (N̄, P·D) float
        F of Eq. 6 (rows: kept eigenvectors).
    example_params : (M, N̄) float
        p_i = F v_i (Eq. 7).
    source_base : (P, D) float
    target_base : (V, 3) float
    target_deltas : (M, V, 3) float
        T_i − T_B.

    Example
    -------
    >>> m = ExpressionMapper.fit(SB, S, TB, T)          # doctest: +SKIP
    >>> mesh = m.synthesize(m.weights(points))          # doctest: +SKIP
    """

    def __init__(self, *, method: str, solver, source_base: np.ndarray, source_examples: np.ndarray,
                 target_base: np.ndarray, target_deltas: np.ndarray, names: tuple[str, ...] | None,
                 options: dict, point_scale: np.ndarray | None = None, whiten: np.ndarray | None = None) -> None:
        self.method = method
        self._solver = solver
        self.source_base = source_base
        self._source_examples = source_examples
        self.target_base = target_base
        self.target_deltas = target_deltas
        self.names = names
        self.options = options
        self.n_examples, self.n_points, self.dim = source_examples.shape
        self.n_vertices = target_base.shape[0]
        self._s_flat = source_base.reshape(-1)
        self.point_scale = point_scale
        self._inv_scale = None if point_scale is None else 1.0 / point_scale.reshape(-1)
        self.whiten = whiten
        self._t_flat = target_base.reshape(-1)
        self._d_flat = np.ascontiguousarray(target_deltas.reshape(self.n_examples, -1))

    # ----------------------------------------------------------------------------------------- fitting
    @classmethod
    def fit(cls, source_base, source_examples, target_base, target_examples, **options) -> ExpressionMapper:
        """Fit a mapper from paired examples.

        Parameters
        ----------
        source_base : (P, D) float
            The performer's neutral feature points S_B, D = 2 or 3.
        source_examples : (M, P, D) float
            The performer's key expressions S_i; example i pairs with target example i.
        target_base : (V, 3) float
            The character's neutral mesh T_B.
        target_examples : (M, V, 3) float
            The character's key-models T_i.
        **options
            Fields of :class:`MapperOptions` (``method``, ``bounds``, ``ridge``, ``angle_ridge``,
            ``noise_ridge``, ``shrinkage``, ``correct``, ``threshold``, ``names``, ``point_scale``,
            ``nuisance``, ``nuisance_floor``).

        Returns
        -------
        ExpressionMapper

        Raises
        ------
        ValueError
            Wrong shapes, NaN/inf, mismatched counts, unknown or invalid options.
        FacepuppetError
            The feature points cannot tell examples apart (named in the message), or a system is singular.
        """
        try:
            opts = MapperOptions(**options)
        except TypeError as e:
            known = ", ".join(MapperOptions.__dataclass_fields__)
            raise ValueError(f"unknown option in {sorted(options)}; known options: {known}") from e
        sb = _array(source_base, "source_base", 2, (2, 3))
        se = _array(source_examples, "source_examples", 3)
        tb = _array(target_base, "target_base", 2, 3)
        te = _array(target_examples, "target_examples", 3)
        if se.shape[1:] != sb.shape:
            raise ValueError(f"source_examples must have shape (M, {sb.shape[0]}, {sb.shape[1]}) like "
                             f"source_base, got {se.shape}")
        if te.shape[1:] != tb.shape:
            raise ValueError(f"target_examples must have shape (M, {tb.shape[0]}, 3) like target_base, "
                             f"got {te.shape}")
        if len(se) != len(te):
            raise ValueError(f"source_examples and target_examples must hold the same number of examples, "
                             f"got {len(se)} and {len(te)}")
        resolved = _resolve(opts, len(se))
        names = tuple(str(n) for n in opts.names) if opts.names is not None else None
        scale = None
        if opts.point_scale is not None:
            scale = _array(opts.point_scale, "point_scale", 2, sb.shape[1])
            if scale.shape != sb.shape or not (scale > 0).all():
                raise ValueError(f"point_scale must be positive with shape {sb.shape} like source_base, got "
                                 f"shape {scale.shape}" + ("" if scale.shape != sb.shape else " with values <= 0"))
        whiten = None
        if opts.nuisance is not None:
            nu = _array(opts.nuisance, "nuisance", 3)
            if nu.shape[1:] != sb.shape:
                raise ValueError(f"nuisance must have shape (K, {sb.shape[0]}, {sb.shape[1]}) like source_base, "
                                 f"got {nu.shape}")
            whiten = nuisance_transform(_displacements(nu, sb, scale), float(opts.nuisance_floor))
        V = _displacements(se, sb, scale, whiten)  # Eq. 5
        solver = METHODS[opts.method].solver.fit(V, resolved, names)
        return cls(method=opts.method, solver=solver, source_base=sb, source_examples=se, target_base=tb,
                   target_deltas=te - tb[None], names=names, options=resolved, point_scale=scale, whiten=whiten)

    # ----------------------------------------------------------------------------------------- runtime
    def weights(self, points) -> np.ndarray:
        """Blend weights of the key-models for one frame or a batch (Eqs. 13 and 8).

        Parameters
        ----------
        points : (P, D) or (F, P, D) float
            Feature points in the same coordinates as ``source_base`` (head pose removed). Select the valid
            frames of a track first: NaN or inf is an error.

        Returns
        -------
        (M,) or (F, M) float
        """
        x = np.asarray(points, dtype=float)
        single = x.ndim == 2
        if x.shape[-2:] != (self.n_points, self.dim) or x.ndim not in (2, 3):
            raise ValueError(f"points must have shape ({self.n_points}, {self.dim}) or "
                             f"(F, {self.n_points}, {self.dim}), got {x.shape}")
        D = x.reshape(-1 if not single else 1, self._s_flat.size) - self._s_flat
        if not np.isfinite(D).all():
            f = int(np.flatnonzero(~np.isfinite(D).all(1))[0])
            raise ValueError(f"points hold NaN or inf (frame {f}); map only the valid frames")
        if self._inv_scale is not None:
            D = D * self._inv_scale
        if self.whiten is not None:
            D = D @ self.whiten
        w = self._solver(D)
        return w[0] if single else w

    def synthesize(self, weights) -> np.ndarray:
        """The character's mesh for the given weights: T_B + Σ w_i (T_i − T_B) (Eq. 14).

        Parameters
        ----------
        weights : (M,) or (F, M) float

        Returns
        -------
        (V, 3) or (F, V, 3) float
        """
        w = np.asarray(weights, dtype=float)
        if w.ndim not in (1, 2) or w.shape[-1] != self.n_examples:
            raise ValueError(f"weights must have shape ({self.n_examples},) or (F, {self.n_examples}), "
                             f"got {w.shape}")
        if not np.isfinite(w).all():
            raise ValueError("weights hold NaN or inf")
        out = w @ self._d_flat
        out += self._t_flat
        return out.reshape(w.shape[:-1] + (self.n_vertices, 3))

    # ----------------------------------------------------------------------------------------- views
    @property
    def feature_matrix(self) -> np.ndarray:
        """(N̄, P·D) F of Eq. 6."""
        return self._solver.F

    @property
    def example_params(self) -> np.ndarray:
        """(M, N̄) parameter vectors p_i = F v_i (Eq. 7)."""
        return self._solver.example_params

    @property
    def source_examples(self) -> np.ndarray:
        """(M, P, D) the performer's key expressions."""
        return self._source_examples

    @property
    def target_examples(self) -> np.ndarray:
        """(M, V, 3) the character's key-models."""
        return self.target_base[None] + self.target_deltas

    def __repr__(self) -> str:
        return (f"ExpressionMapper(method={self.method!r}, n_examples={self.n_examples}, "
                f"n_points={self.n_points}, dim={self.dim}, n_vertices={self.n_vertices})")

    # ----------------------------------------------------------------------------------------- storage
    def to_arrays(self) -> dict[str, np.ndarray]:
        """Everything that defines the mapper, as plain arrays (no objects; loads without pickle).

        Returns
        -------
        dict of str -> ndarray
            Keys ``format``, ``version``, ``method``, ``solver``, ``source_base``, ``source_examples``,
            ``target_base``, ``target_deltas``, ``names`` ((0,) when unnamed), ``option_*``, ``solver_*`` and
            ``point_scale`` and ``whiten`` (the nuisance transform) when they were set.
        """
        out = {
            "format": np.array(FORMAT), "version": np.array(FORMAT_VERSION), "method": np.array(self.method),
            "solver": np.array(self._solver.kind), "source_base": self.source_base,
            "source_examples": self._source_examples, "target_base": self.target_base,
            "target_deltas": self.target_deltas,
            "names": np.array(self.names if self.names else [], dtype=str),
        }
        if self.point_scale is not None:
            out["point_scale"] = self.point_scale
        if self.whiten is not None:
            out["whiten"] = self.whiten
        for key, value in self.options.items():
            out[f"option_{key}"] = np.asarray(value)
        for key, value in self._solver.to_arrays().items():
            out[_SOLVER_PREFIX + key] = np.asarray(value)
        return out

    @classmethod
    def from_arrays(cls, arrays) -> ExpressionMapper:
        """Rebuild a mapper from :meth:`to_arrays` output (or an open ``np.load`` of a saved file).

        Raises
        ------
        FacepuppetError
            Missing keys, another kind of data, a newer format version, or inconsistent shapes.
        """
        keys = set(arrays.keys()) if hasattr(arrays, "keys") else set()
        missing = [k for k in _REQUIRED if k not in keys]
        if missing:
            raise FacepuppetError(f"not an ExpressionMapper (missing {', '.join(missing)})")
        if str(arrays["format"]) != FORMAT:
            raise FacepuppetError(f"not an ExpressionMapper (format is {str(arrays['format'])!r})")
        version = int(arrays["version"])
        if version > FORMAT_VERSION:
            raise FacepuppetError(f"written by a newer facepuppet (mapper format version {version}; this one "
                                  f"reads up to {FORMAT_VERSION})")
        kind = str(arrays["solver"])
        if kind not in SOLVERS:
            raise FacepuppetError(f"unknown solver kind {kind!r}")
        try:
            solver = SOLVERS[kind].from_arrays(
                {k[len(_SOLVER_PREFIX):]: np.asarray(arrays[k]) for k in keys if k.startswith(_SOLVER_PREFIX)})
            options = {k[len("option_"):]: _plain(arrays[k]) for k in keys if k.startswith("option_")}
            names = tuple(str(n) for n in arrays["names"]) or None
            sb, se = np.asarray(arrays["source_base"], float), np.asarray(arrays["source_examples"], float)
            tb, td = np.asarray(arrays["target_base"], float), np.asarray(arrays["target_deltas"], float)
            scale = np.asarray(arrays["point_scale"], float) if "point_scale" in keys else None
            whiten = np.asarray(arrays["whiten"], float) if "whiten" in keys else None
            ok = (sb.ndim == 2 and se.shape[1:] == sb.shape and td.shape[1:] == tb.shape
                  and (scale is None or (scale.shape == sb.shape and (scale > 0).all()))
                  and (whiten is None or (whiten.shape == (sb.size, sb.size) and np.isfinite(whiten).all()))
                  and len(se) == len(td) and (names is None or len(names) == len(se))
                  and solver.F.shape[1] == sb.size)
        except (KeyError, ValueError, TypeError, IndexError) as e:
            raise FacepuppetError(f"damaged ExpressionMapper data ({e})") from e
        if not ok:
            raise FacepuppetError("damaged ExpressionMapper data (inconsistent shapes)")
        return cls(method=str(arrays["method"]), solver=solver, source_base=sb, source_examples=se,
                   target_base=tb, target_deltas=td, names=names, options=options, point_scale=scale,
                   whiten=whiten)

    def save(self, path: str | os.PathLike) -> None:
        """Write the mapper to a versioned ``.npz`` file, atomically (no half-written file on failure)."""
        with atomic_path(path) as tmp, open(tmp, "wb") as f:
            np.savez(f, **self.to_arrays())

    @classmethod
    def load(cls, path: str | os.PathLike) -> ExpressionMapper:
        """Read a mapper written by :meth:`save`.

        Raises
        ------
        FacepuppetError
            Missing, corrupt, truncated, wrong-kind or future-version file; the message names the file.
        """
        from facepuppet._util.npz import read_npz

        arrays = read_npz(path, "mapper file", known=_REQUIRED + ("names", "point_scale", "whiten"),
                          prefixes=("option_", _SOLVER_PREFIX))
        if not arrays:
            raise FacepuppetError(f"{path}: not a mapper file (not an ExpressionMapper: no member it knows)")
        try:
            return cls.from_arrays(arrays)
        except FacepuppetError as e:
            raise FacepuppetError(f"{path}: {e}") from e


def _displacements(points: np.ndarray, base: np.ndarray, scale: np.ndarray | None,
                   whiten: np.ndarray | None = None) -> np.ndarray:
    """(K, P·D) displacement vectors of ``points`` (K, P, D) from ``base`` as the solver sees them (Eq. 5):
    divided by the point scale, then multiplied by the nuisance transform (each only when given)."""
    V = (points - base[None]).reshape(len(points), -1)
    if scale is not None:
        V = V / scale.reshape(-1)
    if whiten is not None:
        V = V @ whiten
    return V


def _plain(a: np.ndarray):
    a = np.asarray(a)
    if a.ndim == 0:
        return a.item()
    return tuple(a.tolist())


