"""Batched box-constrained quadratic programs on a few variables (the runtime solve of the mapping).

Every frame poses the same small problem with its own right-hand side:

    minimise ½ wᵀ H w − bᵀ w   subject to   lo ≤ w ≤ hi,

with a symmetric positive definite ``H`` (M × M, M ≈ 10–50), shared by all frames or one per frame.
A primal-dual active-set iteration (Hintermüller, Ito & Kunisch 2003) solves all frames at once: each
step fixes the variables it predicts to sit on a bound and solves the remaining free system exactly, for
the whole batch with one stacked ``np.linalg.solve``. It stops when no frame's active set changes, which
certifies the KKT conditions exactly. The rare frame that has not settled after a few steps is finished
by a primal active-set method (one constraint at a time, guaranteed finite), so the result is always the
exact minimiser.
"""

from __future__ import annotations

import numpy as np

__all__ = ["solve_box_qp"]

_PDAS_STEPS = 12


def solve_box_qp(H: np.ndarray, B: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                 H_inv: np.ndarray | None = None) -> np.ndarray:
    """Minimise ½ wᵀHw − bᵀw over the box [lo, hi] for every row b of ``B``.

    Parameters
    ----------
    H : (M, M) or (F, M, M) float
        Symmetric positive definite, shared or one per frame.
    B : (F, M) float
        One right-hand side per frame.
    lo, hi : (M,) float
        Bounds, ``lo <= hi`` (``-inf``/``inf`` allowed).
    H_inv : (M, M) float, optional
        ``inv(H)`` of a shared ``H``, when the caller has it precomputed.

    Returns
    -------
    (F, M) float
        The exact minimisers (to rounding).
    """
    batched = H.ndim == 3
    if batched:
        w = np.linalg.solve(H, B[:, :, None])[:, :, 0]  # unconstrained minimiser
    else:
        w = B @ (np.linalg.inv(H) if H_inv is None else H_inv)  # (H symmetric)
    below, above = w < lo, w > hi
    if not (below.any() or above.any()):
        return w
    if len(B) == 1:  # one live frame: index arithmetic beats masked batch algebra
        H1 = H[0] if batched else H
        w1 = _pdas_one(H1, B[0], lo, hi, below[0], above[0])
        return (w1 if w1 is not None else _primal_active_set(H1, B[0], lo, hi))[None]
    M = H.shape[-1]
    eye = np.eye(M, dtype=bool)
    # Scale of the dual/primal comparison in the active-set prediction (any c > 0 works; this one is unitless).
    c = np.diagonal(H, axis1=-2, axis2=-1)
    done = np.zeros(len(B), dtype=bool)
    for _ in range(_PDAS_STEPS):
        fixed = below | above
        w_fix = np.where(below, lo, np.where(above, hi, 0.0))
        free = ~fixed
        K = np.where(free[:, :, None] & free[:, None, :], H, eye)
        rhs = np.where(free, B - _times(w_fix, H), w_fix)
        w = np.linalg.solve(K, rhs[:, :, None])[:, :, 0]
        w = np.where(fixed, w_fix, w)
        lam = _times(w, H) - B  # gradient; zero on the free set
        lam = np.where(free, 0.0, lam)
        new_below = lam + c * (lo - w) > 0
        new_above = lam + c * (hi - w) < 0
        done = (new_below == below).all(1) & (new_above == above).all(1)
        below, above = new_below, new_above
        if done.all():
            return w
    for f in np.flatnonzero(~done):
        w[f] = _primal_active_set(H[f] if batched else H, B[f], lo, hi)
    return w


def _pdas_one(H: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray, below: np.ndarray,
              above: np.ndarray) -> np.ndarray | None:
    """The same iteration for a single frame; None if it has not settled."""
    c = np.diag(H)
    for _ in range(_PDAS_STEPS):
        w = np.where(below, lo, np.where(above, hi, 0.0))
        free = np.flatnonzero(~(below | above))
        if free.size:
            w[free] = np.linalg.solve(H[np.ix_(free, free)], b[free] - H[free] @ w)
        lam = H @ w - b
        lam[free] = 0.0
        new_below = lam + c * (lo - w) > 0
        new_above = lam + c * (hi - w) < 0
        if np.array_equal(new_below, below) and np.array_equal(new_above, above):
            return w
        below, above = new_below, new_above
    return None


def _times(w: np.ndarray, H: np.ndarray) -> np.ndarray:
    """Rows of w times H (shared or per frame; H symmetric)."""
    return w @ H if H.ndim == 2 else np.einsum("fi,fij->fj", w, H)


def _primal_active_set(H: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """One frame by a primal active-set method (feasible iterates, one constraint change per step)."""
    M = len(b)
    w = np.clip(np.zeros(M), lo, hi)
    at_lo = w <= lo
    at_hi = (w >= hi) & ~at_lo
    for _ in range(50 * M + 100):
        free = ~(at_lo | at_hi)
        # Solve for the free variables with the others held at their bounds.
        target = w.copy()
        if free.any():
            rhs = b[free] - H[np.ix_(free, ~free)] @ w[~free]
            target[free] = np.linalg.solve(H[np.ix_(free, free)], rhs)
        step = target - w
        if np.allclose(step, 0.0, atol=1e-15, rtol=0.0) or not free.any():
            g = H @ w - b
            wrong = (at_lo & (g < 0)) | (at_hi & (g > 0))
            if not wrong.any():
                return w
            i = int(np.argmax(np.where(wrong, np.abs(g), -np.inf)))
            at_lo[i] = at_hi[i] = False
            continue
        # Longest feasible move towards the free minimiser.
        with np.errstate(divide="ignore", invalid="ignore"):
            t_lo = np.where(free & (step < 0), (lo - w) / step, np.inf)
            t_hi = np.where(free & (step > 0), (hi - w) / step, np.inf)
        t_all = np.minimum(t_lo, t_hi)
        i = int(np.argmin(t_all))
        t = min(1.0, float(t_all[i]))
        w = w + t * step
        if t < 1.0:
            if t_lo[i] <= t_hi[i]:
                w[i], at_lo[i] = lo[i], True
            else:
                w[i], at_hi[i] = hi[i], True
    return np.clip(w, lo, hi)
