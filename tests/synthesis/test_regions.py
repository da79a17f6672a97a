"""Regional blending: masks from the wires' influence, the blend against the formula, Eq. 14 as a special case."""

from __future__ import annotations

import numpy as np
import pytest

from facepuppet.synthesis import WireDeformer, region_masks, region_support, regional_blend, split_targets


def test_masks_partition_of_unity_by_hand():
    f = np.array([[1.0, 0.5, 0.0, 0.8],
                  [0.0, 0.25, 0.0, 0.6]])
    m = region_masks(f)
    want = np.array([[0.0, 0.25, 1.0, 0.0],
                     [1.0, 0.5, 0.0, 0.8 / 1.4],
                     [0.0, 0.25, 0.0, 0.6 / 1.4]])
    np.testing.assert_allclose(m, want)
    np.testing.assert_allclose(m.sum(axis=0), 1.0)


def test_masks_of_a_bound_mesh(rng):
    pts = rng.uniform(-2, 2, size=(400, 3))
    refs = [np.array([[-1.0, 0, 0], [1, 0, 0]]), np.array([[0.0, -1, 0.5], [0, 1, 0.5]])]
    m = region_masks(WireDeformer(pts, refs, [0.8, 1.2]).influence())
    assert m.shape == (3, 400)
    assert (m >= 0).all()
    np.testing.assert_allclose(m.sum(axis=0), 1.0)
    far = np.linalg.norm(pts, axis=1) > 3.5
    np.testing.assert_array_equal(m[0, far], 1.0)


def small_character(rng, v=30, n_keys=4):
    tb = rng.normal(size=(v, 3))
    deltas = rng.normal(size=(n_keys, v, 3))
    masks = region_masks(rng.uniform(0, 1, size=(2, v)) * (rng.uniform(size=(2, v)) > 0.3))
    return tb, deltas, masks


def test_blend_against_the_formula(rng):
    tb, deltas, masks = small_character(rng)
    w = rng.normal(size=(3, 4))
    want = tb.copy()
    for k in range(3):
        for i in range(4):
            want += masks[k][:, None] * w[k, i] * deltas[i]
    np.testing.assert_allclose(regional_blend(tb, deltas, masks, w), want, atol=1e-12)
    frames = rng.normal(size=(5, 3, 4))
    got = regional_blend(tb, deltas, masks, frames)
    np.testing.assert_allclose(got[2], regional_blend(tb, deltas, masks, frames[2]), atol=1e-12)


def test_same_weights_everywhere_is_eq14_and_keeps_the_examples(rng):
    tb, deltas, masks = small_character(rng)
    w = rng.normal(size=4)
    np.testing.assert_allclose(regional_blend(tb, deltas, masks, np.tile(w, (3, 1))),
                               tb + np.tensordot(w, deltas, 1), atol=1e-12)
    np.testing.assert_allclose(regional_blend(tb, deltas, masks, np.zeros((3, 4))), tb)
    for i in range(4):
        e = np.zeros((3, 4))
        e[:, i] = 1.0
        np.testing.assert_allclose(regional_blend(tb, deltas, masks, e), tb + deltas[i], atol=1e-12)


def test_split_targets_play_the_blend(rng):
    tb, deltas, masks = small_character(rng)
    w = rng.normal(size=(3, 4))
    targets = split_targets(deltas, masks)
    assert targets.shape == (12, 30, 3)
    np.testing.assert_allclose(tb + np.tensordot(w.reshape(-1), targets, 1),
                               regional_blend(tb, deltas, masks, w), atol=1e-12)
    np.testing.assert_allclose(targets.reshape(3, 4, 30, 3).sum(axis=0), deltas, atol=1e-12)


def test_region_support():
    masks = np.array([[1.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 1.0]])
    deltas = np.zeros((3, 4, 3))
    deltas[0, 0] = [1, 0, 0]          # key 0 moves region 0 only
    deltas[1, 3] = [0, 2, 0]          # key 1 moves region 1 only
    deltas[2, [1, 2]] = [0, 0, 1]     # key 2 moves both; key-model with no motion: none
    np.testing.assert_array_equal(region_support(deltas, masks), [[1, 0, 1], [0, 1, 1]])


@pytest.mark.parametrize("call, word", [
    (lambda: region_masks(np.full((2, 3), 1.5)), "influence"),
    (lambda: region_masks(np.zeros(3)), "influence"),
    (lambda: regional_blend(np.zeros((3, 2)), np.zeros((1, 3, 3)), np.ones((1, 3)), np.ones((1, 1))), "neutral"),
    (lambda: regional_blend(np.zeros((3, 3)), np.zeros((1, 4, 3)), np.ones((1, 3)), np.ones((1, 1))), "deltas"),
    (lambda: regional_blend(np.zeros((3, 3)), np.zeros((1, 3, 3)), np.ones((1, 4)), np.ones((1, 1))), "masks"),
    (lambda: regional_blend(np.zeros((3, 3)), np.zeros((1, 3, 3)), np.ones((1, 3)), np.ones((2, 1))), "weights"),
    (lambda: split_targets(np.zeros((1, 3, 3)), np.ones((1, 2))), "masks"),
])
def test_bad_input_names_the_argument(call, word):
    with pytest.raises(ValueError, match=word):
        call()
