"""The batched box-constrained QP solver against scipy's bounded least squares (exact minimisers)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import lsq_linear

from facepuppet.mapping._boxqp import _primal_active_set, solve_box_qp


def _objective(H, b, w):
    return 0.5 * w @ H @ w - b @ w


@pytest.mark.parametrize("frames", [1, 12])
@pytest.mark.parametrize("shared", [True, False])
def test_matches_bvls(shared, frames, rng):
    for _ in range(30):
        m = int(rng.integers(2, 16))
        A = [rng.normal(size=(m + 4, m)) * rng.uniform(0.05, 20, size=m) for _ in range(1 if shared else frames)]
        y = rng.normal(scale=rng.uniform(0.1, 10), size=(frames, m + 4))
        H = A[0].T @ A[0] if shared else np.stack([a.T @ a for a in A])
        B = np.stack([y[f] @ A[0 if shared else f] for f in range(frames)])
        lo, hi = np.zeros(m), np.full(m, rng.uniform(0.5, 1.5))
        w = solve_box_qp(H, B, lo, hi)
        assert np.all(w >= lo) and np.all(w <= hi)
        for f in range(frames):
            a = A[0 if shared else f]
            ref = lsq_linear(a, y[f], bounds=(lo, hi), method="bvls", tol=1e-14).x
            Hf = H if shared else H[f]
            scale = 0.5 * y[f] @ y[f]
            assert _objective(Hf, B[f], w[f]) <= _objective(Hf, B[f], ref) + 1e-12 * scale


def test_primal_fallback_matches(rng):
    for _ in range(30):
        m = int(rng.integers(2, 12))
        a = rng.normal(size=(m + 2, m))
        y = rng.normal(size=m + 2)
        lo, hi = np.full(m, -0.3), np.full(m, 0.4)
        w = _primal_active_set(a.T @ a, y @ a, lo, hi)
        ref = lsq_linear(a, y, bounds=(lo, hi), method="bvls", tol=1e-14).x
        np.testing.assert_allclose(w, ref, atol=1e-8)


def test_unconstrained_when_inside(rng):
    a = rng.normal(size=(8, 4))
    H = a.T @ a
    w_true = np.array([[0.2, 0.5, 0.1, 0.9]])
    np.testing.assert_allclose(solve_box_qp(H, w_true @ H, np.zeros(4), np.ones(4)), w_true, atol=1e-12)
