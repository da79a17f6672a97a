"""One-Euro smoothing: known answers on constant, step, noisy and lost-frame inputs."""

from __future__ import annotations

import numpy as np
import pytest

from facepuppet.pipeline.smoothing import OneEuroFilter, SmoothingConfig, parse_smoothing, smooth

FPS = 30.0


def test_constant_input_passes_unchanged():
    w = np.tile([0.0, 0.3, 1.0], (60, 1))
    np.testing.assert_allclose(smooth(w, FPS), w, atol=1e-12)


def test_first_sample_passes_unchanged():
    f = OneEuroFilter(3)
    np.testing.assert_array_equal(f.update(np.array([0.1, 0.2, 0.3]), 0.0), [0.1, 0.2, 0.3])


def test_step_response_is_monotone_and_converges():
    w = np.r_[np.zeros(10), np.ones(50)][:, None]
    y = smooth(w, FPS)[:, 0]
    assert np.all(np.diff(y) >= -1e-12)
    assert np.all(y <= 1.0 + 1e-12)
    assert y[10] > 0.3                      # it starts moving at once (little lag on fast change)
    assert y[10 + 6] > 0.95                 # within 0.2 s it is nearly there
    assert abs(y[-1] - 1.0) < 1e-3


def test_noise_variance_is_reduced(rng):
    truth = 0.4
    w = truth + 0.02 * rng.standard_normal((300, 4))
    y = smooth(w, FPS)[30:]
    ratio = np.var(y - truth) / np.var(w[30:] - truth)
    assert ratio < 0.35
    assert abs(np.mean(y) - truth) < 0.01


def test_vectorised_equals_per_channel(rng):
    w = np.cumsum(rng.standard_normal((100, 3)) * 0.05, axis=0)
    batch = smooth(w, FPS)
    for c in range(3):
        np.testing.assert_allclose(batch[:, c], smooth(w[:, c:c + 1], FPS)[:, 0], atol=1e-12)


def test_disabled_passes_valid_frames():
    w = np.random.default_rng(0).random((20, 2))
    np.testing.assert_array_equal(smooth(w, FPS, config=SmoothingConfig(enabled=False)), w)


def test_lost_frames_hold_then_ease_to_neutral():
    cfg = SmoothingConfig(hold=0.25, ease=0.3)
    w = np.full((60, 2), 0.8)
    valid = np.ones(60, bool)
    valid[10:] = False                          # lost from t = 10/30 s on
    y = smooth(w, FPS, valid=valid, config=cfg)
    t_gap = (np.arange(60) - 10) / FPS
    held = (t_gap >= 0) & (t_gap <= 0.25)
    np.testing.assert_allclose(y[held], 0.8)    # hold
    easing = (t_gap > 0.25) & (t_gap < 0.55)
    assert np.all(np.diff(y[easing, 0]) < 0)    # eases down monotonically
    assert np.all((y[easing] > 0) & (y[easing] < 0.8))
    np.testing.assert_allclose(y[t_gap >= 0.55 + 1e-9], 0.0)   # neutral after hold + ease


def test_return_after_loss_does_not_jump():
    w = np.full((40, 1), 0.8)
    valid = np.ones(40, bool)
    valid[5:30] = False                         # long gap: output reaches 0
    y = smooth(w, FPS, valid=valid)[:, 0]
    assert y[29] == pytest.approx(0.0)
    # resumes from neutral through the filter, standing still there: one One-Euro step from 0 towards 0.8
    cfg, T = SmoothingConfig(), 1 / FPS

    def alpha(fc):
        return 1 / (1 + 1 / (2 * np.pi * fc) / T)

    dx = alpha(cfg.d_cutoff) * 0.8 / T
    step = alpha(cfg.min_cutoff + cfg.beta * abs(dx)) * 0.8
    assert y[30] == pytest.approx(step, rel=1e-9) and 0.4 < step < 0.7      # no jump to 0.8
    assert np.all(np.diff(y[30:]) >= 0)


def test_lost_before_any_face_is_neutral():
    w = np.full((5, 2), np.nan)
    np.testing.assert_array_equal(smooth(w, FPS), 0.0)


def test_parse_smoothing():
    assert parse_smoothing("on") == SmoothingConfig()
    assert parse_smoothing("off").enabled is False
    cfg = parse_smoothing("min_cutoff=1.0, beta=0.5")
    assert (cfg.min_cutoff, cfg.beta) == (1.0, 0.5)
    with pytest.raises(ValueError, match="--smoothing"):
        parse_smoothing("speed=3")
    with pytest.raises(ValueError, match="min_cutoff"):
        parse_smoothing("min_cutoff=0")
