"""Known answers of the wire deformer: identity, translation, scale, rotation, the combination of two wires."""

from __future__ import annotations

import numpy as np
import pytest

from facepuppet.synthesis import WireDeformer, falloff, wire_deform


def straight(k=5, length=4.0):
    """A straight reference along +x from the origin, K points."""
    x = np.linspace(0.0, length, k)
    return np.stack([x, np.zeros(k), np.zeros(k)], axis=1)


def grid(xs, ys, zs):
    return np.stack(np.meshgrid(xs, ys, zs, indexing="ij"), axis=-1).reshape(-1, 3)


def f_ref(x):
    """The documented default falloff, written out."""
    return np.where(x < 1, (1 - x**2) ** 2, 0.0)


def test_falloff_values_and_c1():
    x = np.array([0.0, 0.5, 1.0, 1.5])
    np.testing.assert_allclose(falloff(x), [1.0, 0.5625, 0.0, 0.0])
    h = 1e-6
    assert abs((falloff(1.0) - falloff(1.0 - h)) / h) < 1e-5          # f'(1-) = 0: C1 at the boundary
    assert abs((falloff(h) - falloff(0.0)) / h) < 1e-5                # f'(0) = 0
    assert np.all(np.diff(falloff(np.linspace(0, 1, 50))) < 0)


def test_unmoved_wire_moves_nothing(rng):
    ref = np.cumsum(rng.normal(size=(6, 3)), axis=0)
    pts = rng.normal(size=(300, 3)) * 3
    np.testing.assert_allclose(wire_deform(pts, ref, ref, 2.0), pts, atol=1e-12)
    d = WireDeformer(pts, [ref, ref + [5, 0, 0]], [2.0, 1.0])
    np.testing.assert_allclose(d.deform([ref, ref + [5, 0, 0]]), pts, atol=1e-12)


def test_translation_moves_by_falloff_of_distance():
    ref = straight()
    d = np.array([0.1, -0.3, 0.7])
    r = 0.8
    pts = grid(np.linspace(0.5, 3.5, 7), np.linspace(-1.2, 1.2, 13), np.linspace(-0.6, 0.6, 5))
    out = wire_deform(pts, ref, ref + d, r)
    x = np.hypot(pts[:, 1], pts[:, 2]) / r
    np.testing.assert_allclose(out, pts + f_ref(x)[:, None] * d, atol=1e-12)
    on = x == 0
    assert on.any() and (x >= 1).any()
    np.testing.assert_allclose(out[on], pts[on] + d, atol=1e-12)     # points on R move by d
    np.testing.assert_array_equal(out[x >= 1], pts[x >= 1])         # points beyond r stay


def test_translation_of_curved_wire(rng):
    """A rigid translation keeps every tangent: each point moves by F d whatever the curve's shape."""
    ref = np.array([[0, 0, 0], [1, 0.5, 0], [2, 0.2, 0.4], [3, 1.0, 0.3]], float)
    d = np.array([0.0, 0.2, -0.1])
    pts = rng.uniform([-0.5, -1, -1], [3.5, 2, 1.5], size=(500, 3))
    r = 0.9
    dist = np.array([min(seg_distance(p, ref[j], ref[j + 1]) for j in range(3)) for p in pts])
    out = wire_deform(pts, ref, ref + d, r)
    np.testing.assert_allclose(out, pts + f_ref(dist / r)[:, None] * d, atol=1e-12)


def seg_distance(p, a, b):
    t = np.clip(np.dot(p - a, b - a) / np.dot(b - a, b - a), 0, 1)
    return np.linalg.norm(p - (a + t * (b - a)))


def test_scale_about_a_straight_wire():
    ref = straight()
    r, s = 1.0, 1.8
    pts = grid(np.linspace(0.5, 3.5, 4), np.linspace(-1.5, 1.5, 31), [0.0, 0.3])
    out = wire_deform(pts, ref, ref, r, scale=s)
    rho = np.hypot(pts[:, 1], pts[:, 2])
    gain = 1 + (s - 1) * f_ref(rho / r)
    want = pts.copy()
    want[:, 1:] *= gain[:, None]
    np.testing.assert_allclose(out, want, atol=1e-12)


@pytest.mark.parametrize("alpha", [0.3, -0.9, 2.0])
def test_rotation_of_a_straight_wire(alpha):
    """W = R turned by alpha about z through the origin: offsets turn by F alpha, R(u) moves F (W(u) - R(u))."""
    ref = straight()
    c, s = np.cos(alpha), np.sin(alpha)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    wire = ref @ rot.T
    r = 1.2
    pts = grid(np.linspace(0.25, 3.75, 8), np.linspace(-1.0, 1.0, 9), np.linspace(-0.5, 0.5, 3))
    out = wire_deform(pts, ref, wire, r)
    x, y, z = pts.T
    f = f_ref(np.hypot(y, z) / r)
    phi = f * alpha
    want = np.stack([x - y * np.sin(phi) + f * (x * c - x),
                     y * np.cos(phi) + f * x * s,
                     z], axis=1)
    np.testing.assert_allclose(out, want, atol=1e-12)
    near = f == 1
    np.testing.assert_allclose(out[near], pts[near] @ rot.T, atol=1e-12)   # on R: carried rigidly


@pytest.mark.parametrize("m", [0.0, 1.0, 2.0, 3.5])
def test_two_wires_combine_by_displacement_weights(m):
    ref1 = straight()
    ref2 = straight() + [0, 1, 0]
    d1, d2 = np.array([0, 0, 0.5]), np.array([0.2, 0, -0.1])
    r = 1.5
    pts = grid(np.linspace(0.5, 3.5, 5), np.linspace(-0.4, 1.4, 19), [0.0])
    dfm = WireDeformer(pts, [ref1, ref2], r, exponent=m)
    out = dfm.deform([ref1 + d1, ref2 + d2])
    y = pts[:, 1]
    f1, f2 = f_ref(np.abs(y) / r), f_ref(np.abs(1 - y) / r)
    a, b = f1[:, None] * d1, f2[:, None] * d2
    wa, wb = np.linalg.norm(a, axis=1) ** m, np.linalg.norm(b, axis=1) ** m
    # a wire that does not reach the point (F = 0) is left out of both sums
    wa, wb = np.where(f1 > 0, wa, 0), np.where(f2 > 0, wb, 0)
    want = pts + (a * wa[:, None] + b * wb[:, None]) / (wa + wb)[:, None]
    np.testing.assert_allclose(out, want, atol=1e-12)


def test_deformer_matches_single_wire_and_radius_override(rng):
    ref = np.cumsum(rng.normal(size=(7, 3)), axis=0)
    wire = ref + rng.normal(scale=0.3, size=ref.shape)
    pts = ref[rng.integers(0, 7, 800)] + rng.normal(scale=1.0, size=(800, 3))
    want = wire_deform(pts, ref, wire, 1.3, scale=0.7)
    np.testing.assert_allclose(WireDeformer(pts, [ref], 1.3).deform([wire], 0.7), want, atol=1e-12)
    big = WireDeformer(pts, [ref], 3.0)
    np.testing.assert_allclose(big.deform([wire], [0.7], radii=[1.3]), want, atol=1e-12)
    np.testing.assert_allclose(big.deform(wire[None], 0.7, radii=1.3), want, atol=1e-12)
    f = big.influence(1.3)[0]
    np.testing.assert_allclose(f[want[:, 0] == pts[:, 0]], 0)     # unmoved points: no influence ...
    assert (f > 0).sum() == (np.abs(want - pts).sum(axis=1) > 0).sum()    # ... and every reached one moves


def test_deformation_is_continuous_across_a_bend():
    """The tangent is interpolated along u, so points on both sides of a vertex's normal plane agree."""
    ref = np.array([[0, 0, 0], [1, 0, 0], [2, 1, 0]], float)
    wire = np.array([[0, 0, 0], [1, 0, 0.2], [1.5, 1.5, 0.6]], float)
    eps = 1e-7
    pts = np.array([[1 - eps, -0.3, 0.1], [1 + eps, -0.3, 0.1]])
    out = wire_deform(pts, ref, wire, 1.0, scale=1.3)
    assert np.linalg.norm(out[0] - out[1]) < 1e-5


@pytest.mark.parametrize("call, word", [
    (lambda: wire_deform(np.zeros((3, 2)), straight(), straight(), 1), "points"),
    (lambda: wire_deform([[0, 0, np.nan]], straight(), straight(), 1), "points"),
    (lambda: wire_deform(np.zeros((3, 3)), straight()[:1], straight()[:1], 1), "reference"),
    (lambda: wire_deform(np.zeros((3, 3)), straight(), straight(4), 1), "wire"),
    (lambda: wire_deform(np.zeros((3, 3)), straight(), straight(), 0), "radius"),
    (lambda: wire_deform(np.zeros((3, 3)), straight(), straight(), -1), "radius"),
    (lambda: wire_deform(np.zeros((3, 3)), straight(), straight(), "a"), "radius"),
    (lambda: wire_deform(np.zeros((3, 3)), straight(), straight(), 1, scale=np.inf), "scale"),
    (lambda: wire_deform(np.zeros((3, 3)), [[0, 0, 0], [0, 0, 0]], straight(2), 1), "reference"),
    (lambda: WireDeformer(np.zeros((3, 3)), [straight()], [1, 2]), "radii"),
    (lambda: WireDeformer(np.zeros((3, 3)), [straight()], 1, exponent=-1), "exponent"),
    (lambda: WireDeformer(np.zeros((3, 3)), [], 1), "references"),
    (lambda: WireDeformer(np.zeros((3, 3)), [straight()], 1).deform([straight(4)]), "wires[0]"),
    (lambda: WireDeformer(np.zeros((3, 3)), [straight()], 1).deform([straight()], radii=2), "radii[0]"),
    (lambda: WireDeformer(np.zeros((3, 3)), [straight()], 1).deform([straight()], [1, 2]), "scales"),
])
def test_bad_input_names_the_argument(call, word):
    with pytest.raises(ValueError, match=word.replace("[", r"\[").replace("]", r"\]")):
        call()


def test_float32_passes_match_float64(rng):
    refs = [np.cumsum(rng.normal(size=(6, 3)), axis=0) for _ in range(3)]
    wires = [r + rng.normal(scale=0.3, size=r.shape) for r in refs]
    pts = np.concatenate(refs)[rng.integers(0, 18, 2000)] + rng.normal(scale=1.0, size=(2000, 3))
    exact = WireDeformer(pts, refs, 1.5).deform(wires, [0.8, 1.0, 1.3])
    fast = WireDeformer(pts, refs, 1.5, dtype=np.float32)
    got = fast.deform(wires, [0.8, 1.0, 1.3])
    assert got.dtype == np.float64
    np.testing.assert_allclose(got, exact, atol=1e-5 * np.ptp(pts))
    np.testing.assert_allclose(fast.deform(wires, radii=1.0), WireDeformer(pts, refs, 1.0).deform(wires),
                               atol=1e-5 * np.ptp(pts))
    with pytest.raises(ValueError, match="dtype"):
        WireDeformer(pts, refs, 1.5, dtype=np.int32)
