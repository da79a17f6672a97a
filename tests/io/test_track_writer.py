"""TrackWriter: the streamed file equals save_track's, frame for frame; per-frame times only when they differ."""

import numpy as np
import pytest

from facepuppet.io.track import Track, load_track, save_track
from facepuppet.io.track_writer import TrackWriter


class Frame:
    def __init__(self, valid, curves, rotation, translation, points, extras=None):
        self.valid, self.curves, self.rotation = valid, curves, rotation
        self.translation, self.points, self.extras = translation, points, extras


def _frames(n, rng):
    out = []
    for i in range(n):
        valid = i % 3 != 1
        extras = {"blendshapes": rng.random(4).astype(np.float32)} if i >= 2 else None
        out.append(Frame(valid, rng.normal(size=(2, 4, 2)), np.eye(3), rng.normal(size=3), rng.normal(size=(3, 3)),
                         extras))
    return out


def test_streamed_track_equals_the_saved_one(tmp_path, rng):
    frames = _frames(7, rng)
    with TrackWriter(tmp_path / "s.npz", fps=25.0, frame_size=(64, 48), curve_names=("a", "b"),
                     point_names=("p", "q", "r"), backend="color",
                     media={"size": 10, "frames": 7, "hash": "blake2b:00"}) as w:
        for f in frames:
            w.add(f)
        w.finish()
    got = load_track(tmp_path / "s.npz")
    valid = np.array([f.valid for f in frames])
    nan = np.where(valid[:, None, None], 1.0, np.nan)
    assert got.n_frames == 7 and got.fps == 25.0 and got.times is None
    np.testing.assert_array_equal(got.valid, valid)
    np.testing.assert_allclose(got.curves, np.stack([f.curves for f in frames]).astype(np.float32)
                               * nan[..., None], rtol=0)
    np.testing.assert_allclose(got.points, np.stack([f.points for f in frames]).astype(np.float32) * nan, rtol=0)
    blend = got.extras["blendshapes"]
    assert np.isnan(blend[:2]).all()
    np.testing.assert_array_equal(blend[2:], np.stack([f.extras["blendshapes"] for f in frames[2:]]))
    assert got.media == {"size": 10, "frames": 7, "hash": "blake2b:00"}
    # the same content written whole loads the same
    save_track(tmp_path / "w.npz", got)
    again = load_track(tmp_path / "w.npz")
    np.testing.assert_array_equal(again.points, got.points)


def test_variable_frame_times_are_kept(tmp_path, rng):
    frames = _frames(4, rng)
    times = [0.0, 0.04, 0.5, 0.54]
    with TrackWriter(tmp_path / "v.npz", fps=25.0, frame_size=(64, 48), curve_names=("a", "b"),
                     point_names=("p", "q", "r"), backend="color") as w:
        for f, t in zip(frames, times, strict=True):
            w.add(f, t)
        w.finish()
    np.testing.assert_array_equal(load_track(tmp_path / "v.npz").times, times)


def test_nothing_appears_without_finish(tmp_path, rng):
    with pytest.raises(RuntimeError):
        with TrackWriter(tmp_path / "x.npz", fps=25.0, frame_size=(64, 48), curve_names=("a", "b"),
                         point_names=("p", "q", "r"), backend="color") as w:
            w.add(_frames(1, rng)[0])
            raise RuntimeError("stop")
    assert list(tmp_path.iterdir()) == []


def test_track_times_must_increase():
    with pytest.raises(ValueError, match="increasing"):
        Track(fps=30.0, frame_size=np.array([4, 4]), valid=np.ones(2, bool), curves=np.zeros((2, 1, 4, 2)),
              curve_names=("a",), points=np.zeros((2, 1, 3)), point_names=("p",),
              rotation=np.zeros((2, 3, 3)), translation=np.zeros((2, 3)), backend="x", times=np.array([1.0, 0.5]))
