"""The coordinate-noise and nuisance statistics (mapping.noise), with known answers."""

from __future__ import annotations

import numpy as np

from facepuppet.mapping.noise import coordinate_noise, head_turn_nuisance, noise_from_examples


def test_coordinate_noise_recovers_each_coordinates_noise(rng):
    """Points = neutral + score-driven expressions + Gaussian noise of a known scale per coordinate (some
    coordinates noiseless): the scales come back, the noiseless ones at the floor."""
    f, p = 4000, 12
    neutral = rng.normal(size=(p, 3))
    scores = rng.uniform(0, 1, size=(f, 2))
    B = rng.normal(size=(2, p, 3))
    sigma = rng.uniform(0.05, 0.5, size=(p, 3))
    sigma[:3] = 0.0
    points = neutral + np.tensordot(scores, B, axes=1) + 0.2 + rng.normal(size=(f, p, 3)) * sigma
    got = coordinate_noise(points, scores, neutral, floor=0.1, motion_floor=0.0)
    floor = 0.1 * np.median(np.sqrt((sigma ** 2).mean(axis=1)))
    np.testing.assert_allclose(got, np.sqrt(sigma ** 2 + floor ** 2), rtol=0.1)
    assert np.allclose(got[:3], got[:3].min()) and got[:3].min() > 0


def test_noise_from_examples_is_the_noise_of_the_examples_blends(rng):
    """Frames that are exact blends of the examples plus known noise: the same scales as coordinate_noise with
    the true blend weights; too few frames give None."""
    f, p, m = 3000, 10, 2
    neutral = rng.normal(size=(p, 3))
    examples = neutral + rng.normal(size=(m, p, 3))
    w = rng.uniform(0, 1, size=(f, m))
    sigma = rng.uniform(0.01, 0.05, size=(p, 3))
    points = neutral + np.tensordot(w, examples - neutral, axes=1) + rng.normal(size=(f, p, 3)) * sigma
    got = noise_from_examples(points, neutral, examples)
    np.testing.assert_allclose(got, coordinate_noise(points, w, neutral), rtol=0.05)
    assert noise_from_examples(points[:m + 9], neutral, examples) is None


def test_head_turn_nuisance_needs_turns(rng):
    f, p = 100, 6
    neutral = rng.normal(size=(p, 3))
    points = neutral + 0.01 * rng.normal(size=(f, p, 3))
    still = np.tile(np.eye(3), (f, 1, 1))
    assert head_turn_nuisance(points, still, rng.uniform(size=(f, 3)), neutral) is None
    few = np.tile(np.eye(3), (8, 1, 1))
    few[:, 0, 2] = np.linspace(-0.1, 0.1, 8)
    assert head_turn_nuisance(points[:8], few, rng.uniform(size=(8, 3)), neutral) is None   # 8 < 2 * (1 + 3 + 3)
