"""The mapping methods: each turns a displacement vector of the feature points into blend weights.

Every method is a small class with ``fit(V, options)``, ``__call__(D)``, ``to_arrays()`` and ``from_arrays()``;
:data:`METHODS` maps the public names to a class and the option values that define it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from facepuppet.errors import FacepuppetError
from facepuppet.mapping._boxqp import solve_box_qp
from facepuppet.mapping._cardinal import (
    center_labels,
    cubic_bspline,
    nearest_separation,
    pairwise_distances,
    radial_matrix,
)
from facepuppet.mapping._params import check_examples, feature_matrix
from facepuppet.mapping._regional import RegionalSolver

__all__ = ["METHODS", "DEFAULT_METHOD", "Method", "BoundedSolver", "PaperSolver"]

_B0 = 2.0 / 3.0  # cubic_bspline(0)


class BoundedSolver:
    """Bounded least squares in a shrinkage-whitened parameter space, with a ridge that grows off the span.

    At fit time (V: (M, N) source displacement vectors, Eq. 5):

    1. Parameter space: ``F`` holds all M right singular vectors of V (the uncentred PCA of Eqs. 6–7, every
       axis kept: the examples were checked to be well separated), ``p_i = F v_i``, singular values ``s``.
    2. Metric: the unexplained part of a real frame is modelled as noise whose covariance is the examples'
       own covariance shrunk towards a multiple of the identity (``shrinkage`` γ = 0.7):
       ``Σ = (1 − γ) diag(s²) + γ mean(s²) I``; coordinates are scaled by ``q = Σ^(-1/2)``. γ = 1 is plain
       Euclidean least squares on the points; γ = 0 is full whitening (Mahalanobis), which trusts weakly
       moving examples as much as strong ones and amplifies noise.

    Per frame, with displacement vector d (Eq. 13: p = F d), ``H = (P q)(P q)ᵀ``:

    3. ``w = argmin ‖q ⊙ (p − Pᵀ w)‖² + λ(d) Σ_i H_ii w_i² + μ(d) Σ_i w_i²`` subject to ``lo ≤ w ≤ hi``.
       The ridge λ is
       relative to each example's own strength (scale-free) and grows with how far the frame lies outside
       the examples' span: ``λ(d) = ridge + angle_ridge · sin θ``, θ the angle between d and the span
       (``sin θ = ‖d − Fᵀ F d‖ / ‖d‖``). A frame the examples explain (every blend of them, each example,
       the neutral face) is solved without shrinkage, hence reproduced exactly; a frame carrying motion
       the examples cannot express (another expression, tracking noise) has its weights damped, which is
       where least squares would otherwise turn that motion into spurious weights (``angle_ridge`` = 0 is
       plain bounded least squares).
       The noise ridge μ (``noise_ridge`` c, method ``adaptive``) is the Gaussian prior of a Bayesian
       regression: weights with prior standard deviation τ = 1/√c under per-coordinate noise of variance σ²
       give ``μ = σ² / τ² = c σ̂²(d)``, with σ² estimated per frame from the part of d the examples cannot
       express, ``σ̂² = ‖d − Fᵀ F d‖² / (N − M)`` (N coordinates, M examples). Absolute rather than relative
       to H_ii, it shrinks most the examples that barely move the points, whose weights noise perturbs most;
       it vanishes on the examples' span, so the guarantees below still hold. The values of γ, the angle
       ridge and c of each method (:data:`METHODS`) are chosen with ``benchmarks/eval_mapping_variants.py``.
    4. Optional radial correction (``correct``, paper §5.3 in spirit), needed only with a constant
       ``ridge`` > 0, which moves the examples off their exact weights: a cubic B-spline bump centred on
       each example, of radius α_j = distance to the nearest other example or to the neutral face, adds back
       the residual ``e_j − w(p_j)``. The bumps vanish at every other example and at the neutral face; the
       result is clipped to the bounds (which keeps both).

    Guarantees (bounds holding 0 and 1): w(neutral) = 0 and w(example i) = e_i exactly; every blend of the
    examples with weights inside the bounds is reproduced exactly when ``ridge`` = 0; w is continuous in d.
    """

    kind = "bounded"

    def __init__(self, F: np.ndarray, q: np.ndarray, P: np.ndarray, bounds: np.ndarray, ridge: float,
                 angle_ridge: float, alpha: np.ndarray, C: np.ndarray, noise_ridge: float = 0.0) -> None:
        self.F, self.q, self.P = F, q, P
        self.noise_ridge = float(noise_ridge)
        self.lo = np.full(len(P), float(bounds[0]))
        self.hi = np.full(len(P), float(bounds[1]))
        self.ridge, self.angle_ridge = float(ridge), float(angle_ridge)
        self.alpha, self.C = alpha, C
        Pw = P * q
        self.H0 = Pw @ Pw.T
        self.Hd = np.diag(np.diag(self.H0))
        self.H = self.H0 + self.ridge * self.Hd
        try:
            self.H_inv = np.linalg.inv(self.H)
        except np.linalg.LinAlgError as e:  # pragma: no cover - the examples were checked before
            raise FacepuppetError("source_examples: the least-squares system is singular") from e
        # One product gives both the right-hand side b = (F d ⊙ q) Pwᵀ and the parameter vector p = F d.
        self.G = np.concatenate([F.T @ (q[:, None] * Pw.T), F.T], axis=1)
        self.correct = bool(np.any(C))

    @classmethod
    def fit(cls, V: np.ndarray, opts: dict, names: tuple[str, ...] | None) -> BoundedSolver:
        check_examples(V, names, opts["threshold"])
        M = len(V)
        _, s, vt = np.linalg.svd(V, full_matrices=False)
        F = vt[:M]
        P = V @ F.T
        g = float(opts["shrinkage"])
        q = 1.0 / np.sqrt((1.0 - g) * s**2 + g * np.mean(s**2))
        q /= q.max()
        bounds = np.asarray(opts["bounds"], dtype=float)
        args = (F, q, P, bounds, opts["ridge"], opts["angle_ridge"])
        noise_ridge = float(opts.get("noise_ridge", 0.0))
        solver = cls(*args, np.ones(M), np.zeros((M, M)), noise_ridge)
        if opts["correct"]:
            centres = np.vstack([np.zeros((1, P.shape[1])), P])
            alpha = nearest_separation(centres, center_labels(M, names))[1:]
            residual = np.eye(M) - solver._linear(V)[0]
            solver = cls(*args, alpha, residual, noise_ridge)
        return solver

    def _linear(self, D: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Steps 3 for every row of D: (weights, parameter vectors)."""
        M = len(self.P)
        Z = D @ self.G
        b, p = Z[:, :M], Z[:, M:]
        if self.angle_ridge == 0.0 and self.noise_ridge == 0.0:
            return solve_box_qp(self.H, b, self.lo, self.hi, self.H_inv), p
        outside = D - p @ self.F
        out2 = np.einsum("fn,fn->f", outside, outside)
        norm2 = np.einsum("fn,fn->f", D, D)
        sin = np.sqrt(out2 / np.where(norm2 > 0.0, norm2, 1.0))
        H = self.H[None] + (self.angle_ridge * np.minimum(sin, 1.0))[:, None, None] * self.Hd[None]
        if self.noise_ridge:
            sigma2 = out2 / max(D.shape[1] - M, 1)
            H = H + (self.noise_ridge * sigma2)[:, None, None] * np.eye(M)[None]
        return solve_box_qp(H, b, self.lo, self.hi), p

    def __call__(self, D: np.ndarray) -> np.ndarray:
        """(F, N) displacement vectors -> (F, M) weights."""
        w, p = self._linear(D)
        if self.correct:
            phi = cubic_bspline(2.0 * pairwise_distances(p, self.P) / self.alpha[None, :]) / _B0
            w = np.clip(w + phi @ self.C, self.lo, self.hi)
        return w

    @property
    def example_params(self) -> np.ndarray:
        return self.P

    def to_arrays(self) -> dict[str, np.ndarray]:
        return {"F": self.F, "q": self.q, "P": self.P, "bounds": np.array([self.lo[0], self.hi[0]]),
                "ridge": np.array(self.ridge), "angle_ridge": np.array(self.angle_ridge), "alpha": self.alpha,
                "C": self.C, "noise_ridge": np.array(self.noise_ridge)}

    @classmethod
    def from_arrays(cls, a: dict[str, np.ndarray]) -> BoundedSolver:
        # A file without ``noise_ridge`` holds a method without the noise ridge (μ = 0).
        return cls(a["F"], a["q"], a["P"], a["bounds"], float(a["ridge"]), float(a["angle_ridge"]), a["alpha"],
                   a["C"], float(a.get("noise_ridge", 0.0)))


class PaperSolver:
    """The paper's cardinal basis functions (§4.1–5.4), exactly, with the neutral face as one more data point.

    1. ``F``: eigenvectors of the covariance of the v_i (centred, as the paper's "component covariance
       matrix"), those with eigenvalue ≥ ``threshold`` × the largest kept (Eqs. 5–6, threshold relative,
       see :mod:`facepuppet.mapping._params`); p_i = F v_i (Eq. 7).
    2. Data points: the M examples (weights e_i) and the neutral face p_0 = 0 (weights all zero). The paper
       lists only the examples, but it also requires T_B for the neutral expression (Eq. 14); fitting it as
       a data point is what makes neutral → neutral exact.
    3. Linear bases A_0 = 1, A_l(p) = p^l, coefficients by least squares (Eq. 9; minimum norm if under-
       determined); residuals w′ (Eq. 10).
    4. Radial bases R_j(p) = B(‖p − p_j‖ / α_j), B the cubic B-spline, α_j the distance from p_j to the nearest
       other data point (Eq. 11); coefficients r from the square system of Eq. 12.
    5. Runtime: p = F d (Eq. 13), w_i(p) by Eq. 8, unbounded.
    """

    kind = "paper"

    def __init__(self, F: np.ndarray, a: np.ndarray, X: np.ndarray, alpha: np.ndarray, r: np.ndarray) -> None:
        self.F, self.a, self.X, self.alpha, self.r = F, a, X, alpha, r

    @classmethod
    def fit(cls, V: np.ndarray, opts: dict, names: tuple[str, ...] | None) -> PaperSolver:
        check_examples(V, names, opts["threshold"])
        M = len(V)
        F, _ = feature_matrix(V, opts["threshold"], centred=True)
        if len(F) == 0:
            raise FacepuppetError("source_examples: the paper's method needs at least two examples that differ "
                                  "(its PCA is centred on their mean)")
        X = np.vstack([np.zeros((1, len(F))), V @ F.T])  # (M+1, N̄): neutral, then the examples
        target = np.vstack([np.zeros((1, M)), np.eye(M)])  # (M+1, M)
        A = np.hstack([np.ones((M + 1, 1)), X])
        a = np.linalg.lstsq(A, target, rcond=None)[0]  # Eq. 9
        residual = target - A @ a  # Eq. 10
        alpha = nearest_separation(X, center_labels(M, names))
        R = radial_matrix(X, X, alpha)  # R[k, j] = R_j(p_k), Eq. 11
        cond = np.linalg.cond(R)
        if not np.isfinite(cond) or cond > 1e12:
            raise FacepuppetError(f"source_examples: the radial system of the paper's method (Eq. 12) is singular "
                                  f"(condition number {cond:.3g}); some examples are too close together")
        r = np.linalg.solve(R, residual)  # Eq. 12
        return cls(F, a, X, alpha, r)

    def __call__(self, D: np.ndarray) -> np.ndarray:
        p = D @ self.F.T  # Eq. 13
        return self.a[0] + p @ self.a[1:] + radial_matrix(p, self.X, self.alpha) @ self.r  # Eq. 8

    @property
    def example_params(self) -> np.ndarray:
        return self.X[1:]

    def to_arrays(self) -> dict[str, np.ndarray]:
        return {"F": self.F, "a": self.a, "X": self.X, "alpha": self.alpha, "r": self.r}

    @classmethod
    def from_arrays(cls, a: dict[str, np.ndarray]) -> PaperSolver:
        return cls(a["F"], a["a"], a["X"], a["alpha"], a["r"])


@dataclass(frozen=True)
class Method:
    """A named mapping method: the solver class and the option values that define it."""

    solver: type
    defaults: dict = field(default_factory=dict)
    summary: str = ""


_INF = float("inf")

METHODS: dict[str, Method] = {
    "adaptive": Method(BoundedSolver, {"bounds": (0.0, 1.0), "ridge": 0.0, "angle_ridge": 0.2, "shrinkage": 0.7,
                                       "correct": None, "noise_ridge": 4.0},
                       "as bounded, plus a Bayesian ridge from the frame's noise variance estimated from the motion "
                       "the examples cannot express (the default)"),
    "bounded": Method(BoundedSolver, {"bounds": (0.0, 1.0), "ridge": 0.0, "angle_ridge": 0.3, "shrinkage": 0.7,
                                      "correct": None},
                      "bounded least squares in a shrinkage-whitened PCA space, ridge growing with the frame's "
                      "angle to the examples' span"),
    "ridge": Method(BoundedSolver, {"bounds": (0.0, 1.0), "ridge": 0.1, "angle_ridge": 0.0, "shrinkage": 0.7,
                                    "correct": None},
                    "bounded least squares with a constant ridge, radial correction back to exact examples"),
    "lsq": Method(BoundedSolver, {"bounds": (0.0, 1.0), "ridge": 0.0, "angle_ridge": 0.0, "shrinkage": 1.0,
                                 "correct": False},
                  "least squares of the feature displacements with weights in [0, 1]"),
    "linear": Method(BoundedSolver, {"bounds": (-_INF, _INF), "ridge": 0.0, "angle_ridge": 0.0, "shrinkage": 1.0,
                                 "correct": False},
                     "unbounded least squares of the feature displacements (projection on the examples)"),
    "regional": Method(RegionalSolver, {"bounds": (0.0, 1.0), "ridge": 0.0, "angle_ridge": 0.2, "shrinkage": 0.7,
                                        "correct": None, "noise_ridge": 4.0, "n_regions": 12, "leak": 0.2,
                                        "region_share": 1.0,
                                        "support_tol": 1e-3},
                       "adaptive per region: each region of the character (found from its key-models, or given) "
                       "gets its own weights from its own feature points (non-uniform blending)"),
    "paper": Method(PaperSolver, {}, "the paper's cardinal basis functions (Eqs. 5-13), unbounded"),
}
DEFAULT_METHOD = "adaptive"

SOLVERS = {cls.kind: cls for cls in (BoundedSolver, PaperSolver, RegionalSolver)}
