"""Calibration: marks files, steady windows, examples from synthetic tracks with known answers, --auto, checks."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from facepuppet.capture.curves import CURVE_NAMES, POINT_NAMES
from facepuppet.errors import FacepuppetError
from facepuppet.io.track import Track
from facepuppet.pipeline.calibrate import (
    HEAD_MOTION,
    MIN_HEAD_MOTION_FRAMES,
    CalibrateConfig,
    Mark,
    calibrate_auto,
    check_examples,
    coordinate_noise,
    examples_from_marks,
    parse_when,
    read_marks,
    steadiest_window,
)

FPS = 30.0
P = len(POINT_NAMES)


def make_track(points: np.ndarray, valid: np.ndarray | None = None, extras: dict | None = None) -> Track:
    f = len(points)
    valid = np.ones(f, bool) if valid is None else valid
    points = np.where(valid[:, None, None], points, np.nan)
    return Track(fps=FPS, frame_size=np.array([64, 64]), valid=valid,
                 curves=np.zeros((f, len(CURVE_NAMES), 4, 2)), curve_names=CURVE_NAMES, points=points,
                 point_names=POINT_NAMES, rotation=np.tile(np.eye(3), (f, 1, 1)), translation=np.zeros((f, 3)),
                 backend="test", extras=extras)


@pytest.mark.parametrize("text, frame", [("45", 45), ("1.5s", 45), ("00:01.5", 45), ("0:00:02", 60),
                                         (" 2S ", 60), ("0", 0)])
def test_parse_when(text, frame):
    assert parse_when(text, FPS) == frame


@pytest.mark.parametrize("text", ["1.5", "-3", "abc", "1:2:3:4", ""])
def test_parse_when_refuses_ambiguous(text):
    with pytest.raises(ValueError, match="1.5s"):
        parse_when(text, FPS)


def write(tmp_path, text):
    p = tmp_path / "marks.csv"
    p.write_text(text)
    return p


def test_read_marks(tmp_path):
    p = write(tmp_path, "time,name\n# a comment\n\n0.5s,neutral\n00:02.0,jawOpen\n95,mouthSmile\n")
    marks = read_marks(p, FPS, 200, names=["jawOpen", "mouthSmile"])
    assert [(m.frame, m.name) for m in marks] == [(15, "neutral"), (60, "jawOpen"), (95, "mouthSmile")]


def test_read_marks_with_head_motion_spans(tmp_path):
    p = write(tmp_path, "0.5s,neutral\n60,jawOpen\n3s-4.5s,head-motion\n150-200,head-motion\n")
    marks = read_marks(p, FPS, 200, names=["jawOpen"])
    assert [(m.frame, m.stop, m.name) for m in marks] == [(15, None, "neutral"), (60, None, "jawOpen"),
                                                          (90, 135, HEAD_MOTION), (150, 200, HEAD_MOTION)]


@pytest.mark.parametrize("text, match", [
    ("0,neutral\n5,jawOpen\n50-40,head-motion\n", r"line 3: the span 50-40 ends before it starts"),
    ("0,neutral\n5,jawOpen\n50,head-motion\n", r"line 3: head-motion marks a span: write START-END"),
    ("0,neutral\n5-9,jawOpen\n", r"line 2: only head-motion marks a span .START-END.; 'jawOpen' marks one"),
    ("0,neutral\n5,jawOpen\n1s-5s,head-motion\n", r"line 3: 1s-5s \(head-motion\) is past the end"),
    ("0,neutral\n1-2s,head-motion\n", "at least one key expression"),
    ("0,neutral\n5,jawOpen\n10-x,head-motion\n", r"line 3: 'x' is not a time"),
])
def test_bad_head_motion_spans_named(tmp_path, text, match):
    with pytest.raises(ValueError, match=match):
        read_marks(write(tmp_path, text), FPS, 100, names=["jawOpen"])


def test_head_motion_frames_become_the_nuisance(rng):
    neutral = rng.normal(size=(P, 3))
    smile = rng.normal(size=(P, 3))
    f = 80
    points = np.repeat(neutral[None], f, axis=0)
    points[20:30] = neutral + smile
    points[40:70] += 0.1 * rng.normal(size=(30, P, 3))        # the head moving under a neutral face
    valid = np.ones(f, bool)
    valid[50] = False                                           # a lost frame in the span is left out
    track = make_track(points, valid)
    marks = [Mark(5, "neutral", 1, "5"), Mark(25, "mouthSmile", 2, "25"), Mark(40, HEAD_MOTION, 3, "40-60", 60),
             Mark(60, HEAD_MOTION, 4, "60-70", 70)]
    result = examples_from_marks(track, marks, CalibrateConfig(window=4))
    assert result.names == ("mouthSmile",)
    np.testing.assert_allclose(result.nuisance, np.delete(points[40:70], 10, axis=0))
    assert examples_from_marks(track, marks[:2], CalibrateConfig(window=4)).nuisance is None
    short = [*marks[:2], Mark(40, HEAD_MOTION, 3, "40-45", 40 + MIN_HEAD_MOTION_FRAMES - 1)]
    with pytest.raises(FacepuppetError, match=r"head-motion 40-45 \(line 3\): only 9 frames with a face"):
        examples_from_marks(track, short, CalibrateConfig(window=4))


@pytest.mark.parametrize("text, match", [
    ("0,neutral\n10,jawOpn\n", r"line 2: the character has no key-model named 'jawOpn'"),
    ("0,neutral\n10s,jawOpen\n", r"line 2: 10s \(jawOpen\) is past the end"),
    ("5,jawOpen\n", "no mark names the neutral"),
    ("0,neutral\n", "at least one key expression"),
    ("0,neutral\n5,jawOpen\n7,jawOpen\n", "marked twice"),
    ("0,neutral\n1.5,jawOpen\n", "line 2: '1.5' is not a time"),
    ("0,neutral,extra\n", "line 1: expected WHEN,NAME"),
])
def test_bad_marks_named(tmp_path, text, match):
    with pytest.raises(ValueError, match=match):
        read_marks(write(tmp_path, text), FPS, 100, names=["jawOpen"])


def test_steadiest_window_finds_the_still_run(rng):
    pts = rng.normal(size=(40, 3, 3))
    pts[22:27] = pts[22]                               # still from frame 22 to 26
    valid = np.ones(40, bool)
    assert steadiest_window(pts, valid, centre=20, radius=8, window=5) == (22, 27)
    valid[24] = False
    span = steadiest_window(pts, valid, centre=20, radius=8, window=5)
    assert span is not None and not (span[0] <= 24 < span[1])
    assert steadiest_window(pts, np.zeros(40, bool), 20, 8, 5) is None


def test_examples_from_marks_recover_held_expressions(rng):
    neutral = rng.normal(size=(P, 3))
    shapes = {"jawOpen": rng.normal(size=(P, 3)), "mouthSmile": rng.normal(size=(P, 3))}
    f = 90
    points = np.repeat(neutral[None], f, axis=0) + 0.3 * rng.normal(size=(f, P, 3))   # jittery elsewhere
    points[5:15] = neutral
    points[35:45] = neutral + shapes["jawOpen"]
    points[65:75] = neutral + shapes["mouthSmile"]
    valid = np.ones(f, bool)
    valid[40] = False                                      # a lost frame inside a hold is avoided
    track = make_track(points, valid)

    class M:
        def __init__(self, frame, name):
            self.frame, self.name = frame, name

    marks = [M(8, "neutral"), M(38, "jawOpen"), M(72, "mouthSmile")]
    result = examples_from_marks(track, marks, CalibrateConfig(window=4, search=0.3))
    np.testing.assert_allclose(result.neutral, neutral, atol=1e-12)
    assert result.names == ("jawOpen", "mouthSmile")
    np.testing.assert_allclose(result.examples[0], neutral + shapes["jawOpen"], atol=1e-12)
    np.testing.assert_allclose(result.examples[1], neutral + shapes["mouthSmile"], atol=1e-12)
    assert result.point_names == POINT_NAMES
    assert result.warnings == ()
    # the jitter outside the holds is what the key expressions cannot express: about 0.3 per coordinate
    assert result.noise.shape == neutral.shape and 0.1 < np.median(result.noise) < 0.4


def test_no_face_near_a_mark(rng):
    points = rng.normal(size=(60, P, 3))
    valid = np.ones(60, bool)
    valid[20:60] = False

    class M:
        frame, name = 50, "jawOpen"

    class N:
        frame, name = 5, "neutral"

    with pytest.raises(FacepuppetError, match="jawOpen .frame 50.: no face"):
        examples_from_marks(make_track(points, valid), [N, M])


def test_check_examples_names_problems(rng):
    neutral = rng.normal(size=(P, 3))
    a, b, c = (rng.normal(size=(P, 3)) for _ in range(3))
    examples = np.stack([neutral + a, neutral + b, neutral + b + 0.01 * c, neutral + 1e-4 * c])
    out = check_examples(neutral, examples, ["jawOpen", "smile", "grin", "blank"])
    assert any("blank barely differs from neutral" in m for m in out)
    assert any("smile and grin are too close" in m for m in out)
    assert len(out) == 2
    assert check_examples(neutral, examples[:2], ["jawOpen", "smile"]) == []


def test_auto_picks_frames_by_blendshape_scores(rng):
    from facepuppet.arkit import ARKIT_NAMES as BLENDSHAPE_NAMES

    col = {n: i for i, n in enumerate(BLENDSHAPE_NAMES)}
    f = 60
    neutral = rng.normal(size=(P, 3))
    neutral[:, 0] = np.linspace(-5, 5, P)                       # spread left and right for the side split
    jaw, blink, puff = (rng.normal(size=(P, 3)) for _ in range(3))
    scores = np.full((f, len(BLENDSHAPE_NAMES)), 0.1)
    points = np.repeat(neutral[None], f, axis=0) + 0.05 * rng.normal(size=(f, P, 3))
    scores[2:8] = 0.0                                           # the most relaxed frames
    points[2:8] = neutral
    scores[20:26, col["jawOpen"]] = 0.9
    points[20:26] = neutral + jaw
    scores[30:36, [col["eyeBlinkLeft"], col["eyeBlinkRight"]]] = 0.95
    points[30:36] = neutral + blink
    scores[40:46, col["cheekPuff"]] = 0.8
    points[40:46] = neutral + puff
    track = make_track(points, extras={"blendshapes": scores, "blendshape_names": np.array(BLENDSHAPE_NAMES)})
    names = ["jawOpen", "eyeBlink", "cheekPuff_L", "mouthPucker", "wiggle"]
    result = calibrate_auto("clip", names, config=CalibrateConfig(window=4, auto_method="frames"),
                            scores_track=track, track=track)
    assert result.names == ("jawOpen", "eyeBlink", "cheekPuff_L")
    np.testing.assert_allclose(result.neutral, neutral, atol=1e-12)
    np.testing.assert_allclose(result.examples[0], neutral + jaw, atol=1e-12)
    np.testing.assert_allclose(result.examples[1], neutral + blink, atol=1e-12)
    half = result.examples[2] - neutral                         # only the performer's left (x > 0) moves
    assert np.abs(half[neutral[:, 0] < -1]).max() < 0.05 * np.abs(puff).max()
    np.testing.assert_allclose(half[neutral[:, 0] > 1], puff[neutral[:, 0] > 1], rtol=0.05, atol=0.02)
    assert any("mouthPucker" in w for w in result.warnings)
    assert any("wiggle (not an ARKit name)" in w for w in result.warnings)
    assert result.noise is not None and result.noise.shape == neutral.shape and (result.noise > 0).all()


def test_auto_needs_scores(rng):
    track = make_track(rng.normal(size=(10, P, 3)))
    with pytest.raises(FacepuppetError, match="blendshape scores"):
        calibrate_auto("clip", ["jawOpen"], scores_track=track, track=track)


def test_auto_splits_pairs_and_leaves_out_twins(rng):
    from facepuppet.arkit import ARKIT_NAMES

    col = {n: i for i, n in enumerate(ARKIT_NAMES)}
    f = 50
    neutral = rng.normal(size=(P, 3))
    neutral[:, 0] = np.linspace(-5, 5, P)
    blink, smile = rng.normal(size=(P, 3)), rng.normal(size=(P, 3))
    scores = np.full((f, len(ARKIT_NAMES)), 0.05)
    points = np.repeat(neutral[None], f, axis=0) + 0.05 * rng.normal(size=(f, P, 3))
    scores[2:8] = 0.0
    points[2:8] = neutral
    scores[20:26, [col["eyeBlinkLeft"], col["eyeBlinkRight"]]] = 0.9       # both eyes together
    points[20:26] = neutral + blink
    scores[35:41, [col["mouthSmileLeft"], col["mouthSmileRight"], col["cheekSquintLeft"],
                   col["cheekSquintRight"]]] = [0.9, 0.9, 0.6, 0.6]       # a smile squints the cheeks
    points[35:41] = neutral + smile
    track = make_track(points, extras={"blendshapes": scores, "blendshape_names": np.array(ARKIT_NAMES)})
    names = ["eyeBlink_L", "eyeBlink_R", "mouthSmile", "cheekSquint"]
    result = calibrate_auto("clip", names, config=CalibrateConfig(window=4, auto_method="frames"),
                            scores_track=track, track=track)
    assert result.names == ("eyeBlink_L", "eyeBlink_R", "mouthSmile")
    d_l, d_r = result.examples[0] - neutral, result.examples[1] - neutral
    np.testing.assert_allclose(d_l + d_r, blink, atol=1e-9)                 # the halves add up to the blink
    left = neutral[:, 0] > 1
    assert np.abs(d_r[left]).max() < 0.05 * np.abs(blink).max()
    assert any("cheekSquint (shown only together with mouthSmile)" in w for w in result.warnings)


def test_auto_regression_separates_expressions_shown_together(rng):
    """Frames are exact blends of two pure expressions by their scores; the pure ones come back."""
    from facepuppet.arkit import ARKIT_NAMES

    col = {n: i for i, n in enumerate(ARKIT_NAMES)}
    f = 80
    neutral = rng.normal(size=(P, 3))
    jaw, smile = rng.normal(size=(P, 3)), rng.normal(size=(P, 3))
    scores = np.zeros((f, len(ARKIT_NAMES)))
    s_jaw = np.clip(np.sin(np.arange(f) / 6.0), 0, 1)
    s_smile = np.clip(np.cos(np.arange(f) / 9.0), 0, 1) * 0.8
    s_smile[s_jaw > 0.5] = 0.3 + 0.5 * s_jaw[s_jaw > 0.5]              # the smile always comes with the jaw
    s_smile[:6] = s_jaw[:6] = 0.0
    scores[:, col["jawOpen"]] = s_jaw
    scores[:, [col["mouthSmileLeft"], col["mouthSmileRight"]]] = s_smile[:, None]
    points = neutral + s_jaw[:, None, None] * jaw + s_smile[:, None, None] * smile
    points[[15, 33, 60]] = np.nan            # faces whose head pose failed: curves but no points
    track = make_track(points, extras={"blendshapes": scores, "blendshape_names": np.array(ARKIT_NAMES)})
    assert track.valid[[15, 33, 60]].all()
    result = calibrate_auto("clip", ["jawOpen", "mouthSmile"], config=CalibrateConfig(window=3),
                            scores_track=track, track=track)
    assert result.names == ("jawOpen", "mouthSmile")
    np.testing.assert_allclose(result.examples[0], neutral + jaw, atol=0.02)
    np.testing.assert_allclose(result.examples[1], neutral + smile, atol=0.02)


def test_coordinate_noise_recovers_each_coordinates_noise(rng):
    """Points = neutral + score-driven expressions + Gaussian noise of a known scale per coordinate (some
    coordinates noiseless): the scales come back, the noiseless ones at the floor."""
    f, p = 4000, 12
    neutral = rng.normal(size=(p, 3))
    scores = rng.uniform(0, 1, size=(f, 2))
    B = rng.normal(size=(2, p, 3))
    sigma = rng.uniform(0.05, 0.5, size=(p, 3))
    sigma[:3] = 0.0
    points = neutral + np.tensordot(scores, B, axes=1) + 0.2 + rng.normal(size=(f, p, 3)) * sigma
    got = coordinate_noise(points, scores, neutral, floor=0.1, motion_floor=0.0)
    floor = 0.1 * np.median(np.sqrt((sigma ** 2).mean(axis=1)))
    np.testing.assert_allclose(got, np.sqrt(sigma ** 2 + floor ** 2), rtol=0.1)
    assert np.allclose(got[:3], got[:3].min()) and got[:3].min() > 0


def test_auto_takes_the_head_turns_the_landmark_backend_sees_as_nuisance(rng):
    """Points that move with the jaw's score and with the head's yaw (as MediaPipe's rotation has it) while the
    tracker's own pose stays upright: the nuisance is the yaw's part alone; a track whose pose turns gets none."""
    from facepuppet.arkit import ARKIT_NAMES
    from facepuppet.pipeline.calibrate import head_turn_nuisance

    col = {n: i for i, n in enumerate(ARKIT_NAMES)}
    f = 300
    neutral = rng.normal(size=(P, 3))
    jaw, turn = rng.normal(size=(P, 3)), rng.normal(size=(P, 3))
    s_jaw = np.clip(np.sin(np.arange(f) / 7.0), 0, 1)
    s_jaw[:8] = 0.0
    yaw = 0.15 * np.sin(np.arange(f) / 11.0 + 1.0)
    scores = np.zeros((f, len(ARKIT_NAMES)))
    scores[:, col["jawOpen"]] = s_jaw
    points = neutral + s_jaw[:, None, None] * jaw + np.sin(yaw)[:, None, None] * turn
    rot = np.zeros((f, 3, 3))
    rot[:, 0, 0] = rot[:, 2, 2] = np.cos(yaw)
    rot[:, 0, 2], rot[:, 2, 0], rot[:, 1, 1] = np.sin(yaw), -np.sin(yaw), 1.0
    extras = {"blendshapes": scores, "blendshape_names": np.array(ARKIT_NAMES)}
    scores_track = replace(make_track(points, extras=extras), rotation=rot)
    upright = make_track(points)
    got = head_turn_nuisance(upright, scores_track, scores, np.ones(f, bool), neutral)
    expect = (np.sin(yaw) - np.sin(yaw).mean())[:, None, None] * turn
    np.testing.assert_allclose(got - neutral, expect, atol=1e-9)
    result = calibrate_auto("clip", ["jawOpen"], config=CalibrateConfig(window=3), scores_track=scores_track,
                            track=upright)
    assert result.nuisance is not None and result.nuisance.shape[1:] == neutral.shape
    alone = calibrate_auto("clip", ["jawOpen"], config=CalibrateConfig(window=3), scores_track=scores_track,
                           track=scores_track)
    assert alone.nuisance is None
