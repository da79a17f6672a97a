import numpy as np

from facepuppet.capture.one_euro import OneEuro, OneEuroConfig


def test_constant_passes_unchanged():
    f = OneEuro()
    x = np.array([[1.0, 2.0], [3.0, 4.0]])
    for _ in range(5):
        np.testing.assert_allclose(f(x, 1 / 30), x)


def test_still_noise_is_damped_and_fast_motion_followed():
    rng = np.random.default_rng(0)
    f = OneEuro(OneEuroConfig(min_cutoff=1.0, beta=5.0, d_cutoff=1.0))
    noisy = rng.normal(0.0, 0.01, (300, 1, 2))
    out = np.array([f(v, 1 / 30) for v in noisy])
    # Still: the frame-to-frame steps are much smaller than the noise's.
    assert np.abs(np.diff(out[50:], axis=0)).mean() < 0.5 * np.abs(np.diff(noisy[50:], axis=0)).mean()
    # A fast ramp (3 units/s) is followed with a lag of a small fraction of the distance covered.
    f.reset()
    t = np.arange(60) / 30
    ramp = np.stack([3.0 * t, 0 * t], axis=-1)[:, None]
    out = np.array([f(v, 1 / 30) for v in ramp])
    lag = ramp[-1, 0, 0] - out[-1, 0, 0]
    assert 0 <= lag < 0.1 * ramp[-1, 0, 0]


def test_first_sample_and_bad_step_pass_through():
    f = OneEuro()
    np.testing.assert_allclose(f(np.ones((3, 2)), 1 / 30), 1.0)
    np.testing.assert_allclose(f(np.zeros((3, 2)), 0.0), 0.0)
