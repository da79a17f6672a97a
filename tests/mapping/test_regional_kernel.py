"""The regional mapping's compiled per-frame solve against its numpy reference and the box-QP solver."""

from __future__ import annotations

import numpy as np
import pytest
from test_regional import masks_for, two_patches

from facepuppet import ExpressionMapper
from facepuppet.mapping import _regional
from facepuppet.mapping._boxqp import solve_box_qp
from facepuppet.mapping._regional_kernel import solve_regions


def frames(sb, se, rng, n=80):
    """Blends with weights in [-0.5, 1.5] (bounds active) plus noise off the examples' span."""
    w = rng.uniform(-0.5, 1.5, size=(n, len(se)))
    return sb + np.einsum("fm,mpd->fpd", w, se - sb[None]) + rng.normal(scale=0.05, size=(n,) + sb.shape)


@pytest.mark.parametrize("leak", [0.0, 0.2])
@pytest.mark.parametrize("nuisance", [False, True])
def test_compiled_weights_equal_the_numpy_reference(rng, leak, nuisance):
    sb, se, tb, te, inA, *_ = two_patches(rng)
    opts = {"regions": masks_for(inA), "leak": leak}
    if nuisance:
        opts["nuisance"] = sb + rng.normal(scale=0.05, size=(6,) + sb.shape)
    m = ExpressionMapper.fit(sb, se, tb, te, method="regional", **opts)
    x = frames(sb, se, rng)
    got = m.weights(x)
    solver = _regional.RegionalSolver.from_arrays(
        {k[len("solver_"):]: v for k, v in m.to_arrays().items() if k.startswith("solver_")})
    want = solver.reference((x - sb).reshape(len(x), -1))
    assert ((want == 0) | (want == 1)).any() and ((want > 0) & (want < 1)).any()
    np.testing.assert_allclose(got, want, atol=1e-12)
    np.testing.assert_allclose(np.stack([m.weights(f) for f in x[:5]]), want[:5], atol=1e-12)
    if leak == 0.0:
        kept = solver.to_arrays()["H"] != np.eye(len(se))[None]
        assert not kept.any(axis=2).all()          # some region's solver left an example out: n_k < M


def random_problems(rng, r=5, m=7):
    a = rng.normal(size=(r, m, m))
    H = a @ a.transpose(0, 2, 1) + 0.1 * np.eye(m)
    return H, rng.normal(scale=2.0, size=(r, m))


def test_kernel_solves_box_qps_exactly(rng):
    r, m = 5, 7
    H, b = random_problems(rng, r, m)
    Z = np.concatenate([b, np.zeros((r, m))], axis=1)[None]
    lo, hi = np.zeros(m), np.ones(m)
    out, status = np.empty((1, r, m)), np.empty((1, r), dtype=np.int64)
    kept = np.tile(np.arange(m), (r, 1))
    solve_regions(Z, np.zeros((1, r)), H, np.zeros_like(H), kept, np.full(r, m), lo, hi, 0.0, 0.0, np.full(r, 20.0),
                  np.ones((r, m)), out, status)
    assert (status == 0).all()
    np.testing.assert_allclose(out[0], solve_box_qp(H, b, lo, hi), atol=1e-12)
    H[2] -= 50 * np.eye(m)                                                   # not positive definite
    solve_regions(Z, np.zeros((1, r)), H, np.zeros_like(H), kept, np.full(r, m), lo, hi, 0.0, 0.0, np.full(r, 20.0),
                  np.ones((r, m)), out, status)
    assert status[0, 2] == 2 and (np.delete(status[0], 2) == 0).all()


def test_problems_the_kernel_hands_back_are_finished_by_numpy(rng, monkeypatch):
    sb, se, tb, te, inA, *_ = two_patches(rng)
    m = ExpressionMapper.fit(sb, se, tb, te, method="regional", regions=masks_for(inA))
    x = frames(sb, se, rng, n=10)
    want = m.weights(x)

    def unsettled(*args):
        solve_regions(*args)
        args[-2][3:6] = -1.0                       # garbage the wrapper must not keep
        args[-1][3:6] = 1

    monkeypatch.setattr(_regional, "solve_regions", unsettled)
    np.testing.assert_allclose(m.weights(x), want, atol=1e-12)


def test_region_share_blends_towards_the_global_weights_and_keeps_the_guarantees(rng):
    sb, se, tb, te, inA, *_ = two_patches(rng)
    own = ExpressionMapper.fit(sb, se, tb, te, method="regional", regions=masks_for(inA))
    half = ExpressionMapper.fit(sb, se, tb, te, method="regional", regions=masks_for(inA), region_share=0.5)
    x = frames(sb, se, rng, n=20)
    w, w1 = half.weights(x), own.weights(x)
    sup = own.region_support
    np.testing.assert_allclose(w[:, 0], w1[:, 0], atol=1e-12)
    np.testing.assert_allclose(w[:, 1:], (0.5 * w1[:, :1] + 0.5 * w1[:, 1:]) * sup[1:], atol=1e-12)
    np.testing.assert_allclose(half.synthesize(half.weights(sb)), tb, atol=1e-12)
    for i in range(len(se)):
        np.testing.assert_allclose(half.synthesize(half.weights(se[i])), te[i], atol=1e-9)
    with pytest.raises(ValueError, match="region_share must lie in"):
        ExpressionMapper.fit(sb, se, tb, te, method="regional", region_share=1.5)
