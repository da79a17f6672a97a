"""The performer's key expressions file: round trip, validation, and clear errors for bad files."""

from __future__ import annotations

import numpy as np
import pytest

from facepuppet.errors import FacepuppetError
from facepuppet.io.performer import PERFORMER_FORMAT, Performer, load_performer, save_performer


def make_performer(rng, m=3, p=5, d=3, point_names=True) -> Performer:
    neutral = rng.normal(size=(p, d))
    return Performer(neutral, neutral[None] + rng.normal(size=(m, p, d)) * 0.1,
                     tuple(f"expr{i}" for i in range(m)),
                     tuple(f"pt{i}" for i in range(p)) if point_names else None)


@pytest.mark.parametrize("d,point_names", [(3, True), (2, False)])
def test_round_trip(tmp_path, rng, d, point_names):
    perf = make_performer(rng, d=d, point_names=point_names)
    save_performer(tmp_path / "ex.npz", perf)
    back = load_performer(tmp_path / "ex.npz")
    np.testing.assert_array_equal(back.neutral, perf.neutral)
    np.testing.assert_array_equal(back.examples, perf.examples)
    assert back.names == perf.names and back.point_names == perf.point_names
    assert back.noise is None
    with np.load(tmp_path / "ex.npz", allow_pickle=False) as raw:
        assert str(raw["format"]) == PERFORMER_FORMAT and int(raw["version"]) == 1


def test_round_trip_with_noise(tmp_path, rng):
    perf = make_performer(rng)
    perf = Performer(perf.neutral, perf.examples, perf.names, perf.point_names, rng.uniform(0.1, 1, (5, 3)))
    save_performer(tmp_path / "ex.npz", perf)
    np.testing.assert_array_equal(load_performer(tmp_path / "ex.npz").noise, perf.noise)
    assert load_performer(tmp_path / "ex.npz").nuisance is None


def test_round_trip_with_nuisance_and_the_rig_discounts_it(tmp_path, rng):
    from facepuppet.io.character import Character
    from facepuppet.pipeline.rig import fit_rig

    perf = make_performer(rng)
    nuisance = perf.neutral[None] + rng.normal(scale=0.05, size=(12, 5, 3))
    perf = Performer(perf.neutral, perf.examples, perf.names, perf.point_names, nuisance=nuisance)
    save_performer(tmp_path / "ex.npz", perf)
    back = load_performer(tmp_path / "ex.npz")
    np.testing.assert_array_equal(back.nuisance, nuisance)
    base = rng.normal(size=(8, 3))
    character = Character(base, base[None] + rng.normal(size=(3, 8, 3)), perf.names,
                          np.array([[0, 1, 2]], dtype=np.int64), name="c")
    assert fit_rig(back, character)[0].mapper.whiten is not None
    plain = Performer(perf.neutral, perf.examples, perf.names, perf.point_names)
    assert fit_rig(plain, character)[0].mapper.whiten is None


@pytest.mark.parametrize("change,match", [
    (dict(neutral=np.zeros((5, 4))), r"neutral must have shape \(P, 2\) or \(P, 3\)"),
    (dict(examples=np.zeros((3, 4, 3))), r"examples must have shape \(M, 5, 3\)"),
    (dict(examples=np.zeros((0, 5, 3)), names=()), "M >= 1"),
    (dict(names=("a", "b")), "names must hold 3 names"),
    (dict(names=("a", "b", "a")), "repeated: a"),
    (dict(names=("a", "", "c")), "non-empty"),
    (dict(point_names=("x",)), "point_names must hold 5"),
    (dict(neutral=np.full((5, 3), np.nan)), "finite"),
    (dict(noise=np.ones((5, 2))), r"noise must hold positive finite numbers with shape \(5, 3\)"),
    (dict(noise=np.zeros((5, 3))), "noise must hold positive"),
    (dict(nuisance=np.zeros((5, 3))), r"nuisance must hold finite numbers with shape \(K, 5, 3\)"),
    (dict(nuisance=np.full((2, 5, 3), np.inf)), "nuisance must hold finite numbers"),
])
def test_validation(rng, change, match):
    perf = make_performer(rng)
    fields = dict(neutral=perf.neutral, examples=perf.examples, names=perf.names, point_names=perf.point_names)
    fields.update(change)
    with pytest.raises(ValueError, match=match):
        Performer(**fields)


def _write(path, **arrays):
    np.savez(path, **arrays)
    return path


def test_bad_files(tmp_path, rng):
    perf = make_performer(rng)
    good = dict(format=PERFORMER_FORMAT, version=1, neutral=perf.neutral, examples=perf.examples,
                names=np.array(perf.names))
    with pytest.raises(FacepuppetError, match="no such file"):
        load_performer(tmp_path / "missing.npz")
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(FacepuppetError, match="junk.npz: cannot read"):
        load_performer(tmp_path / "junk.npz")
    with pytest.raises(FacepuppetError, match="not a facepuppet key expressions file"):
        load_performer(_write(tmp_path / "track.npz", fps=30.0))
    with pytest.raises(FacepuppetError, match="version 2 is newer"):
        load_performer(_write(tmp_path / "v2.npz", **{**good, "version": 2}))
    with pytest.raises(FacepuppetError, match="no valid version"):
        load_performer(_write(tmp_path / "nov.npz", **{k: v for k, v in good.items() if k != "version"}))
    with pytest.raises(FacepuppetError, match="lacks examples"):
        load_performer(_write(tmp_path / "part.npz", **{k: v for k, v in good.items() if k != "examples"}))
    with pytest.raises(FacepuppetError, match="invalid key expressions file"):
        load_performer(_write(tmp_path / "shape.npz", **{**good, "examples": perf.examples[:, :2]}))
    save_performer(tmp_path / "ok.npz", perf)
    data = (tmp_path / "ok.npz").read_bytes()
    (tmp_path / "cut.npz").write_bytes(data[: len(data) // 2])
    with pytest.raises(FacepuppetError, match="cut.npz"):
        load_performer(tmp_path / "cut.npz")
