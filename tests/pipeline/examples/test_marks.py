"""Key expressions from a marks file: the marks file, steady windows, examples from synthetic tracks."""

from __future__ import annotations

import numpy as np
import pytest

from facepuppet.capture.curves import POINT_NAMES
from facepuppet.errors import FacepuppetError
from facepuppet.pipeline.examples import ExamplesConfig, from_marked_track, steadiest_window
from facepuppet.pipeline.examples.marks import HEAD_MOTION, MIN_HEAD_MOTION_FRAMES, Mark, parse_when, read_marks
from synthetic_tracks import FPS, P, make_track


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
    result = from_marked_track(track, marks, ExamplesConfig(window=4))
    assert result.names == ("mouthSmile",)
    np.testing.assert_allclose(result.nuisance, np.delete(points[40:70], 10, axis=0))
    assert from_marked_track(track, marks[:2], ExamplesConfig(window=4)).nuisance is None
    short = [*marks[:2], Mark(40, HEAD_MOTION, 3, "40-45", 40 + MIN_HEAD_MOTION_FRAMES - 1)]
    with pytest.raises(FacepuppetError, match=r"head-motion 40-45 \(line 3\): only 9 frames with a face"):
        from_marked_track(track, short, ExamplesConfig(window=4))


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


def test_from_marked_track_recovers_held_expressions(rng):
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
    result = from_marked_track(track, marks, ExamplesConfig(window=4, search=0.3))
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
        from_marked_track(make_track(points, valid), [N, M])


def test_capture_examples_needs_one_way(tmp_path):
    from facepuppet.pipeline.examples import capture_examples

    for kwargs in ({}, {"marks": tmp_path / "m.csv", "auto": True}):
        with pytest.raises(ValueError, match="either a marks file or auto=True"):
            capture_examples(tmp_path / "v.mp4", names=["jawOpen"], **kwargs)


def test_frames_whose_head_pose_failed_are_left_out_of_an_expression(rng):
    """A frame with a face but no feature points (its head pose was not solved) is not averaged in."""
    from facepuppet.pipeline.examples.window import average_near

    pts = np.tile(rng.normal(size=(1, P, 3)), (40, 1, 1))
    track = make_track(pts)
    track.points[18:23] = np.nan                       # valid, curves found, points NaN
    got, span = average_near(track, "jawOpen", 20, ExamplesConfig())
    assert np.isfinite(got).all() and not (18 <= span[0] < 23 or 18 < span[1] <= 23)
    np.testing.assert_allclose(got, pts[0])
    track.points[:] = np.nan
    with pytest.raises(FacepuppetError, match="no face was tracked"):
        average_near(track, "jawOpen", 20, ExamplesConfig())
