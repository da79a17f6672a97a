import numpy as np
import pytest

from facepuppet.capture.curves import (
    CURVE_NAMES,
    IBUG_CURVES,
    POINT_NAMES,
    POINT_SAMPLES,
    bernstein,
    bezier_points,
    curve_points,
    fit_bezier,
)


def test_vocabulary_is_complete_and_consistent():
    assert set(CURVE_NAMES) == set(IBUG_CURVES)
    assert len(POINT_NAMES) == len(CURVE_NAMES) * len(POINT_SAMPLES)
    assert len(set(POINT_NAMES)) == len(POINT_NAMES)


def test_bernstein_is_a_partition_of_unity_with_endpoint_interpolation():
    B = bernstein(np.linspace(0, 1, 11))
    np.testing.assert_allclose(B.sum(1), 1.0)
    np.testing.assert_allclose(B[0], [1, 0, 0, 0])
    np.testing.assert_allclose(B[-1], [0, 0, 0, 1])


@pytest.mark.parametrize("seed", range(5))
def test_fit_bezier_recovers_a_curve_from_its_samples(seed):
    # an arc like a lid or lip contour: ends apart, inner control points to one side, no loop
    r = np.random.default_rng(seed)
    ctrl = np.array([[0, 0], [r.uniform(5, 15), r.uniform(5, 20)], [r.uniform(20, 35), r.uniform(5, 20)], [40, 0]])
    ctrl = ctrl @ np.array([[np.cos(seed), -np.sin(seed)], [np.sin(seed), np.cos(seed)]]) + r.normal(size=2) * 50
    pts = bezier_points(ctrl, 200)
    fit = fit_bezier(pts)
    np.testing.assert_allclose(fit[[0, 3]], ctrl[[0, 3]])
    # the fitted curve passes within a small fraction of the curve's size of every sample
    dense = bezier_points(fit, 2000)
    d = np.linalg.norm(pts[:, None] - dense[None], axis=-1).min(1)
    assert d.max() < 0.01 * np.ptp(pts, axis=0).max()


def test_fit_bezier_of_a_line_is_the_line():
    pts = np.c_[np.linspace(0, 9, 10), np.linspace(3, 21, 10)]
    fit = fit_bezier(pts)
    np.testing.assert_allclose(fit, [[0, 3], [3, 9], [6, 15], [9, 21]], atol=1e-9)
    np.testing.assert_allclose(fit_bezier(pts[[0, -1]]), fit)


def test_fit_bezier_rejects_too_few_points():
    with pytest.raises(ValueError, match="points"):
        fit_bezier(np.zeros((1, 2)))


def test_curve_points_samples_each_curve_in_order(rng):
    curves = rng.normal(size=(2, len(CURVE_NAMES), 4, 3))
    pts = curve_points(curves)
    assert pts.shape == (2, len(POINT_NAMES), 3)
    k = len(POINT_SAMPLES)
    np.testing.assert_allclose(pts[:, 0], curves[:, 0, 0])          # s = 0: first control point
    np.testing.assert_allclose(pts[:, k - 1], curves[:, 0, 3])      # s = 1: last control point
    np.testing.assert_allclose(pts[1, k:2 * k], bernstein(np.array(POINT_SAMPLES)) @ curves[1, 1])


def test_fit_bezier_through_three_points_passes_through_the_middle_one():
    pts = np.array([[100.0, 200.0], [110.0, 205.0], [125.0, 202.0]])
    ctrl = fit_bezier(pts)
    assert np.allclose(ctrl[[0, 3]], pts[[0, 2]])
    samples = bezier_points(ctrl, 401)
    assert np.linalg.norm(samples - pts[1], axis=1).min() < 0.1
    # stays near the points: no control point pulled towards the origin
    assert np.all(np.abs(ctrl - pts.mean(0)) < 20)
