"""The colour tracker on faces wearing glasses, drawn here onto frames of the shared clips around MediaPipe's
eyes: dark rims (thin and thick, with a bridge and the arms) and a bright reflection on the lenses. The brows
and lids must stay on their features (near MediaPipe's curves on the original frames) behind them."""

import importlib.util
from pathlib import Path

import cv2
import numpy as np
import pytest
from composites import clip_frames, mediapipe_reference

from facepuppet.capture.color.tracker import ColorTracker
from facepuppet.capture.curves import CURVE_NAMES, bezier_points

_spec = importlib.util.spec_from_file_location(
    "drawn", Path(__file__).resolve().parents[3] / "benchmarks" / "drawn.py")
drawn = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(drawn)

_IDX = {n: i for i, n in enumerate(CURVE_NAMES)}
BROWS_LIDS = ("brow_left", "brow_right", "eye_left_upper", "eye_left_lower", "eye_right_upper", "eye_right_lower")
CLIPS = ("performer_a", "performer_b_exaggerated", "performer_c")
#: Rim thickness (eye-centre distances) and the reflection's share of white of each kind of glasses.
RIMS = {"thin rims": (0.02, 0.0), "thick rims": (0.065, 0.0), "reflection": (0.02, 0.6)}
FRAMES = 60                 # frames taken from each clip (every second of its first 120)


def _nme(ours, ref, names=BROWS_LIDS):
    """Mean over ``names`` of the mean distance from the reference curve to ours, over the outer eye span."""
    span = np.linalg.norm(ref[_IDX["eye_left_upper"], 3] - ref[_IDX["eye_right_upper"], 3])
    d = [np.linalg.norm(bezier_points(ref[_IDX[n]], 9)[:, None] - bezier_points(ours[_IDX[n]], 64)[None],
                        axis=-1).min(axis=1).mean() for n in names]
    return float(np.mean(d) / span)


def wear_glasses(rgb, curves, kind):
    """The RGB frame with glasses of ``kind`` (:data:`RIMS`) drawn around the eyes of the reference curves
    (``benchmarks/drawn.py``: lenses, bridge and arms; for "reflection", a bright band across each lens)."""
    rim, glare = RIMS[kind]
    return drawn.wear_glasses(rgb, curves, rim, glare)


@pytest.fixture(scope="module")
def clips(assets, face_landmarker):
    """Per clip: :data:`FRAMES` frames (every 2nd of its first 2 * FRAMES), MediaPipe's curves on them and the
    colour tracker's (NME, share tracked) on the frames as filmed."""
    out = {}
    for clip in CLIPS:
        frames = clip_frames(assets / "video" / f"{clip}.mp4", 0, 2 * FRAMES, 2)
        ref = np.stack([r.curves for r in mediapipe_reference(frames, face_landmarker)])
        out[clip] = frames, ref, _track_nme(frames, ref)
    return out


def _track_nme(frames, ref, kind=None):
    """(mean NME of the brows and lids over the frames tracked, share of frames tracked)."""
    tracker = ColorTracker()
    nme = []
    for i, (rgb, r) in enumerate(zip(frames, ref, strict=True)):
        f = tracker.track(rgb if kind is None else wear_glasses(rgb, r, kind), 66 * i)
        if f.valid:
            nme.append(_nme(f.curves, r))
    return float(np.mean(nme)) if nme else float("nan"), len(nme) / len(frames)


def test_glasses_are_drawn_where_the_eyes_are(clips):
    frames, ref, _ = clips["performer_c"]
    rgb = wear_glasses(frames[0], ref[0], "thick rims")
    changed = np.abs(rgb.astype(int) - frames[0]).max(axis=2) > 40
    ys, xs = np.nonzero(changed)
    eyes = ref[0][[_IDX["eye_right_upper"], _IDX["eye_left_upper"]]][:, [0, 3]].reshape(-1, 2)
    # The rims surround the eyes but leave the eyes themselves as filmed.
    assert xs.min() < eyes[:, 0].min() and xs.max() > eyes[:, 0].max()
    assert ys.min() < eyes[:, 1].min() and ys.max() > eyes[:, 1].max()
    for x, y in np.round(eyes).astype(int):
        assert not changed[y, x]


@pytest.mark.parametrize("kind", ["thin rims", "thick rims"])
def test_brows_and_lids_stay_on_their_features_behind_rims(clips, kind):
    for clip, (frames, ref, (bare, _)) in clips.items():
        worn, tracked = _track_nme(frames, ref, kind)
        # Measured: 0.022-0.036 behind rims (0.023-0.036 as filmed), every frame tracked.
        assert tracked == 1.0, (clip, kind, tracked)
        assert worn < 0.04, (clip, kind, worn, bare)
        assert worn < bare + 0.006, (clip, kind, worn, bare)


def test_brows_and_lids_behind_a_reflection(clips):
    # A bright band across each lens over the eye (60 % white) hides the lids and part of the eye: the tracker
    # takes it for missing evidence (:mod:`~facepuppet.capture.color.glare`), not for skin or the white of the eye.
    # Measured: 0.029-0.045 (0.023-0.036 as filmed), every frame tracked.
    for clip, (frames, ref, (bare, _)) in clips.items():
        worn, tracked = _track_nme(frames, ref, "reflection")
        assert tracked == 1.0, (clip, tracked)
        assert worn < 0.05, (clip, worn, bare)


def test_a_wide_open_mouth_behind_thick_rims(assets, face_landmarker, tmp_path):
    # performer_c's first 172 frames behind thick rims with the glasses copy's passing reflection
    # (benchmarks/drawn.py, :func:`spectacled`'s schedule), coded as MPEG-4 as the copy is; he opens his mouth
    # wide at frames 110-170. Without the rims taken out of the crop (color/rims.py) the crop's likeness to a face
    # fell under the follower's bar: the face was let go in 13 frames (0-1, 5, 23-28, 50, 72, 102-103; in the whole
    # copy it was found again 0.9 eye distances too low, the brows on the rims' lower bars).
    frames, ref = _filmed(assets / "video" / "performer_c.mp4", 172, face_landmarker)
    tracker = ColorTracker()
    off = []
    for i, (rgb, r) in enumerate(zip(clip_frames(_glasses_copy(frames, ref, tmp_path / "glasses.mp4")), ref,
                                     strict=True)):
        f = tracker.track(rgb, 33 * i)
        if not f.valid:
            off.append(np.inf)
            continue
        eyes = [c[_IDX[n]][[0, 3]].mean(axis=0) for c in (f.curves, r.curves) for n in ("eye_right_upper",
                                                                                          "eye_left_upper")]
        span = np.linalg.norm(eyes[3] - eyes[2])
        off.append(np.linalg.norm(0.5 * (eyes[0] + eyes[1]) - 0.5 * (eyes[2] + eyes[3])) / span)
    off = np.array(off)
    # Measured: every frame tracked; the eyes' midpoint at most 0.13 eye distances off MediaPipe's from frame 100.
    assert np.isfinite(off).all(), np.flatnonzero(~np.isfinite(off))
    assert off[100:].max() < 0.25, (100 + int(np.argmax(off[100:])), off[100:].max())


def _filmed(path, count, model):
    """The first ``count`` frames of the video ``path`` (RGB) and MediaPipe's results on them (video mode)."""
    from facepuppet.capture.tracking import make_tracker

    frames = clip_frames(path, 0, count)
    assert len(frames) == count, (path, len(frames))
    mp = make_tracker("mediapipe", model_path=model, running_mode="video")
    try:
        return frames, [mp.track(f, 33 * i) for i, f in enumerate(frames)]
    finally:
        mp.close()


def _coded(frames, path):
    """The RGB frames written to ``path`` as MPEG-4 at 30 frames a second (as the robustness copies are); path."""
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, frames[0].shape[1::-1])
    for rgb in frames:
        writer.write(cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    writer.release()
    return path


def _glasses_copy(frames, ref, path):
    """The frames as the glasses copy shows them (``benchmarks/drawn.py``: thick rims and the passing reflection
    around MediaPipe's eyes of ``ref``, its results on them) coded as MPEG-4 to ``path``; path."""
    return _coded([drawn.glasses_copy_frame(rgb, r.curves, i) for i, (rgb, r) in enumerate(zip(frames, ref,
                                                                                              strict=True))], path)


def _eye_distance(curves):
    return float(np.linalg.norm(np.subtract(*[curves[_IDX[n]][[0, 3]].mean(axis=0)
                                              for n in ("eye_left_upper", "eye_right_upper")])))


def test_a_face_behind_thick_rims_in_a_dim_room_is_found_at_its_size(assets, face_landmarker, tmp_path):
    # performer_b's first 30 frames as the glasses copy shows them (thick rims and the passing reflection, coded
    # as MPEG-4), dimmed to 0.35 and coded again: a glasses wearer in a dim room. The skin models find no skin
    # between the brows and the rims lower the crop's likeness to a face, so that of the candidates of the first
    # search only one whose eye search took the lenses' outer rims for the eyes passed the skinless candidates'
    # bar: the face was taken 1.71-1.77 times its size. The cascade's window holds the face at its size, and a
    # candidate it holds needs no skin (color/acquire.py, ``Acquirer.refine``).
    frames, ref = _filmed(assets / "video" / "performer_b_exaggerated.mp4", 30, face_landmarker)
    dim = [(rgb * 0.35).astype(np.uint8) for rgb in clip_frames(_glasses_copy(frames, ref, tmp_path / "glasses.mp4"))]
    tracker = ColorTracker()
    sizes = []
    for i, (rgb, r) in enumerate(zip(clip_frames(_coded(dim, tmp_path / "dim.mp4")), ref, strict=True)):
        f = tracker.track(rgb, 33 * i)
        sizes.append(_eye_distance(f.curves) / _eye_distance(r.curves) if f.valid else np.nan)
    # Measured: every frame tracked, the eye distance 1.14-1.18 times MediaPipe's (the window's face is a little
    # larger than the face: the rims widen it).
    assert np.isfinite(sizes).all(), sizes
    assert max(sizes) < 1.35, np.round(sizes, 2)
