"""The Toy character made by code: its mesh, key-models and colours."""

from __future__ import annotations

import numpy as np

from facepuppet.demo.script import KEY_NAMES
from facepuppet.demo.toy import KEY_REGIONS, PARTS, toy_character, toy_colors, toy_parts
from facepuppet.export.render import Camera, render_mesh


def test_names_shapes_finite_and_valid_faces():
    toy = toy_character()
    v = len(toy.neutral)
    assert toy.names == KEY_NAMES
    assert toy.targets.shape == (13, v, 3)
    assert np.isfinite(toy.neutral).all() and np.isfinite(toy.targets).all()
    assert toy.faces.dtype.kind == "i" and toy.faces.shape[1] == 3
    assert toy.faces.min() == 0 and toy.faces.max() == v - 1
    assert (np.diff(np.sort(toy.faces, axis=1), axis=1) > 0).all()  # no degenerate index triples
    p = toy.neutral[toy.faces]
    assert (np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1) > 0).all()


def test_each_key_model_moves_only_its_own_region_and_moves_it():
    toy = toy_character()
    names, part = toy_parts()
    assert names == tuple(PARTS) and part.shape == (len(toy.neutral),)
    for i, key in enumerate(KEY_NAMES):
        moved = np.linalg.norm(toy.targets[i] - toy.neutral, axis=1) > 1e-9
        allowed = np.isin(part, [names.index(p) for p in KEY_REGIONS[key]])
        assert moved.any(), key
        assert not (moved & ~allowed).any(), key
        assert np.linalg.norm(toy.targets[i] - toy.neutral, axis=1).max() < 8.0, key  # stays a face


def test_key_models_are_distinct():
    d = toy_character().deltas.reshape(13, -1)
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    cos = d @ d.T
    assert (np.abs(cos[~np.eye(13, dtype=bool)]) < 0.95).all()


def test_symmetric_neutral_and_symmetric_keys():
    toy = toy_character()
    mirror = toy.neutral * [-1, 1, 1]
    # every vertex has a mirror partner in the neutral mesh, and keys move partners symmetrically
    from scipy.spatial import cKDTree

    dist, idx = cKDTree(toy.neutral).query(mirror)
    assert dist.max() < 1e-6
    for i, key in enumerate(KEY_NAMES):
        np.testing.assert_allclose(toy.targets[i][idx] * [-1, 1, 1], toy.targets[i], atol=1e-6, err_msg=key)


def test_colours_per_vertex_and_front_view_shows_the_face():
    toy = toy_character()
    colors = toy_colors()
    assert colors.shape == toy.neutral.shape and colors.min() >= 0 and colors.max() <= 1
    img = render_mesh(toy.neutral, toy.faces, camera=Camera.fit(toy.neutral, (200, 200)), colors=colors)
    lips = np.round(np.asarray(PARTS["lips"]) * 255)
    # some lip-red pixels (shaded) appear in the lower half
    red = (img[..., 0] > 1.6 * img[..., 1]) & (img[..., 0] > 80)
    assert red[100:].sum() > 30 and lips[0] > lips[1]
