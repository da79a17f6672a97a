"""The demo's key vocabulary and scripted performances."""

from __future__ import annotations

import numpy as np
import pytest

from facepuppet.demo.script import (
    ARKIT_NAMES,
    HEAD_AMPLITUDE,
    KEY_DESCRIPTIONS,
    KEY_NAMES,
    calibration_script,
    performance_script,
)


def test_vocabulary_has_thirteen_arkit_keys():
    assert len(KEY_NAMES) == 13 == len(set(KEY_NAMES))
    assert set(ARKIT_NAMES) == set(KEY_NAMES) == set(KEY_DESCRIPTIONS)
    for key, arkit in ARKIT_NAMES.items():
        assert all(a.startswith(key) for a in arkit), key


def test_performance_weights_bounded_smooth_sparse_and_complete():
    s = performance_script(seconds=10, fps=30, seed=0)
    assert s.weights.shape == (300, 13) and s.head_motion.shape == (300, 6)
    assert s.weights.min() >= 0.0 and s.weights.max() <= 1.0
    assert np.all(s.weights.max(axis=0) >= 0.85)  # every key shown clearly at least once
    assert np.abs(np.diff(s.weights, axis=0)).max() < 0.5  # no jumps at 30 fps
    assert (s.weights > 0.05).sum(axis=1).max() <= 4  # a few keys at a time
    assert np.allclose(s.weights[:5], 0.0)  # starts neutral


def test_performance_has_spontaneous_blinks():
    s = performance_script(seconds=10, fps=30, seed=3)
    blink = s.weights[:, KEY_NAMES.index("eyeBlink")]
    closed = blink > 0.8
    n_events = int(np.sum(closed[1:] & ~closed[:-1]) + closed[0])
    assert n_events >= 3  # its own slot plus spontaneous blinks


def test_head_motion_bounded_smooth_and_starts_frontal():
    s = performance_script(seconds=10, fps=30, seed=1)
    assert np.all(np.abs(s.head_motion) <= np.asarray(HEAD_AMPLITUDE) + 1e-12)
    assert np.allclose(s.head_motion[0], 0.0)
    assert np.abs(np.diff(s.head_motion, axis=0)).max(axis=0)[:3].max() < 0.02  # rad per frame
    assert s.head_motion[:, 0].std() > 0.03  # it does move


def test_performance_is_deterministic_per_seed():
    a, b, c = performance_script(seed=5), performance_script(seed=5), performance_script(seed=6)
    assert np.array_equal(a.weights, b.weights) and np.array_equal(a.head_motion, b.head_motion)
    assert not np.array_equal(a.weights, c.weights)


def test_too_short_performance_is_refused():
    with pytest.raises(ValueError, match="seconds"):
        performance_script(seconds=2.0)
    with pytest.raises(ValueError, match="fps"):
        performance_script(fps=0)


def test_calibration_holds_each_key_alone():
    c = calibration_script(hold=0.5, transition=0.25, fps=30)
    assert list(c.marks) == ["neutral", *KEY_NAMES]
    a, b = c.spans["head-motion"]
    assert np.allclose(c.head_motion[:a], 0.0)     # the head is still while the expressions are shown
    for name, (a, b) in c.holds.items():
        assert b - a >= 14  # about 0.5 s at 30 fps
        held = c.weights[a:b]
        expect = np.zeros(13)
        if name != "neutral":
            expect[KEY_NAMES.index(name)] = 1.0
        assert np.allclose(held, expect[None]), name
        assert a <= c.marks[name] < b


def test_calibration_ends_with_the_neutral_face_and_the_head_moving():
    c = calibration_script(hold=0.5, transition=0.25, fps=30, head_motion=5.0)
    a, b = c.spans["head-motion"]
    assert b == c.n_frames and b - a == 150
    assert a >= max(stop for _, stop in c.holds.values())
    assert np.all(c.weights[a:] == 0.0)
    np.testing.assert_allclose(c.head_motion[a], 0.0, atol=1e-12)        # eased in from the frontal pose
    reach = np.abs(c.head_motion[a:]).max(axis=0) / np.asarray(HEAD_AMPLITUDE)
    assert np.all(reach > 0.9), reach                                     # every channel sweeps its range
    assert calibration_script(head_motion=0.0).spans == {}
    with pytest.raises(ValueError, match="head_motion"):
        calibration_script(head_motion=-1.0)
