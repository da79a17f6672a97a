import numpy as np
import pytest

from facepuppet.capture.curves import CURVE_NAMES, POINT_NAMES
from facepuppet.errors import FacepuppetError
from facepuppet.io.track import TRACK_KEYS, Track, load_track, save_track


def make_track(rng, frames=5):
    valid = np.ones(frames, bool)
    valid[2] = False
    curves = rng.normal(size=(frames, len(CURVE_NAMES), 4, 2)) * 100
    points = rng.normal(size=(frames, len(POINT_NAMES), 3))
    rot = np.repeat(np.eye(3)[None], frames, 0)
    trans = rng.normal(size=(frames, 3))
    curves[~valid] = np.nan
    points[~valid] = np.nan
    return Track(fps=30.0, frame_size=np.array([640, 480]), valid=valid, curves=curves, curve_names=CURVE_NAMES,
                 points=points, point_names=POINT_NAMES, rotation=rot, translation=trans, backend="test",
                 extras={"blendshapes": rng.random((frames, 52))})


def test_round_trip_keeps_every_key(tmp_path, rng):
    tr = make_track(rng)
    path = tmp_path / "t.npz"
    save_track(path, tr)
    with np.load(path, allow_pickle=False) as raw:
        assert set(TRACK_KEYS) <= set(raw.files)
        assert raw["curves"].shape == (5, len(CURVE_NAMES), 4, 2)
        assert raw["valid"].dtype == bool
    back = load_track(path)
    assert back.curve_names == CURVE_NAMES and back.point_names == POINT_NAMES
    np.testing.assert_allclose(back.curves, tr.curves, rtol=1e-6, equal_nan=True)
    np.testing.assert_allclose(back.points, tr.points, rtol=1e-6, equal_nan=True)
    np.testing.assert_array_equal(back.valid, tr.valid)
    np.testing.assert_allclose(back.extras["blendshapes"], tr.extras["blendshapes"])
    assert back.fps == 30.0 and back.backend == "test" and list(back.frame_size) == [640, 480]
    assert not list(tmp_path.glob(".t.npz*")), "temporary file left behind"


def test_shape_mismatch_is_named(rng):
    tr = make_track(rng)
    with pytest.raises(ValueError, match="track points"):
        Track(**{**tr.__dict__, "points": tr.points[:, :3]})


def test_bad_files_give_clear_errors(tmp_path, rng):
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip")
    with pytest.raises(FacepuppetError, match="bad.npz"):
        load_track(bad)
    other = tmp_path / "other.npz"
    np.savez(other, x=np.zeros(3))
    with pytest.raises(FacepuppetError, match="not a track file"):
        load_track(other)
    good = tmp_path / "good.npz"
    save_track(good, make_track(rng))
    cut = tmp_path / "cut.npz"
    cut.write_bytes(good.read_bytes()[:200])
    with pytest.raises(FacepuppetError, match="cut.npz"):
        load_track(cut)
