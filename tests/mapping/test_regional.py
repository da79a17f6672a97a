"""The regional mapping (method "regional"): known answers on a two-patch character, guarantees, storage."""

from __future__ import annotations

import numpy as np
import pytest

from facepuppet import ExpressionMapper
from facepuppet.mapping import METHODS


def two_patches(rng):
    """A character of two far-apart patches A (x < 0) and B (x > 0) and a performer with 3 points per patch.

    Key-model 0 moves A, 1 moves B, 2 moves both (its own pattern); the performer's examples move the points
    of the same patches the same way (each key-model's smooth offset field sampled at the points)."""
    a = rng.normal(size=(60, 3)) * 0.3 + [-5.0, 0, 0]
    b = rng.normal(size=(60, 3)) * 0.3 + [5.0, 0, 0]
    tb = np.vstack([a, b])
    inA = np.r_[np.ones(60), np.zeros(60)].astype(bool)
    fields = [lambda p: np.c_[0.2 + 0 * p[:, 0], 0.1 * p[:, 1], 0 * p[:, 0]],
              lambda p: np.c_[0 * p[:, 0], 0.3 + 0 * p[:, 0], 0.1 * p[:, 2]],
              lambda p: np.c_[0.1 * p[:, 2], 0 * p[:, 0], 0.25 + 0 * p[:, 0]]]
    which = [inA, ~inA, np.ones(120, bool)]
    deltas = np.stack([np.where(w[:, None], f(tb), 0.0) for f, w in zip(fields, which, strict=True)])
    sb = np.vstack([a[:3], b[:3]]) + 0.01
    pA = np.r_[np.ones(3), np.zeros(3)].astype(bool)
    pw = [pA, ~pA, np.ones(6, bool)]
    sd = np.stack([np.where(w[:, None], f(sb) * 1.3, 0.0) for f, w in zip(fields, pw, strict=True)])
    return sb, sb + sd, tb, tb + deltas, inA, pA, sd


@pytest.fixture
def scene():
    return two_patches(np.random.default_rng(4))


def masks_for(inA):
    m = np.zeros((3, len(inA)))
    m[1, inA], m[2, ~inA] = 1.0, 1.0
    return m


def test_regional_is_registered():
    assert "regional" in METHODS


@pytest.mark.parametrize("leak", [0.0, 0.2])
def test_guarantees_neutral_and_examples(scene, leak):
    sb, se, tb, te, inA, pA, _ = scene
    m = ExpressionMapper.fit(sb, se, tb, te, method="regional", regions=masks_for(inA),
                             region_names=("background", "A", "B"), leak=leak)
    assert m.regional and m.region_names == ("background", "A", "B")
    w0 = m.weights(sb)
    assert w0.shape == (3, 3)
    np.testing.assert_allclose(w0, 0.0, atol=1e-12)
    np.testing.assert_allclose(m.synthesize(w0), tb, atol=1e-12)
    for i in range(3):   # to rounding: coordinates of about 5, solved through the examples' inverse
        np.testing.assert_allclose(m.synthesize(m.weights(se[i])), te[i], atol=1e-8)


def test_region_a_key_model_does_not_move_takes_no_weight(scene):
    sb, se, tb, te, inA, pA, _ = scene
    m = ExpressionMapper.fit(sb, se, tb, te, method="regional", regions=masks_for(inA), leak=0.2)
    sup = m.region_support
    assert sup[1].tolist() == [True, False, True] and sup[2].tolist() == [False, True, True]
    w = m.weights(se[2] + np.random.default_rng(0).normal(scale=0.05, size=se[2].shape))
    assert w[1, 1] == 0.0 and w[2, 0] == 0.0


def test_non_uniform_blend_mouth_of_one_brows_of_another(scene):
    """Points of A do key-model 2's motion, points of B stay: A takes key-model 2, B stays neutral."""
    sb, se, tb, te, inA, pA, sd = scene
    m = ExpressionMapper.fit(sb, se, tb, te, method="regional", regions=masks_for(inA), leak=0.0)
    x = sb + np.where(pA[:, None], sd[2], 0.0)
    w = m.weights(x)
    np.testing.assert_allclose(w[1], [0, 0, 1], atol=1e-9)
    np.testing.assert_allclose(w[2], [0, 0, 0], atol=1e-12)
    out = m.synthesize(w)
    np.testing.assert_allclose(out[inA], te[2][inA], atol=1e-9)
    np.testing.assert_allclose(out[~inA], tb[~inA], atol=1e-9)
    g = ExpressionMapper.fit(sb, se, tb, te)              # the global mapping cannot do this
    assert np.abs(g.synthesize(g.weights(x)) - np.where(inA[:, None], te[2], tb)).max() > 1e-2


def test_arrays_only_finds_regions_and_points(scene):
    sb, se, tb, te, inA, pA, _ = scene
    m = ExpressionMapper.fit(sb, se, tb, te, method="regional", names=("jawOpen", "browDown_L", "mouthSmile"))
    masks = m.region_masks
    np.testing.assert_allclose(masks.sum(0), 1.0)
    assert len(m.region_names) >= 3 and m.region_names[0] == "background"
    for i in range(3):
        np.testing.assert_allclose(m.synthesize(m.weights(se[i])), te[i], atol=1e-9)
    np.testing.assert_allclose(m.synthesize(m.weights(sb)), tb, atol=1e-12)


def test_split_targets_equal_synthesize(scene):
    sb, se, tb, te, inA, pA, _ = scene
    m = ExpressionMapper.fit(sb, se, tb, te, method="regional", regions=masks_for(inA))
    x = np.stack([sb + 0.5 * (se[0] - sb), sb + 0.3 * (se[2] - sb) + 0.4 * (se[1] - sb)])
    w = m.weights(x)
    targets = m.split_targets()
    assert targets.shape == (9, len(tb), 3)
    direct = tb + np.einsum("fk,kvc->fvc", w.reshape(2, -1), targets)
    np.testing.assert_allclose(m.synthesize(w), direct, atol=1e-12)


def test_save_load_round_trip(scene, tmp_path):
    sb, se, tb, te, inA, pA, _ = scene
    m = ExpressionMapper.fit(sb, se, tb, te, method="regional", names=("a", "b", "c"),
                             nuisance=sb[None] + np.random.default_rng(1).normal(scale=0.01, size=(5, 6, 3)))
    m.save(tmp_path / "m.npz")
    back = ExpressionMapper.load(tmp_path / "m.npz")
    x = se[1] + 0.02
    assert back.regional and back.region_names == m.region_names
    np.testing.assert_array_equal(back.weights(x), m.weights(x))
    np.testing.assert_array_equal(back.region_masks, m.region_masks)


def test_bad_regions_are_one_clear_error(scene):
    sb, se, tb, te, inA, pA, _ = scene
    with pytest.raises(ValueError, match="regions must be"):
        ExpressionMapper.fit(sb, se, tb, te, method="regional", regions=np.ones((2, len(tb))))
    with pytest.raises(ValueError, match="apply to method 'regional'"):
        ExpressionMapper.fit(sb, se, tb, te, regions=masks_for(inA))
    with pytest.raises(ValueError, match="leak"):
        ExpressionMapper.fit(sb, se, tb, te, method="regional", leak=2.0)


def test_wire_synthesis_is_delegated(scene):
    sb, se, tb, te, *_ = scene
    m = ExpressionMapper.fit(sb, se, tb, te)

    class Wires:
        def synthesize(self, w):
            return np.full((len(tb), 3), float(np.sum(w)))

    np.testing.assert_array_equal(m.synthesize([0.5, 0.25, 0.0], wires=Wires()), 0.75)
