import numpy as np

from facepuppet.filters import OneEuro, OneEuroConfig


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


def test_noise_going_to_and_fro_does_not_open_the_filter():
    # An input flipping between +e and -e every frame (the to-and-fro of noise, at its fastest). Its velocity
    # is filtered before its length is taken, so it averages out and the cut-off stays near min_cutoff; taking
    # the length first (speed ~ 2e per frame) would open the filter and let about 3/4 of the flips through.
    e, dt = 0.01, 1 / 30
    f = OneEuro(OneEuroConfig(min_cutoff=1.0, beta=50.0, d_cutoff=1.0))
    out = np.array([f(np.array([[e * (-1) ** k, 0.0]]), dt)[0, 0] for k in range(300)])
    amplitude = np.ptp(out[200:]) / 2
    # A plain exponential filter at min_cutoff (gain a) passes a / (2 - a) of a flip; at 1 Hz that is 0.095.
    a = 1 / (1 + 1 / (2 * np.pi * 1.0 * dt))
    assert a / (2 - a) * e <= amplitude < 0.3 * e


def test_restart_carries_on_from_a_value_standing_still():
    f = OneEuro(OneEuroConfig(min_cutoff=1.0, beta=0.0, d_cutoff=1.0))
    f(np.array([[5.0]]), 1 / 30)
    f.restart(np.array([[1.0]]))
    a = 1 / (1 + 1 / (2 * np.pi * 1.0 / 30))
    np.testing.assert_allclose(f(np.array([[2.0]]), 1 / 30), [[1.0 + a]])
