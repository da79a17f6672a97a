"""The per-frame stream: its mapper equals the batch chain, the neutral re-zero, outputs all or none, times."""

from __future__ import annotations

import contextlib
import csv

import numpy as np
import pytest
from test_animate import LinearMapper, StubRig

from facepuppet.capture.curves import CURVE_NAMES, POINT_NAMES
from facepuppet.capture.features import FrameFeatures
from facepuppet.errors import FacepuppetError
from facepuppet.io.character import Character
from facepuppet.pipeline.gain import GainConfig, apply_gain, parse_gain
from facepuppet.pipeline.outputs import CsvOutput, GlbOutput
from facepuppet.pipeline.smoothing import SmoothingConfig, smooth
from facepuppet.pipeline.stream import FrameMapper, SourceFrame, run_stream

P = len(POINT_NAMES)
FRONTAL = np.diag([1.0, -1.0, -1.0])


def features(points, valid=True):
    if not valid:
        return FrameFeatures.lost(len(CURVE_NAMES), P)
    return FrameFeatures(True, np.zeros((len(CURVE_NAMES), 4, 2)), FRONTAL, np.zeros(3), points)


@pytest.fixture
def setup(rng):
    neutral = rng.normal(size=(P, 3))
    q, _ = np.linalg.qr(rng.normal(size=(P * 3, 2)))
    basis = q.T.reshape(2, P, 3)
    w = np.stack([np.linspace(0, 1, 40), 0.5 + 0.45 * np.sin(np.arange(40) / 4)], axis=1)
    points = neutral + np.einsum("fm,mpd->fpd", w, basis)
    rig = StubRig(LinearMapper(neutral, basis), ["jawOpen", "mouthSmile"])
    rig.mapper.source_base = neutral
    return rig, points, w


def test_per_frame_chain_equals_the_batch_chain(setup):
    rig, points, w = setup
    valid = np.ones(40, bool)
    valid[10:18] = False                                       # a lost face: hold, then ease
    gain = parse_gain(["1.3", "mouthSmile=0.6"])
    m = FrameMapper(rig, smoothing=SmoothingConfig(), gain=gain)
    got = np.array([m.step(features(points[k], valid[k]), k / 30.0)[1] for k in range(40)])
    raw = np.where(valid[:, None], w, np.nan)
    want = apply_gain(smooth(raw, 30.0, valid=valid), gain, rig.names)
    np.testing.assert_allclose(got, want, atol=1e-12)
    assert got[12].tolist() == pytest.approx(want[12].tolist())   # held through the gap
    assert (got <= 1.3 + 1e-12).all() and (got >= 0).all()


def test_rezero_takes_the_current_face_as_neutral(setup):
    rig, points, w = setup
    m = FrameMapper(rig, smoothing=SmoothingConfig(enabled=False), gain=GainConfig(low=None, high=None))
    assert m.rezero(features(points[20]))
    raw, _, _ = m.step(features(points[20]), 0.0)
    np.testing.assert_allclose(raw, 0.0, atol=1e-12)           # the face of that moment is neutral
    raw, _, _ = m.step(features(points[30]), 1 / 30)
    np.testing.assert_allclose(raw, w[30] - w[20], atol=1e-12)   # later faces measured from it (linear mapper)
    assert not m.rezero(features(None, valid=False))            # no face: nothing changes
    m.clear_rezero()
    np.testing.assert_allclose(m.step(features(points[30]), 2 / 30)[0], w[30], atol=1e-12)


def test_request_rezero_waits_for_a_face(setup):
    rig, points, _ = setup
    m = FrameMapper(rig, smoothing=SmoothingConfig(enabled=False))
    m.request_rezero()
    assert np.isnan(m.step(features(None, valid=False), 0.0)[0]).all()
    np.testing.assert_allclose(m.step(features(points[5]), 0.1)[0], 0.0, atol=1e-12)


def test_lost_frames_keep_the_last_head_rotation(setup):
    rig, points, _ = setup
    m = FrameMapper(rig)
    np.testing.assert_array_equal(m.step(features(None, valid=False), 0.0)[2], np.eye(3))   # rest before first
    turn = np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]])
    f = FrameFeatures(True, np.zeros((len(CURVE_NAMES), 4, 2)), FRONTAL @ turn, np.zeros(3), points[0])
    np.testing.assert_allclose(m.step(f, 0.1)[2], turn, atol=1e-12)
    np.testing.assert_allclose(m.step(features(None, valid=False), 0.2)[2], turn, atol=1e-12)


class _CharRig(StubRig):
    """A rig with a character whose key-models are the two paired names plus one the rig does not drive."""

    def __init__(self, mapper, names):
        super().__init__(mapper, names)
        v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
        self.character = Character(v, v[None] + np.arange(1, 4)[:, None, None] * 0.1,
                                   ("jawOpen", "other", "mouthSmile"), np.array([[0, 1, 2]]), name="tri")
        self.target_indices = np.array([0, 2])

    def character_weights(self, weights):
        out = np.zeros(np.shape(weights)[:-1] + (3,))
        out[..., self.target_indices] = weights
        return out


class _Fails:
    def write(self, frame):
        pass

    def finish(self):
        raise FacepuppetError("disk full")


def test_outputs_appear_together_or_not_at_all(setup, tmp_path):
    rig, points, _ = setup
    rig = _CharRig(rig.mapper, rig.names)
    frames = [SourceFrame(k, k / 30, None, 0.0, features(points[k])) for k in range(5)]
    with pytest.raises(FacepuppetError, match="disk full"):
        with contextlib.ExitStack() as stack:
            outs = [GlbOutput(tmp_path / "a.glb", rig, stack), CsvOutput(tmp_path / "a.csv", rig, stack), _Fails()]
            run_stream(frames, None, FrameMapper(rig), outs)
    assert list(tmp_path.iterdir()) == []                      # no output, no temporary file
    with contextlib.ExitStack() as stack:
        outs = [GlbOutput(tmp_path / "a.glb", rig, stack), CsvOutput(tmp_path / "a.csv", rig, stack)]
        summary = run_stream(frames, None, FrameMapper(rig), outs)
    assert summary.frames == 5 and summary.with_face == 5
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.csv", "a.glb"]


def test_dropped_frames_keep_their_own_times(setup, tmp_path):
    from pygltflib import GLTF2

    rig, points, _ = setup
    rig = _CharRig(rig.mapper, rig.names)
    kept = [0, 1, 3, 4, 7, 12]                                 # a live take whose stream dropped 2, 5, 6, 8-11
    frames = [SourceFrame(k, k / 30, None, 0.0, features(points[k])) for k in kept]
    with contextlib.ExitStack() as stack:
        outs = [GlbOutput(tmp_path / "a.glb", rig, stack, fps=30), CsvOutput(tmp_path / "a.csv", rig, stack, fps=30)]
        run_stream(frames, None, FrameMapper(rig), outs)
    with open(tmp_path / "a.csv", newline="") as fh:
        rows = list(csv.reader(fh))
    def seconds(timecode):                                     # HH:MM:SS:FF.mmm, FF.mmm in 60ths of a second
        hh, mm, ss, ff = timecode.split(":")
        return 3600 * int(hh) + 60 * int(mm) + int(ss) + float(ff) / 60

    assert [seconds(r[0]) for r in rows[1:]] == pytest.approx([k / 30 for k in kept], abs=1e-4)
    g = GLTF2().load(str(tmp_path / "a.glb"))
    acc = g.accessors[g.animations[0].samplers[0].input]
    view = g.bufferViews[acc.bufferView]
    blob = g.binary_blob()
    t = np.frombuffer(blob, np.float32, acc.count, view.byteOffset + (acc.byteOffset or 0))
    np.testing.assert_allclose(t, np.array(kept) / 30, rtol=1e-6)


def test_rig_of_other_points_is_refused_before_the_first_frame(setup):
    rig, points, _ = setup
    with pytest.raises(FacepuppetError, match="other feature points"):
        run_stream([], None, FrameMapper(rig), [], point_names=POINT_NAMES[:-1])
