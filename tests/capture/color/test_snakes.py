"""Bezier snakes (paper §3.3, Eqs. 2-4) on synthetic shapes with known outlines, both cases of Fig. 3."""

import numpy as np
import pytest

from facepuppet.capture.color.snakes import (
    LOWER,
    UPPER,
    SnakeConfig,
    SnakeSolver,
    box_guess,
    minimise_snakes,
    snake_energy,
    snake_fields,
)
from facepuppet.capture.curves import bernstein

UP = np.array([0.0, -1.0])          # upright head: up is -y in the image
S = np.linspace(0, 1, 200)
B = bernstein(S)

# A lip-like band between two known Bezier outlines: A (upper boundary) and B (lower boundary).
CURVE_A = np.array([[20.0, 40.0], [35.0, 30.0], [65.0, 30.0], [80.0, 40.0]])
CURVE_B = np.array([[20.0, 40.0], [35.0, 50.0], [65.0, 50.0], [80.0, 40.0]])
CONFIG = SnakeConfig(iterations=40, step=1.5, decay=0.93, samples=16, offset=2.0)


def _band_image(h=80, w=100):
    """Feature intensity 1 between curves A and B, 0 on the skin around it."""
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32) + 0.5
    top = np.interp(xx, (B @ CURVE_A)[:, 0], (B @ CURVE_A)[:, 1], left=np.inf, right=np.inf)
    bot = np.interp(xx, (B @ CURVE_B)[:, 0], (B @ CURVE_B)[:, 1], left=-np.inf, right=-np.inf)
    return ((yy > top) & (yy < bot)).astype(np.float32)


def _distance(ctrl, truth):
    """Mean distance from the true outline's samples to the fitted curve's samples (pixels)."""
    p, q = B @ truth, B @ ctrl
    return float(np.linalg.norm(p[:, None] - q[None], axis=-1).min(axis=1).mean())


@pytest.fixture(scope="module")
def fields():
    return snake_fields(_band_image(), blur=5)


def test_fields_hold_intensity_and_gradients():
    img = np.zeros((20, 20), np.float32)
    img[:, 10:] = 1.0
    f = snake_fields(img, blur=0)
    assert f.shape == (20, 20, 5)
    assert f[5, 9, 1] == pytest.approx(0.5) and f[5, 10, 1] == pytest.approx(0.5)
    assert np.all(f[..., 2] == 0)


@pytest.mark.parametrize("side, truth, start_dy", [(UPPER, CURVE_A, -4.0), (UPPER, CURVE_A, 4.0),
                                                   (LOWER, CURVE_B, 4.0), (LOWER, CURVE_B, -4.0)])
def test_snake_converges_on_its_own_outline(fields, side, truth, start_dy):
    start = truth + [0.0, start_dy]
    start[[1, 2], 1] += np.sign(start_dy) * 2.0
    got = minimise_snakes(start[None], np.array([side]), UP, fields, CONFIG)[0]
    assert _distance(start, truth) > 4.0
    assert _distance(got, truth) < 1.0


def test_fig3_the_constraint_term_tells_curve_a_from_curve_b(fields):
    """Both outlines lie on strong edges; only Eq. 4 makes A the minimum for UPPER and B for LOWER."""
    both = np.stack([CURVE_A, CURVE_B])
    e_up = snake_energy(both, np.array([UPPER, UPPER]), UP, fields, CONFIG)
    e_lo = snake_energy(both, np.array([LOWER, LOWER]), UP, fields, CONFIG)
    assert e_up[0] < e_up[1] and e_lo[1] < e_lo[0]
    edge_only = SnakeConfig(w_in=0.0, w_out=0.0)
    e_edge = snake_energy(both, np.array([UPPER, UPPER]), UP, fields, edge_only)
    assert abs(e_edge[0] - e_edge[1]) < 0.1 * abs(e_edge[0])      # gradients alone cannot tell them apart


def test_fig3_from_the_middle_of_the_feature_each_side_finds_its_own_outline(fields):
    """The same initial guess inside the lip goes to A as an UPPER curve and to B as a LOWER curve."""
    middle = (CURVE_A + CURVE_B) / 2.0
    middle[[1, 2], 1] += [-1.0, -1.0]
    got = minimise_snakes(np.stack([middle, middle]), np.array([UPPER, LOWER]), UP, fields, CONFIG)
    assert _distance(got[0], CURVE_A) < 1.0
    assert _distance(got[1], CURVE_B) < 1.0


def test_up_vector_follows_head_roll():
    """Rotate the whole scene by 90 degrees: with the rotated up-vector the snake still finds curve A."""
    img = np.ascontiguousarray(np.rot90(_band_image()))        # (x, y) -> (y, w - 1 - x) ... new coords below
    w = _band_image().shape[1]
    rot = lambda c: np.stack([c[:, 1], w - c[:, 0]], axis=1)   # noqa: E731
    f = snake_fields(img, blur=5)
    up = np.array([-1.0, 0.0])
    start = rot(CURVE_A + [0.0, -4.0])
    got = minimise_snakes(start[None], np.array([UPPER]), up, f, CONFIG)[0]
    assert _distance(got, rot(CURVE_A)) < 1.0


def test_fixed_ends_stay_put(fields):
    start = CURVE_A + [0.0, -3.0]
    got = minimise_snakes(start[None], np.array([UPPER]), UP, fields, CONFIG, fixed_ends=np.array([True]))[0]
    np.testing.assert_array_equal(got[[0, 3]], start[[0, 3]].astype(np.float32))


def test_a_solver_set_up_once_finds_both_outlines_each_time(fields):
    """A tracker's solver (sides, up-vector and options fixed) reused on several guesses: each finds its outline,
    and the ends held fixed stay put."""
    solve = SnakeSolver(np.array([UPPER, LOWER]), UP, CONFIG, fixed_ends=np.array([True, True]))
    for dy in (-3.0, 2.0):
        start = np.stack([CURVE_A, CURVE_B]) + [0.0, dy]
        got = solve(start, fields)
        assert _distance(got[0], CURVE_A) < 1.0 and _distance(got[1], CURVE_B) < 1.0
        np.testing.assert_array_equal(got[:, [0, 3]], start[:, [0, 3]].astype(np.float32))
    with pytest.raises(ValueError, match="2 curves"):
        solve(CURVE_A[None], fields)


def test_box_guess_is_the_top_or_bottom_edge_of_the_box():
    box = np.array([[10.0, 20.0, 40.0, 30.0], [10.0, 20.0, 40.0, 30.0]])
    g = box_guess(box, np.array([UPPER, LOWER]))
    np.testing.assert_allclose(g[0], [[10, 20], [20, 20], [30, 20], [40, 20]])
    np.testing.assert_allclose(g[1], [[10, 30], [20, 30], [30, 30], [40, 30]])


def test_empty_batch():
    f = snake_fields(np.zeros((8, 8), np.float32))
    assert minimise_snakes(np.zeros((0, 4, 2)), np.zeros(0), UP, f).shape == (0, 4, 2)


def test_lip_field_paints_the_opening_at_the_lips_level():
    """Inside the inner lips the field takes the median over the lips (between outer and inner curves); outside
    it is unchanged, and a closed mouth (inner lips on each other) leaves the whole field as it is."""
    from facepuppet.capture.color.snakes import lip_field
    from facepuppet.capture.curves import CURVE_NAMES

    idx = {n: i for i, n in enumerate(CURVE_NAMES)}
    img = np.zeros((60, 80), np.float32)
    img[10:50, 10:70] = 0.4                                   # lips
    img[25:35, 20:60] = 1.0                                   # the opening, brighter than the lips in C
    curves = np.zeros((len(CURVE_NAMES), 4, 2))

    def line(y0, y1, x0=10.0, x1=70.0):
        return np.array([[x0, y0], [x0 + (x1 - x0) / 3, y1], [x0 + 2 * (x1 - x0) / 3, y1], [x1, y0]])

    curves[idx["lip_upper_outer"]] = line(30, 2.0)            # B(1/2) at y 9.5
    curves[idx["lip_lower_outer"]] = line(30, 58.0)           # B(1/2) at y 51.5
    curves[idx["lip_upper_inner"]] = line(30, 20.0, 18, 62)   # B(1/2) at y 22.5
    curves[idx["lip_lower_inner"]] = line(30, 40.0, 18, 62)   # B(1/2) at y 37.5
    out = lip_field(img, curves)
    assert np.all(out[27:33, 30:50] == np.float32(0.4))       # the opening at the lips' level ...
    assert out[25, 20] == 1.0                                 # ... inside the inner lips only
    assert np.array_equal(out[:8], img[:8]) and np.array_equal(out[52:], img[52:])
    assert out[30, 5] == 0.0 and out[45, 40] == np.float32(0.4)
    closed = curves.copy()
    closed[idx["lip_lower_inner"]] = closed[idx["lip_upper_inner"]]
    assert np.array_equal(lip_field(img, closed), img)
