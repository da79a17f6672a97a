"""ExpressionMapper: the public face of the mapping stage (DESIGN.md, "Python")."""

from __future__ import annotations

import os

import numpy as np

from facepuppet._util.atomic import atomic_path
from facepuppet.errors import FacepuppetError
from facepuppet.mapping._blend import blend_regions, sparse_masks
from facepuppet.mapping._methods import METHODS, SOLVERS
from facepuppet.mapping._metric import nuisance_transform
from facepuppet.mapping._options import MapperOptions, check_array, resolve_options

__all__ = ["ExpressionMapper", "MapperOptions", "FORMAT", "FORMAT_VERSION"]

FORMAT = "facepuppet.ExpressionMapper"
FORMAT_VERSION = 1
_SOLVER_PREFIX = "solver_"
_REQUIRED = ("format", "version", "method", "solver", "source_base", "source_examples", "target_base",
             "target_deltas", "names")


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
        self._sparse_masks = self._deltas_c = None

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
        sb = check_array(source_base, "source_base", 2, (2, 3))
        se = check_array(source_examples, "source_examples", 3)
        tb = check_array(target_base, "target_base", 2, 3)
        te = check_array(target_examples, "target_examples", 3)
        if se.shape[1:] != sb.shape:
            raise ValueError(f"source_examples must have shape (M, {sb.shape[0]}, {sb.shape[1]}) like "
                             f"source_base, got {se.shape}")
        if te.shape[1:] != tb.shape:
            raise ValueError(f"target_examples must have shape (M, {tb.shape[0]}, 3) like target_base, "
                             f"got {te.shape}")
        if len(se) != len(te):
            raise ValueError(f"source_examples and target_examples must hold the same number of examples, "
                             f"got {len(se)} and {len(te)}")
        resolved = resolve_options(opts, len(se))
        names = tuple(str(n) for n in opts.names) if opts.names is not None else None
        scale = None
        if opts.point_scale is not None:
            scale = check_array(opts.point_scale, "point_scale", 2, sb.shape[1])
            if scale.shape != sb.shape or not (scale > 0).all():
                raise ValueError(f"point_scale must be positive with shape {sb.shape} like source_base, got "
                                 f"shape {scale.shape}" + ("" if scale.shape != sb.shape else " with values <= 0"))
        whiten = None
        if opts.nuisance is not None:
            nu = check_array(opts.nuisance, "nuisance", 3)
            if nu.shape[1:] != sb.shape:
                raise ValueError(f"nuisance must have shape (K, {sb.shape[0]}, {sb.shape[1]}) like source_base, "
                                 f"got {nu.shape}")
            whiten = nuisance_transform(_displacements(nu, sb, scale), float(opts.nuisance_floor))
        cls_ = METHODS[opts.method].solver
        if getattr(cls_, "needs_target", False):
            masks = None
            if opts.regions is not None:
                masks = check_array(opts.regions, "regions", 2)
                if masks.shape[1] != len(tb) or (masks < -1e-9).any() or not np.allclose(masks.sum(0), 1.0):
                    raise ValueError(f"regions must be (R, {len(tb)}) masks >= 0 summing to 1 at every vertex "
                                     f"(background first), got shape {masks.shape}")
            rnames = None if opts.region_names is None else tuple(str(n) for n in opts.region_names)
            if rnames is not None and (masks is None or len(rnames) != len(masks)):
                raise ValueError("region_names must hold one name per row of regions")
            solver = cls_.fit(_displacements(se, sb, scale), resolved, names, part=SOLVERS["bounded"],
                              whiten=whiten, source_deltas=se - sb[None], target_deltas=te - tb[None],
                              target_base=tb, masks=masks, region_names=rnames)
        else:
            solver = cls_.fit(_displacements(se, sb, scale, whiten), resolved, names)  # Eq. 5
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
            With a ``regional`` mapper: (R, M) or (F, R, M), the weights of each region (``region_names``).
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
        if self.whiten is not None and not self.regional:
            D = D @ self.whiten
        w = self._solver(D)
        return w[0] if single else w

    def synthesize(self, weights, *, wires=None) -> np.ndarray:
        """The character's mesh for the given weights: T_B + Σ w_i (T_i − T_B) (Eq. 14).

        Regional weights (R, M) or (F, R, M) (a ``regional`` mapper's) blend region by region:
        T_B + Σ_k Σ_i M_k ⊙ w_ik (T_i − T_B), ``region_masks`` M_k.

        Parameters
        ----------
        weights : (M,) or (F, M) float, or (R, M) / (F, R, M) with a regional mapper
        wires : synthesis.CharacterWires, optional
            The paper's wire-based synthesis instead of Eq. 14: the key-models' wire curves and (r, s) are
            blended with the weights and the neutral mesh is deformed by them (``wires.synthesize``);
            global weights (M,) or (F, M) only.

        Returns
        -------
        (V, 3) or (F, V, 3) float
        """
        w = np.asarray(weights, dtype=float)
        if wires is not None:
            if w.ndim not in (1, 2) or w.shape[-1] != self.n_examples:
                raise ValueError(f"weights must have shape ({self.n_examples},) or (F, {self.n_examples}) for the "
                                 f"wire-based synthesis, got {w.shape}")
            return wires.synthesize(w)
        if self.regional and w.ndim >= 2 and w.shape[-2:] == (len(self.region_names), self.n_examples):
            if not np.isfinite(w).all():
                raise ValueError("weights hold NaN or inf")
            if self._sparse_masks is None:
                self._sparse_masks = sparse_masks(self.region_masks)
                self._deltas_c = np.ascontiguousarray(self.target_deltas, dtype=np.float64)
            out = blend_regions(self.target_base, self._deltas_c, self._sparse_masks, w.reshape(-1, *w.shape[-2:]))
            return out.reshape(w.shape[:-2] + out.shape[1:])
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
    def regional(self) -> bool:
        """True when :meth:`weights` gives one row of weights per region."""
        return getattr(self._solver, "kind", "") == "regional"

    @property
    def region_names(self) -> tuple[str, ...]:
        """Names of the regions (the background first); ``("all",)`` for a global mapper."""
        return self._solver.region_names if self.regional else ("all",)

    @property
    def region_masks(self) -> np.ndarray:
        """(R, V) masks M_k, a partition of unity over the vertices; (1, V) ones for a global mapper."""
        return self._solver.masks if self.regional else np.ones((1, self.n_vertices))

    @property
    def region_support(self) -> np.ndarray:
        """(R, M) bool: which key-models may move which region (the others take weight 0 there)."""
        return self._solver.support if self.regional else np.ones((1, self.n_examples), dtype=bool)

    def split_targets(self) -> np.ndarray:
        """(R·M, V, 3) morph targets M_k ⊙ (T_i − T_B), region-major: with the weights ``w.reshape(F, -1)``
        of :meth:`weights` (F, R, M), T_B + Σ weight · target equals :meth:`synthesize`."""
        m = self.region_masks
        return (m[:, None, :, None] * self.target_deltas[None]).reshape(-1, self.n_vertices, 3)

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


