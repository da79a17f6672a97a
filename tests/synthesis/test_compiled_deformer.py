"""The compiled per-frame pass of WireDeformer equals the numpy passes (the reference) on random wires."""

from __future__ import annotations

import numpy as np
import pytest

from facepuppet.synthesis import WireDeformer


def wires_scene(rng, n=400, k=3):
    pts = rng.uniform(-1, 1, size=(n, 3))
    refs = [np.c_[np.linspace(-1, 1, 6), np.full(6, y), rng.normal(scale=0.1, size=6)] for y in (-0.4, 0.1, 0.5)][:k]
    wires = [r + rng.normal(scale=0.1, size=r.shape) for r in refs]
    return pts, refs, wires


@pytest.mark.parametrize("exponent", [0.0, 1.0, 2.0, 1.5])
def test_compiled_equals_numpy(rng, exponent):
    pts, refs, wires = wires_scene(rng)
    kw = dict(exponent=exponent)
    fast = WireDeformer(pts, refs, [0.5, 0.6, 0.4], **kw)
    ref = WireDeformer(pts, refs, [0.5, 0.6, 0.4], compiled=False, **kw)
    assert fast.compiled and not ref.compiled
    for scales, radii in [(None, None), ([1.2, 0.8, 1.0], None), (1.1, [0.3, 0.6, 0.2])]:
        got = fast.deform(wires, scales, radii=radii)
        want = ref.deform(wires, scales, radii=radii)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-13)
    assert np.abs(got - pts).max() > 0.01            # the wires do move the points


def test_compiled_identity_and_translation(rng):
    """W = R moves nothing; W = R + d moves points on R by d (the deformer's known answers, compiled)."""
    pts, refs, _ = wires_scene(rng, k=1)
    d = WireDeformer(np.vstack([pts, refs[0]]), refs, 0.5)
    np.testing.assert_array_equal(d.deform(refs), d.points)
    moved = d.deform([refs[0] + [0.0, 0.0, 0.3]])
    np.testing.assert_allclose(moved[-6:] - refs[0], [[0.0, 0.0, 0.3]] * 6, atol=1e-12)
