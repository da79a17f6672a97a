"""Wires on a character: a grid face whose key-models are known wire deformations, the paths file, the ICT face."""

from __future__ import annotations

import json
import logging

import numpy as np
import pytest

from facepuppet.io.character import Character
from facepuppet.synthesis import (
    FindOptions,
    WireDeformer,
    bind_points,
    find_wire_paths,
    fit_wires,
    read_wire_paths,
    reproduction_errors,
    write_wire_paths,
)

N = 41          # grid vertices per side, on [-1, 1]^2
ROW_A, ROW_B = 10, 30        # y = -0.5 and y = +0.5
COLS = range(8, 33)          # x in [-0.6, 0.6]


def grid_mesh():
    xs = np.linspace(-1.0, 1.0, N)
    x, y = np.meshgrid(xs, xs, indexing="xy")          # vertex j * N + i at (xs[i], xs[j])
    verts = np.stack([x.ravel(), y.ravel(), np.zeros(N * N)], axis=1)
    i, j = np.meshgrid(np.arange(N - 1), np.arange(N - 1), indexing="xy")
    a = (j * N + i).ravel()
    faces = np.concatenate([np.stack([a, a + 1, a + N + 1], 1), np.stack([a, a + N + 1, a + N], 1)])
    return verts, faces


def row_path(row):
    return np.array([row * N + i for i in COLS])


TRUTH = {  # key-model: per wire (A, B): (radius, scale) or None (wire not moved)
    "mouthUp": [(0.3, 1.3), None],
    "both": [(0.25, 1.0), (0.4, 0.8)],
}


def grid_character():
    verts, faces = grid_mesh()
    ra, rb = verts[row_path(ROW_A)], verts[row_path(ROW_B)]
    bump = np.cos(np.pi * ra[:, 0] / 1.4)[:, None]
    c, s = np.cos(0.2), np.sin(0.2)
    turned = (rb - rb.mean(0)) @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]).T + rb.mean(0)
    wires = {"mouthUp": [ra + bump * [0, 0, 0.2], rb], "both": [ra + [0, 0.05, 0.1], turned]}
    targets = []
    for name, params in TRUTH.items():
        act = [k for k, p in enumerate(params) if p is not None]
        d = WireDeformer(verts, [(ra, rb)[k] for k in act], [params[k][0] for k in act])
        targets.append(d.deform([wires[name][k] for k in act], [params[k][1] for k in act]))
    targets.append(verts.copy())        # a key-model that moves nothing
    return Character(neutral=verts, targets=np.stack(targets), names=(*TRUTH, "still"), faces=faces)


def test_fit_recovers_known_wire_deformations():
    ch = grid_character()
    wires = fit_wires(ch, {"A": row_path(ROW_A), "B": row_path(ROW_B)})
    assert wires.names == ("A", "B")
    for i, (name, params) in enumerate(TRUTH.items()):
        for k, p in enumerate(params):
            assert wires.active[i, k] == (p is not None), (name, k)
            if p is not None:
                assert wires.radii[i, k] == pytest.approx(p[0], abs=1e-4), (name, k)
                assert wires.scales[i, k] == pytest.approx(p[1], abs=1e-4), (name, k)
    assert not wires.active[2].any()
    np.testing.assert_array_less(wires.errors, 1e-5)
    np.testing.assert_allclose(reproduction_errors(ch, wires), wires.errors)
    np.testing.assert_allclose(wires.reproduce(0), ch.targets[0], atol=1e-5)
    np.testing.assert_array_equal(wires.wire_curves(1)[1], ch.targets[1][row_path(ROW_B)])


def test_reproduction_error_is_relative_to_the_key_models_motion():
    ch = grid_character()
    wires = fit_wires(ch, {"A": row_path(ROW_A)})          # wire B left out: "both" is half reproduced
    e = reproduction_errors(ch, wires)
    d = ch.targets[1] - ch.neutral
    near_b = np.abs(ch.neutral[:, 1] - 0.5) < 0.45
    floor = np.linalg.norm(d[near_b]) / np.linalg.norm(d)       # what wire A cannot reach
    assert e[0] < 1e-5
    assert e[1] == pytest.approx(floor, rel=0.05)


def test_found_paths_follow_the_moved_rows():
    ch = grid_character()
    paths = find_wire_paths(ch, FindOptions(n_wires=4))
    assert set(paths) == {"mouthUp", "both"}   # the still key-model places none
    verts = ch.neutral
    rows = []
    for p in paths.values():
        assert len(p) >= 2
        a, b = p[:-1], p[1:]                                    # consecutive vertices share a grid edge
        step = np.abs(verts[a] - verts[b]).max(axis=1)
        assert np.all(step < 0.051)
        rows.append(verts[p, 1].mean())
        assert np.ptp(verts[p, 0]) > 0.3 or np.ptp(verts[p, 1]) > 0.3
    # the most-moved vertices lie beside each moved row (within the wire's reach): one path per row
    rows = np.array(rows)
    assert np.abs(rows + 0.5).min() < 0.16 and np.abs(rows - 0.5).min() < 0.16


def test_paths_file_round_trip(tmp_path):
    ch = grid_character()
    paths = {"A": row_path(ROW_A), "B": row_path(ROW_B)[::-1]}
    f = tmp_path / "wires.json"
    write_wire_paths(f, paths)
    back = read_wire_paths(f, ch)
    assert list(back) == ["A", "B"]
    for k in paths:
        np.testing.assert_array_equal(back[k], paths[k])
    assert json.loads(f.read_text())["format"] == "facepuppet-wires"


@pytest.mark.parametrize("body, word", [
    ("not json", "not a JSON file"),
    ('{"paths": {}}', "'wires' field"),
    ('{"format": "other", "wires": {"a": [0, 1]}}', "format"),
    ('{"version": 2, "wires": {"a": [0, 1]}}', "version 2"),
    ('{"wires": {}}', "non-empty"),
    ('{"wires": {"a": [0]}}', "at least 2"),
    ('{"wires": {"a": [0, 1.5]}}', "integers"),
    ('{"wires": {"a": "0 1"}}', "list of vertex indices"),
    ('{"wires": {"a": [0, 99999]}}', "out of range"),
    ('{"wires": {"a": [0, 1, 0]}}', "appears twice"),
    ('{"wires": {"a": [0, 5]}}', "share no mesh edge"),
])
def test_bad_paths_file_names_file_and_problem(tmp_path, body, word):
    f = tmp_path / "bad.json"
    f.write_text(body)
    with pytest.raises(ValueError, match=word) as info:
        read_wire_paths(f, grid_character())
    assert str(f) in str(info.value) and "\n" not in str(info.value)


def test_missing_paths_file(tmp_path):
    with pytest.raises(ValueError, match="cannot read"):
        read_wire_paths(tmp_path / "none.json")


def test_ict_face_wires(ict, caplog):
    """The ICT face: 12 found wires, a few key-models fitted; their reproduction figures are logged."""
    base = ict["neutral"].astype(float)
    names = [str(n) for n in ict["expr_names"]]
    full = Character(neutral=base, targets=base[None] + ict["expr_deltas"], names=tuple(names),
                     faces=ict["faces"])
    paths = find_wire_paths(full)
    assert len(paths) == 12
    pick = [names.index(n) for n in ("jawOpen", "eyeBlink_L", "mouthSmile_L", "browInnerUp_R")]
    sub = Character(neutral=base, targets=full.targets[pick], names=tuple(names[i] for i in pick),
                    faces=ict["faces"])
    wires = fit_wires(sub, paths)
    with caplog.at_level(logging.INFO):
        logging.getLogger(__name__).info("ICT wire reproduction: %s",
                                         dict(zip(wires.key_names, np.round(wires.errors, 3), strict=True)))
    # every fitted key-model is represented better than by the neutral face (error 1) ...
    assert np.all(wires.errors < 0.8)
    # ... and its wires stay local: vertices beyond every active wire's radius do not move
    for i in range(len(pick)):
        got = wires.reproduce(i)
        reach = np.zeros(len(base), bool)
        for k in np.flatnonzero(wires.active[i]):
            reach |= bind_points(base, base[wires.paths[k]]).distance < wires.radii[i, k]
        assert (~reach).any()
        np.testing.assert_array_equal(got[~reach], base[~reach])
