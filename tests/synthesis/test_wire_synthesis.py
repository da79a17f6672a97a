"""The paper's wire-based synthesis (CharacterWires.synthesize) and edited wire curves, on the grid face."""

from __future__ import annotations

import numpy as np
import pytest
from test_character_wires import ROW_A, ROW_B, grid_character, row_path

from facepuppet import ExpressionMapper
from facepuppet.synthesis import bind_points, fit_wires


@pytest.fixture(scope="module")
def fitted():
    ch = grid_character()
    return ch, fit_wires(ch, {"A": row_path(ROW_A), "B": row_path(ROW_B)})


def test_unit_weights_reproduce_each_key_model_and_zero_is_neutral(fitted):
    ch, wires = fitted
    for i in range(len(ch.names)):
        w = np.zeros(len(ch.names))
        w[i] = 1.0
        np.testing.assert_allclose(wires.synthesize(w), wires.reproduce(i), atol=1e-12)
    np.testing.assert_allclose(wires.synthesize(np.zeros(len(ch.names))), ch.neutral, atol=1e-15)


def test_a_blend_of_one_wire_moves_it_halfway(fitted):
    """w = 0.5 e_mouthUp: wire A's curve is halfway, so points on R_A move by half the curve's offset."""
    ch, wires = fitted
    i = list(ch.names).index("mouthUp")
    w = np.zeros(len(ch.names))
    w[i] = 0.5
    out = wires.synthesize(w)
    on_curve = row_path(ROW_A)
    np.testing.assert_allclose(out[on_curve] - ch.neutral[on_curve],
                               0.5 * (wires.curves[0][i] - ch.neutral[on_curve]), atol=1e-9)
    batch = wires.synthesize(np.stack([w, 2 * w]))
    np.testing.assert_allclose(batch[0], out)


def test_edited_wire_changes_the_key_model_only_where_the_wire_reaches(fitted):
    ch, wires = fitted
    i = list(ch.names).index("both")
    k = 0                                               # wire A
    curve = wires.curves[k][i].copy()
    curve[5:10] += [0.0, 0.0, 0.3]                      # move a few control points
    edited = wires.with_curve(i, k, curve)
    before, after = wires.reproduce(i), edited.reproduce(i)
    dist = bind_points(ch.neutral, ch.neutral[row_path(ROW_A)]).distance
    far = dist >= wires.radii[i, k]
    assert np.abs(after - before)[~far].max() > 0.05
    np.testing.assert_array_equal(after[far], before[far])
    for j in range(len(ch.names)):                      # the other key-models keep their wires
        if j != i:
            np.testing.assert_array_equal(edited.reproduce(j), wires.reproduce(j))


def test_mapper_synthesizes_with_wires(fitted):
    ch, wires = fitted
    pts = ch.neutral[::97]
    S = np.stack([t[::97] for t in ch.targets[:2]] + [pts + 0.01])
    m = ExpressionMapper.fit(pts, S, ch.neutral, ch.targets)
    w = m.weights(S[0])
    np.testing.assert_allclose(m.synthesize(w, wires=wires), wires.synthesize(w))


def test_regions_from_the_wires_influence(fitted):
    ch, wires = fitted
    masks, names = wires.regions()
    assert names == ("background", "A", "B")
    np.testing.assert_allclose(masks.sum(0), 1.0, atol=1e-12)
    row_a, row_b = row_path(ROW_A), row_path(ROW_B)
    np.testing.assert_allclose(masks[1, row_a], 1.0)          # on its reference curve a wire's mask is 1
    np.testing.assert_allclose(masks[2, row_b], 1.0)
    far = bind_points(ch.neutral, ch.neutral[row_a]).distance >= wires.radii[:, 0].max()
    assert (masks[1, far] == 0).all()
    pts = np.r_[row_a[::6], row_b[::6]]
    m = ExpressionMapper.fit(ch.neutral[pts], ch.targets[:2, pts], ch.neutral, ch.targets[:2], method="regional",
                             regions=masks, region_names=names)
    assert m.region_names == names
    for i in range(2):
        np.testing.assert_allclose(m.synthesize(m.weights(ch.targets[i, pts])), ch.targets[i], atol=1e-9)
