"""Many small symmetric positive definite systems at once, compiled (Cholesky per system).

``np.linalg.solve`` on a stack of 10-50 x 10-50 systems spends most of its time per call on the stack's
bookkeeping; this loop factors each H = L L^T and solves L L^T x = b in place.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from facepuppet._util.jit import KERNEL

__all__ = ["solve_spd"]


@nb.njit(**KERNEL)
def _solve_spd(H, B, X):
    n, m = B.shape
    L = np.empty((m, m))
    for f in range(n):
        ok = True
        for j in range(m):
            s = H[f, j, j]
            for k in range(j):
                s -= L[j, k] * L[j, k]
            if s <= 0.0:
                ok = False
                break
            d = math.sqrt(s)
            L[j, j] = d
            for i in range(j + 1, m):
                s = H[f, i, j]
                for k in range(j):
                    s -= L[i, k] * L[j, k]
                L[i, j] = s / d
        if not ok:
            X[f, 0] = np.nan
            continue
        for i in range(m):
            s = B[f, i]
            for k in range(i):
                s -= L[i, k] * X[f, k]
            X[f, i] = s / L[i, i]
        for i in range(m - 1, -1, -1):
            s = X[f, i]
            for k in range(i + 1, m):
                s -= L[k, i] * X[f, k]
            X[f, i] = s / L[i, i]


def solve_spd(H: np.ndarray, B: np.ndarray) -> np.ndarray:
    """x_f = H_f^{-1} b_f for (F, M, M) symmetric positive definite H and (F, M) B; LAPACK for any H_f that
    is not positive definite to rounding (the same answer, by LU)."""
    Hc = np.ascontiguousarray(H, dtype=np.float64)
    Bc = np.ascontiguousarray(B, dtype=np.float64)
    X = np.empty_like(Bc)
    _solve_spd(Hc, Bc, X)
    bad = np.flatnonzero(np.isnan(X[:, 0])) if len(X) and X.shape[1] else np.zeros(0, dtype=int)
    if len(bad):
        X[bad] = np.linalg.solve(Hc[bad], Bc[bad][:, :, None])[:, :, 0]
    return X
