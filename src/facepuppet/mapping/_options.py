"""The options of :meth:`ExpressionMapper.fit` and their checks."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from facepuppet.mapping._methods import DEFAULT_METHOD, METHODS

__all__ = ["MapperOptions", "check_array", "resolve_options"]


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
    n_regions : int, optional
        ``regional``: most regions found from the key-models besides the background (12).
    leak : float in [0, 1], optional
        ``regional``: weight, in a region, of the feature points that belong to another region (0.2).
    region_share : float in [0, 1], optional
        ``regional``: share of a region's own weights in its final weights, the rest the global (background)
        weights: w_k = support_k ⊙ ((1 − share) w_0 + share w_k^own) (1: each region's own solve).
    support_tol : float, optional
        ``regional``: a key-model moves a region when its masked motion there exceeds this share of its
        largest motion (1e-3); elsewhere its weight is 0.
    regions : (R, V) float, optional
        ``regional``: the region masks (a partition of unity over the character's vertices, the background
        first), e.g. ``synthesis.region_masks`` of the character's wires. None: found from the key-models.
    region_names : tuple of R str, optional
        Names of the given ``regions`` (the first is the background).
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
    n_regions: int | None = None
    leak: float | None = None
    region_share: float | None = None
    support_tol: float | None = None
    regions: object = None
    region_names: tuple[str, ...] | None = None


def check_array(x, name: str, ndim: int, last: int | tuple[int, ...] | None = None) -> np.ndarray:
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


def resolve_options(opts: MapperOptions, m: int) -> dict:
    """The option values the method runs with, checked."""
    if opts.method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)}; got {opts.method!r}")
    spec = METHODS[opts.method]
    out = dict(spec.defaults)
    for key in ("bounds", "ridge", "angle_ridge", "noise_ridge", "shrinkage", "correct", "n_regions", "leak",
                "region_share",
                "support_tol"):
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
    if "n_regions" in out and not (isinstance(out["n_regions"], (int, np.integer)) and out["n_regions"] >= 0):
        raise ValueError(f"n_regions must be an integer >= 0, got {out['n_regions']!r}")
    for key in ("leak", "region_share"):
        if key in out and not (0.0 <= float(out[key]) <= 1.0):
            raise ValueError(f"{key} must lie in [0, 1], got {out[key]}")
    if "support_tol" in out and not (0.0 <= float(out["support_tol"]) < 1.0):
        raise ValueError(f"support_tol must lie in [0, 1), got {out['support_tol']}")
    if (opts.regions is not None or opts.region_names is not None) and "leak" not in out:
        raise ValueError(f"options 'regions' and 'region_names' apply to method 'regional', not {opts.method!r}")
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
