"""The regional mapping's per-frame solve, compiled: every region's box QP of every frame in one pass.

For frame f and region k, with the products z = d G_k (right-hand side b and parameters p) and the weighted
norm ||d_k||^2 computed before (one matrix product each for all regions), the kernel forms the region's
system only over the examples its solver kept (n_k <= M; the others have b = 0 and an identity block, so
their weight is 0 and they decouple):

    K = H_k + angle_ridge * min(sin, 1) * Hd_k + noise_ridge * sigma^2 * I,
    sin^2 = max(||d_k||^2 - ||p||^2, 0) / ||d_k||^2,   sigma^2 = max(||d_k||^2 - ||p||^2, 0) / dof_k

(the formulas of :class:`facepuppet.mapping._regional.RegionalSolver`), and minimises 1/2 w^T K w - b^T w over
the box by the primal-dual active-set iteration of :mod:`facepuppet.mapping._boxqp` (same prediction rule,
same step limit), each free system solved by a Cholesky factorisation. A problem that has not settled, or
whose system is not numerically positive definite, is reported in ``status`` and finished by the numpy
solver, so the result is always the exact minimiser.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from facepuppet._util.jit import INNER, KERNEL

__all__ = ["PDAS_STEPS", "solve_regions"]

#: Steps of the primal-dual active-set iteration before a problem is handed back (as in ``_boxqp``).
PDAS_STEPS = 12


@nb.njit(**INNER)
def _cholesky_solve(K, free, n_free, rhs, L, y, out):
    """Solve K[free, free] x = rhs (n_free values) into ``out``; False if the block is not positive definite."""
    for i in range(n_free):
        fi = free[i]
        for j in range(i + 1):
            s = K[fi, free[j]]
            for q in range(j):
                s -= L[i, q] * L[j, q]
            if i == j:
                if not s > 0.0:
                    return False
                L[i, i] = math.sqrt(s)
            else:
                L[i, j] = s / L[j, j]
    for i in range(n_free):
        s = rhs[i]
        for q in range(i):
            s -= L[i, q] * y[q]
        y[i] = s / L[i, i]
    for i in range(n_free - 1, -1, -1):
        s = y[i]
        for q in range(i + 1, n_free):
            s -= L[q, i] * out[q]
        out[i] = s / L[i, i]
    return True


@nb.njit(**INNER)
def _box_qp(K, b, lo, hi, n, w, below, above, free, rhs, L, y, x, lam):
    """Minimise 1/2 w^T K w - b^T w over lo <= w <= hi (n variables) into ``w``: 0 settled, 1 not, 2 not PD."""
    for i in range(n):
        free[i] = i
        rhs[i] = b[i]
    if not _cholesky_solve(K, free, n, rhs, L, y, w):
        return 2
    any_out = False
    for i in range(n):
        below[i] = w[i] < lo[i]
        above[i] = w[i] > hi[i]
        any_out = any_out or below[i] or above[i]
    if not any_out:
        return 0
    for _ in range(PDAS_STEPS):
        n_free = 0
        for i in range(n):
            if below[i]:
                w[i] = lo[i]
            elif above[i]:
                w[i] = hi[i]
            else:
                w[i] = 0.0
                free[n_free] = i
                n_free += 1
        for a in range(n_free):
            i = free[a]
            s = b[i]
            for j in range(n):
                if below[j] or above[j]:
                    s -= K[i, j] * w[j]
            rhs[a] = s
        if n_free and not _cholesky_solve(K, free, n_free, rhs, L, y, x):
            return 2
        for a in range(n_free):
            w[free[a]] = x[a]
        settled = True
        for i in range(n):
            if below[i] or above[i]:
                g = -b[i]
                for j in range(n):
                    g += K[i, j] * w[j]
                lam[i] = g
            else:
                lam[i] = 0.0
            c = K[i, i]
            nb_ = lam[i] + c * (lo[i] - w[i]) > 0
            na_ = lam[i] + c * (hi[i] - w[i]) < 0
            if nb_ != below[i] or na_ != above[i]:
                settled = False
            below[i], above[i] = nb_, na_
        if settled:
            return 0
    return 1


@nb.njit(**KERNEL)
def solve_regions(Z, norm2, H, Hd, kept, n_kept, lo, hi, angle_ridge, noise_ridge, dof, support, out,
                  status):
    """Weights of every frame and region into ``out`` (F, R, M); ``status`` (F, R) 0 where solved here.

    Parameters
    ----------
    Z : (F, R, 2M) float64
        d G_k per frame and region: b in the first M columns, p in the last M.
    norm2 : (F, R) float64
        ||d_k||^2, the frame's weighted (and whitened) squared norm in region k.
    H, Hd : (R, M, M) float64
        Each region's system and the diagonal the angle ridge scales.
    kept : (R, M) int64
        Each region's kept examples, the first ``n_kept[k]`` entries.
    n_kept : (R,) int64
    lo, hi : (M,) float64
    angle_ridge, noise_ridge : float
    dof : (R,) float64
        Each region's degrees of freedom of the residual, dof_k (``RegionalSolver``).
    support : (R, M) float64
        1 where key-model i may move region k, else 0 (the weight there is 0).
    out : (F, R, M) float64
    status : (F, R) int64
        0 solved; 1 not settled after :data:`PDAS_STEPS` steps; 2 a system not positive definite.
    """
    F, R, M2 = Z.shape
    M = M2 // 2
    K = np.empty((M, M))
    b = np.empty(M)
    lo_k, hi_k, w = np.empty(M), np.empty(M), np.empty(M)
    below, above = np.empty(M, dtype=np.bool_), np.empty(M, dtype=np.bool_)
    free = np.empty(M, dtype=np.int64)
    rhs, y, x, lam = np.empty(M), np.empty(M), np.empty(M), np.empty(M)
    L = np.empty((M, M))
    ridged = angle_ridge != 0.0 or noise_ridge != 0.0
    for f in range(F):
        for k in range(R):
            n = n_kept[k]
            for i in range(M):
                out[f, k, i] = 0.0
            pp = 0.0
            for i in range(M):
                pp += Z[f, k, M + i] * Z[f, k, M + i]
            a_coef = 0.0
            c_coef = 0.0
            if ridged:
                nn = norm2[f, k]
                out2 = max(nn - pp, 0.0)
                sin = math.sqrt(out2 / (nn if nn > 0.0 else 1.0))
                a_coef = angle_ridge * min(sin, 1.0)
                c_coef = noise_ridge * (out2 / dof[k])
            for a in range(n):
                ia = kept[k, a]
                b[a] = Z[f, k, ia]
                lo_k[a], hi_k[a] = lo[ia], hi[ia]
                for c in range(n):
                    ic = kept[k, c]
                    K[a, c] = H[k, ia, ic] + a_coef * Hd[k, ia, ic]
                if noise_ridge != 0.0:
                    K[a, a] += c_coef
            s = _box_qp(K, b, lo_k, hi_k, n, w, below, above, free, rhs, L, y, x, lam)
            status[f, k] = s
            if s == 0:
                for a in range(n):
                    ia = kept[k, a]
                    out[f, k, ia] = w[a] * support[k, ia]
