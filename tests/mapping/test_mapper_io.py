"""Saving and loading a mapper: round trips, and clear errors for every kind of bad file."""

from __future__ import annotations

import zipfile

import numpy as np
import pytest

from facepuppet import ExpressionMapper, FacepuppetError
from facepuppet.mapping import FORMAT_VERSION, METHODS


@pytest.fixture
def pair(rng):
    sb = rng.normal(size=(15, 3))
    se = sb[None] + rng.normal(scale=0.3, size=(5, 15, 3))
    tb = rng.normal(size=(40, 3))
    te = tb[None] + rng.normal(scale=0.5, size=(5, 40, 3))
    return sb, se, tb, te


def frames(pair, rng):
    return pair[0] + rng.normal(scale=0.3, size=(30,) + pair[0].shape)


@pytest.mark.parametrize("method", sorted(METHODS))
def test_save_load_round_trip(method, pair, rng, tmp_path):
    m = ExpressionMapper.fit(*pair, method=method, names=list("abcde"))
    path = tmp_path / "map.npz"
    m.save(path)
    back = ExpressionMapper.load(path)
    x = frames(pair, rng)
    assert np.array_equal(back.weights(x), m.weights(x))
    assert np.array_equal(back.synthesize(m.weights(x)), m.synthesize(m.weights(x)))
    assert back.method == method and back.names == tuple("abcde") and back.options == m.options
    assert [p.name for p in tmp_path.iterdir()] == ["map.npz"]  # no temporary left behind


def test_any_suffix_is_kept(pair, tmp_path):
    m = ExpressionMapper.fit(*pair)
    m.save(tmp_path / "rig.map")
    assert [p.name for p in tmp_path.iterdir()] == ["rig.map"]
    assert ExpressionMapper.load(tmp_path / "rig.map").n_examples == 5


def test_to_arrays_from_arrays(pair, rng):
    m = ExpressionMapper.fit(*pair)
    arrays = m.to_arrays()
    assert all(isinstance(v, np.ndarray) and v.dtype != object for v in arrays.values())
    prefixed = {f"mapper/{k}": v for k, v in arrays.items()}  # as another file would embed them
    back = ExpressionMapper.from_arrays({k.split("/", 1)[1]: v for k, v in prefixed.items()})
    x = frames(pair, rng)
    assert np.array_equal(back.weights(x), m.weights(x))
    assert back.names is None


def test_loads_without_pickle(pair, tmp_path):
    path = tmp_path / "m.npz"
    ExpressionMapper.fit(*pair).save(path)
    with np.load(path, allow_pickle=False) as d:
        assert int(d["version"]) == FORMAT_VERSION


def _rewrite(path, **changes):
    with np.load(path, allow_pickle=False) as d:
        arrays = {k: d[k] for k in d.files}
    for k, v in changes.items():
        if v is None:
            arrays.pop(k)
        else:
            arrays[k] = v
    np.savez(path, **arrays)


def test_bad_files_name_the_file(pair, tmp_path):
    good = tmp_path / "good.npz"
    ExpressionMapper.fit(*pair).save(good)
    raw = good.read_bytes()

    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(raw[: len(raw) // 2])
    garbage = tmp_path / "garbage.npz"
    garbage.write_bytes(b"not a zip file at all")
    empty = tmp_path / "empty.npz"
    empty.write_bytes(b"")
    other = tmp_path / "other.npz"
    np.savez(other, points=np.zeros((3, 3)))
    future = tmp_path / "future.npz"
    future.write_bytes(raw)
    _rewrite(future, version=np.array(FORMAT_VERSION + 1))
    wrong_kind = tmp_path / "kind.npz"
    wrong_kind.write_bytes(raw)
    _rewrite(wrong_kind, format=np.array("facepuppet.Track"))
    damaged = tmp_path / "damaged.npz"
    damaged.write_bytes(raw)
    _rewrite(damaged, solver_F=None)
    shapes = tmp_path / "shapes.npz"
    shapes.write_bytes(raw)
    _rewrite(shapes, target_deltas=np.zeros((2, 40, 3)))
    pickled = tmp_path / "pickled.npz"
    np.savez(pickled, format=np.array([{"a": 1}], dtype=object))

    cases = {
        truncated: "cannot read mapper file", garbage: "cannot read mapper file",
        empty: "cannot read mapper file", other: "not an ExpressionMapper",
        future: "newer facepuppet", wrong_kind: "not an ExpressionMapper", damaged: "damaged",
        shapes: "inconsistent shapes", pickled: "cannot read mapper file",
        tmp_path / "missing.npz": "no such file",
    }
    for path, match in cases.items():
        with pytest.raises(FacepuppetError, match=match) as info:
            ExpressionMapper.load(path)
        assert str(path) in str(info.value)
        assert "\n" not in str(info.value)


def test_failed_save_leaves_no_file(pair, tmp_path, monkeypatch):
    m = ExpressionMapper.fit(*pair)

    def boom(*a, **k):
        raise zipfile.BadZipFile("disk full")

    monkeypatch.setattr(np, "savez", boom)
    with pytest.raises(zipfile.BadZipFile):
        m.save(tmp_path / "m.npz")
    assert list(tmp_path.iterdir()) == []


def test_a_file_from_before_the_noise_ridge_loads_as_the_same_mapping(pair, rng):
    m = ExpressionMapper.fit(*pair, method="bounded")
    arrays = {k: v for k, v in m.to_arrays().items() if k != "solver_noise_ridge"}
    back = ExpressionMapper.from_arrays(arrays)
    x = frames(pair, rng)
    assert np.array_equal(back.weights(x), m.weights(x))
