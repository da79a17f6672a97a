"""The CPU mesh renderer: coverage of a known triangle, shading, depth order, culling, determinism."""

from __future__ import annotations

import numpy as np
import pytest

from facepuppet.export.render import Camera, Light, render_mesh

W, H = 64, 48
BG = (0, 0, 0)


def _ortho() -> Camera:
    """Orthographic camera with one pixel per unit: (x, y, z) lands on pixel (W/2 + x, H/2 - y)."""
    return Camera(center=np.zeros(3), scale=1.0, size=(W, H))


def _mesh_from_pixels(pix, z=0.0):
    """Vertices (3, 3) whose orthographic images are the pixel positions ``pix`` (3, 2)."""
    pix = np.asarray(pix, float)
    return np.column_stack([pix[:, 0] - W / 2, H / 2 - pix[:, 1], np.full(3, z)])


def _inside(pix, px, py):
    """Signed-distance test of points (px, py) against the triangle ``pix`` (3, 2): min edge distance."""
    d = []
    for i in range(3):
        a, b = np.asarray(pix[i], float), np.asarray(pix[(i + 1) % 3], float)
        c = np.asarray(pix[(i + 2) % 3], float)
        n = np.array([-(b - a)[1], (b - a)[0]])
        n /= np.linalg.norm(n)
        if n @ (c - a) < 0:
            n = -n
        d.append((px - a[0]) * n[0] + (py - a[1]) * n[1])
    return np.min(d, axis=0)


def test_triangle_covers_the_analytic_pixels():
    pix = [(10.0, 8.0), (50.0, 12.0), (20.0, 40.0)]
    img = render_mesh(_mesh_from_pixels(pix), np.array([[0, 1, 2]]), camera=_ortho(), background=BG,
                      cull=False, colors=(1.0, 1.0, 1.0))
    py, px = np.mgrid[0:H, 0:W]
    dist = _inside(pix, px, py)
    painted = img.sum(axis=2) > 0
    assert painted[dist > 1.0].all()  # well inside: painted
    assert not painted[dist < -1.0].any()  # well outside: background
    # the painted area matches the triangle's area to within its border pixels
    (ax, ay), (bx, by) = np.subtract(pix[1], pix[0]), np.subtract(pix[2], pix[0])
    area = 0.5 * abs(ax * by - ay * bx)
    perimeter = sum(np.hypot(*np.subtract(pix[i], pix[(i + 1) % 3])) for i in range(3))
    assert abs(painted.sum() - area) <= 0.6 * perimeter


def test_flat_lambert_colour_of_a_facing_triangle():
    pix = [(10.0, 10.0), (10.0, 40.0), (50.0, 10.0)]  # counter-clockwise seen from +z (y up)
    light = Light(direction=(0.0, 0.6, 0.8), ambient=0.2, diffuse=0.5)
    base = np.array([0.8, 0.4, 0.2])
    img = render_mesh(_mesh_from_pixels(pix), np.array([[0, 1, 2]]), camera=_ortho(), background=BG,
                      colors=base, light=light)
    shade = 0.2 + 0.5 * 0.8  # normal (0, 0, 1) . light
    expected = np.clip(base * shade * 255 + 0.5, 0, 255).astype(int)
    assert img[15, 15].tolist() == expected.tolist()


def test_back_faces_are_culled_and_two_sided_mode_draws_them():
    pix = [(10.0, 10.0), (50.0, 10.0), (10.0, 40.0)]  # clockwise seen from +z: faces away
    v, f = _mesh_from_pixels(pix), np.array([[0, 1, 2]])
    assert render_mesh(v, f, camera=_ortho(), background=BG).sum() == 0
    assert render_mesh(v, f, camera=_ortho(), background=BG, cull=False)[15, 15].sum() > 0


@pytest.mark.parametrize("near_first", [True, False])
def test_the_nearer_triangle_wins_whatever_the_face_order(near_first):
    pix = [(5.0, 5.0), (5.0, 43.0), (60.0, 5.0)]
    near, far = _mesh_from_pixels(pix, z=1.0), _mesh_from_pixels(pix, z=-1.0)
    far[:, 0] += 2.0  # slightly shifted so both are non-degenerate and overlap almost fully
    verts = np.vstack([near, far] if near_first else [far, near])
    faces = np.array([[0, 1, 2], [3, 4, 5]])
    red, blue = (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)
    colors = np.array([red, blue] if near_first else [blue, red])  # the near one is always red
    img = render_mesh(verts, faces, camera=_ortho(), background=BG, colors=colors)
    r, g, b = img[12, 15]
    assert r > 0 and b == 0


def test_perspective_projection_of_a_point_on_the_axis_and_off_it():
    cam = Camera(center=np.zeros(3), scale=10.0, size=(100, 100), distance=20.0)
    xy, depth = cam.project(np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 0.0], [1.0, 0.0, 10.0]]))
    np.testing.assert_allclose(xy[0], [50, 50])
    np.testing.assert_allclose(xy[1], [60, 40])
    np.testing.assert_allclose(xy[2], [50 + 10 * 20 / 10, 50])  # twice as near: twice as large
    np.testing.assert_allclose(depth, [0, 0, 10])


def test_fit_frames_the_vertices_inside_the_margin():
    rng = np.random.default_rng(0)
    v = rng.normal(size=(200, 3)) * [3.0, 2.0, 1.0] + [5.0, -1.0, 2.0]
    cam = Camera.fit(v, (120, 80), margin=0.1, yaw=0.3, pitch=-0.2)
    xy, _ = cam.project(v)
    assert xy[:, 0].min() >= 12 - 1e-6 and xy[:, 0].max() <= 108 + 1e-6
    assert xy[:, 1].min() >= 8 - 1e-6 and xy[:, 1].max() <= 72 + 1e-6


def test_rendering_is_deterministic_and_leaves_the_background_image_alone():
    from facepuppet.demo.toy import toy_character, toy_colors

    toy = toy_character()
    cam = Camera.fit(toy.neutral, (160, 160))
    bg = np.full((160, 160, 3), 7, np.uint8)
    a = render_mesh(toy.targets[0], toy.faces, camera=cam, colors=toy_colors(), background=bg)
    b = render_mesh(toy.targets[0], toy.faces, camera=cam, colors=toy_colors(), background=bg)
    assert np.array_equal(a, b)
    assert (bg == 7).all()
    assert (a != 7).any()


def test_bad_input_is_refused_with_a_clear_message():
    v, f = np.zeros((3, 3)), np.array([[0, 1, 2]])
    with pytest.raises(ValueError, match="faces index"):
        render_mesh(v, np.array([[0, 1, 3]]), camera=_ortho())
    with pytest.raises(ValueError, match="vertices"):
        render_mesh(np.zeros((3, 2)), f, camera=_ortho())
    with pytest.raises(ValueError, match="colors"):
        render_mesh(v, f, camera=_ortho(), colors=np.zeros((5, 3)))
    with pytest.raises(ValueError, match="size"):
        render_mesh(v, f, camera=_ortho(), size=(10, 10))
