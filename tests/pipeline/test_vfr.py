"""Variable frame rate: frame times come from the container's timestamps, through the stream into the CSV.

OpenCV writes only constant-rate MP4s, so the clip is made honestly in two steps: OpenCV writes 20 frames at
30 fps, then the MP4's time-to-sample table (``moov/trak/mdia/minf/stbl/stts``) is rewritten so the first 10
frames last 1/120 s and the last 10 last 7/120 s (the total duration is unchanged, so no other box changes).
"""

import csv
import struct
from dataclasses import replace

import numpy as np
import pytest

#: The clip's frames: (count, duration in 1/120 s).
RUNS = ((10, 1), (10, 7))


def _boxes(data, start, end):
    i = start
    while i + 8 <= end:
        size, kind = struct.unpack(">I4s", data[i:i + 8])
        if size < 8:
            return
        yield i, size, kind.decode("latin-1")
        i += size


def _find(data, path, start=0, end=None, chain=()):
    end = len(data) if end is None else end
    for off, size, kind in _boxes(data, start, end):
        if kind == path[0]:
            chain = (*chain, (off, size))
            return chain if len(path) == 1 else _find(data, path[1:], off + 8, off + size, chain)
    raise KeyError(path[0])


@pytest.fixture(scope="module")
def vfr_clip(tmp_path_factory):
    import cv2

    path = tmp_path_factory.mktemp("vfr") / "vfr.mp4"
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, (64, 64))
    for i in range(20):
        w.write(np.full((64, 64, 3), 10 * i, np.uint8))
    w.release()
    data = bytearray(path.read_bytes())
    chain = _find(data, ["moov", "trak", "mdia", "minf", "stbl", "stts"])
    off, size = chain[-1]
    flags, n = struct.unpack(">II", data[off + 8:off + 16])
    (count, delta), = [struct.unpack(">II", data[off + 16:off + 24])] if n == 1 else pytest.skip("stts layout")
    assert count == 20 and delta % 4 == 0        # one entry: 20 frames of 1/30 s (delta ticks)
    tick = delta // 4                               # 1/120 s
    body = struct.pack(">II", flags, len(RUNS)) + b"".join(struct.pack(">II", c, d * tick) for c, d in RUNS)
    new = struct.pack(">I4s", 8 + len(body), b"stts") + body
    for o, s in chain[:-1]:
        struct.pack_into(">I", data, o, s + len(new) - size)
    data[off:off + size] = new
    path.write_bytes(bytes(data))
    times = np.concatenate([[0.0], np.cumsum(np.repeat([d for _, d in RUNS], [c for c, _ in RUNS]))[:-1]]) / 120
    return path, times


def test_source_frames_follow_the_container(vfr_clip):
    from facepuppet.io.frames import open_media
    from facepuppet.pipeline.stream import source_frames

    path, truth = vfr_clip
    with open_media(path) as src:
        got = np.array([f.time for f in source_frames(src)])
    assert len(got) == 20
    nominal = np.arange(20) / 30.0
    far = np.abs(truth - nominal) >= 0.5 / 30        # frames a constant rate would misplace
    assert far.sum() >= 15
    np.testing.assert_allclose(got[far], truth[far], atol=1e-3)
    np.testing.assert_allclose(got[~far], truth[~far], atol=0.5 / 30)
    assert np.all(np.diff(got) > 0)


def test_constant_rate_video_keeps_index_over_fps(tmp_path):
    import cv2

    from facepuppet.io.frames import open_media
    from facepuppet.pipeline.stream import source_frames

    path = tmp_path / "cfr.mp4"
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 25.0, (32, 32))
    for i in range(8):
        w.write(np.full((32, 32, 3), 20 * i, np.uint8))
    w.release()
    with open_media(path) as src:
        assert [f.time for f in source_frames(src)] == [i / 25.0 for i in range(8)]


def _timecode_seconds(text):
    h, m, s, ff = text.split(":")
    return 3600 * int(h) + 60 * int(m) + int(s) + float(ff) / 60.0


def test_track_times_reach_the_csv(tmp_path, rng):
    """A track with per-frame times (as `track` writes for a VFR clip) keys the CSV at those times."""
    from facepuppet.capture import CURVE_NAMES, POINT_NAMES
    from facepuppet.demo.toy import toy_character
    from facepuppet.io.performer import Performer
    from facepuppet.io.track import Track
    from facepuppet.pipeline.animate import animate
    from facepuppet.pipeline.rig import fit_rig

    toy = toy_character()
    p = len(POINT_NAMES)
    neutral = rng.normal(0, 3, (p, 3))
    performer = Performer(neutral, neutral[None] + rng.normal(0, 0.5, (len(toy.names), p, 3)), tuple(toy.names),
                          tuple(POINT_NAMES))
    rig, _ = fit_rig(performer, toy)
    n = 12
    times = np.array([0.0, 0.01, 0.02, 0.5, 0.6, 0.61, 1.0, 1.5, 1.51, 1.52, 2.0, 3.0])
    track = Track(fps=30.0, frame_size=np.array([64, 64]), valid=np.ones(n, bool),
                  curves=np.zeros((n, len(CURVE_NAMES), 4, 2)), curve_names=tuple(CURVE_NAMES),
                  points=np.repeat(neutral[None], n, axis=0), point_names=tuple(POINT_NAMES),
                  rotation=np.tile(np.eye(3), (n, 1, 1)), translation=np.zeros((n, 3)), backend="color")
    animate(None, rig, csv=tmp_path / "w.csv", track=replace(track, times=times), keep_track=False)
    with open(tmp_path / "w.csv", newline="") as f:
        rows = list(csv.reader(f))[1:]
    got = np.array([_timecode_seconds(r[0]) for r in rows])
    np.testing.assert_allclose(got, times, atol=1e-3)
