"""Key expressions picked by blendshape scores (--auto), on synthetic tracks with known answers."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from facepuppet.errors import FacepuppetError
from facepuppet.pipeline.examples import ExamplesConfig, from_auto
from synthetic_tracks import P, make_track


def lip_points() -> np.ndarray:
    """(P,) bool: the feature points on the lips' curves."""
    from facepuppet.capture.curves import POINT_NAMES

    return np.array([n.startswith("lip") for n in POINT_NAMES])


def region_of(prefix: str) -> np.ndarray:
    """(P,) bool: the feature points on the curves whose name starts with ``prefix``."""
    from facepuppet.capture.curves import POINT_NAMES

    return np.array([n.startswith(prefix) for n in POINT_NAMES])


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
    result = from_auto("clip", names, config=ExamplesConfig(window=4, auto_method="frames"),
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
        from_auto("clip", ["jawOpen"], scores_track=track, track=track)


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
    result = from_auto("clip", names, config=ExamplesConfig(window=4, auto_method="frames"),
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
    lips = lip_points()[:, None]                                       # the jaw and the smile move the lips
    jaw, smile = rng.normal(size=(P, 3)) * lips, rng.normal(size=(P, 3)) * lips
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
    result = from_auto("clip", ["jawOpen", "mouthSmile"], config=ExamplesConfig(window=3),
                            scores_track=track, track=track)
    assert result.names == ("jawOpen", "mouthSmile")
    np.testing.assert_allclose(result.examples[0], neutral + jaw, atol=0.02)
    np.testing.assert_allclose(result.examples[1], neutral + smile, atol=0.02)


def test_auto_takes_the_head_turns_the_landmark_backend_sees_as_nuisance(rng):
    """Points that move with the jaw's score and with the head's yaw (as MediaPipe's rotation has it) while the
    tracker's own pose stays upright: the nuisance is the yaw's part alone; a track whose pose turns gets none."""
    from facepuppet.arkit import ARKIT_NAMES
    from facepuppet.mapping.noise import head_turn_nuisance

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
    got = head_turn_nuisance(upright.points, scores_track.rotation, scores, neutral)
    expect = (np.sin(yaw) - np.sin(yaw).mean())[:, None, None] * turn
    np.testing.assert_allclose(got - neutral, expect, atol=1e-9)
    result = from_auto("clip", ["jawOpen"], config=ExamplesConfig(window=3), scores_track=scores_track,
                            track=upright)
    assert result.nuisance is not None and result.nuisance.shape[1:] == neutral.shape
    alone = from_auto("clip", ["jawOpen"], config=ExamplesConfig(window=3), scores_track=scores_track,
                           track=scores_track)
    assert alone.nuisance is None


def test_auto_keeps_each_expression_to_its_part_of_the_face_and_finds_neutral_without_a_relaxed_frame(rng):
    """A performer who never relaxes (the jaw always at least a third open) and whose lips part by an amount
    no score measures whenever the eyes close: the blink comes back on the eyelids alone, the jaw whole, and
    the neutral is the face at zero scores, not the most relaxed frame."""
    from facepuppet.arkit import ARKIT_NAMES

    col = {n: i for i, n in enumerate(ARKIT_NAMES)}
    f = 240
    t = np.arange(f)
    neutral = rng.normal(size=(P, 3))
    lips, eyes = region_of("lip")[:, None], region_of("eye")[:, None]
    jaw, blink, parting = rng.normal(size=(P, 3)) * lips, rng.normal(size=(P, 3)) * eyes, rng.normal(size=(P, 3)) * lips
    s_jaw = 0.35 + 0.6 * (0.5 + 0.5 * np.sin(t / 7.0))
    s_blink = np.clip(np.sin(t / 4.3), 0, 1) ** 2
    scores = np.zeros((f, len(ARKIT_NAMES)))
    scores[:, col["jawOpen"]] = s_jaw
    scores[:, [col["eyeBlinkLeft"], col["eyeBlinkRight"]]] = s_blink[:, None]
    points = (neutral + s_jaw[:, None, None] * jaw + s_blink[:, None, None] * (blink + 0.7 * parting)
              + 0.01 * rng.normal(size=(f, P, 3)))
    track = make_track(points, extras={"blendshapes": scores, "blendshape_names": np.array(ARKIT_NAMES)})
    result = from_auto("clip", ["jawOpen", "eyeBlink"], config=ExamplesConfig(window=3), scores_track=track,
                       track=track)
    assert result.names == ("jawOpen", "eyeBlink")
    scale = np.abs(jaw).max()
    still = ~region_of("lip")         # the lips' unscored parting averages into their zero-score face
    np.testing.assert_allclose(result.neutral[still], neutral[still], atol=0.05 * scale)
    d_jaw, d_blink = result.examples[0] - result.neutral, result.examples[1] - result.neutral
    np.testing.assert_allclose(d_jaw, jaw, atol=0.05 * scale)
    np.testing.assert_allclose(d_blink, blink, atol=0.05 * scale)
    assert np.abs(d_blink[region_of("lip")]).max() == 0.0 and np.abs(d_jaw[region_of("eye")]).max() == 0.0
    frames = result.frames["neutral"]                    # the most relaxed frames still show a third of the jaw
    assert s_jaw[frames[0]:frames[1]].min() > 0.3
    points -= s_blink[:, None, None] * 0.7 * parting
    track = make_track(points, extras={"blendshapes": scores, "blendshape_names": np.array(ARKIT_NAMES)})
    result = from_auto("clip", ["jawOpen", "eyeBlink"], config=ExamplesConfig(window=3), scores_track=track,
                       track=track)
    np.testing.assert_allclose(result.neutral, neutral, atol=0.02 * scale)
    np.testing.assert_allclose(result.examples[0], neutral + jaw, atol=0.02 * scale)
