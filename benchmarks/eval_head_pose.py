"""Head pose of the colour tracker against MediaPipe's: yaw, pitch and roll on the shared clips.

For each clip, the MediaPipe backend tracks every frame (its pose: PnP of its landmarks on the generic face,
the reference). The colour tracker then tracks the clip twice: with the generic profile, and with a profile
trained on the first half of the clip (every third frame MediaPipe found a face in, at most 150, labelled by
MediaPipe's curves and head rotations, as ``calibrate --train-profile`` does); the trained one is scored on
the second half only (held out). An angle held at zero (what the tracker gives where it does not measure
one) is scored beside them: its error is the size of MediaPipe's angle. Printed per angle: Pearson
correlation and mean absolute error in degrees over the frames both backends tracked (a constant angle has
no correlation: "-"), and the spread of MediaPipe's angles over the held-out half (an angle whose spread is
under ``TURNS`` degrees does not turn: its correlation is on noise). For the trained profile also, per
angle: the slope of its angle regressed on MediaPipe's (under 1: the turns read smaller than they are) and
the jitter of both (the mean absolute change from one frame to the next over consecutive held-out frames
both tracked, degrees: a head that wobbles). ``--generic-only`` skips the trained profile.

    python benchmarks/eval_head_pose.py [--frames N] [--model face_landmarker.task] [--generic-only] [CLIP ...]
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
ASSETS = Path(os.environ.get("FACEPUPPET_ASSETS", ROOT.parent / "shared" / "assets"))
CLIPS = ("performer_a.mp4", "performer_b_exaggerated.mp4", "performer_c.mp4")
EVERY, MAX_LABELS = 3, 150          # labelled frames of the trained profile, as the CLI takes them
ANGLES = ("yaw", "pitch", "roll")
#: Spread (standard deviation, degrees) of MediaPipe's angle over the held-out half from which the head is
#: taken to turn about that axis; a clip whose head turns less gives a correlation on noise.
TURNS = 2.0


def decode(path: Path, limit: int) -> tuple[list[np.ndarray], float]:
    """The first ``limit`` frames of a clip as RGB arrays, and its frame rate."""
    from facepuppet.io.frames import open_media

    frames = []
    with open_media(path) as src:
        fps = src.fps
        for rgb in src:
            frames.append(rgb)
            if len(frames) >= limit:
                break
    return frames, fps


def track(backend: str, options: dict, frames: list[np.ndarray], fps: float):
    """(valid (F,) bool, curves (F, C, 4, 2), rotations (F, 3, 3), angles (F, 3) radians) of one backend."""
    from facepuppet.capture.pose import FRONTAL_ROTATION
    from facepuppet.capture.tracking import make_tracker

    tracker = make_tracker(backend, **options)
    valid, curves, rots = [], [], []
    try:
        for i, rgb in enumerate(frames):
            f = tracker.track(rgb, int(round(i * 1000.0 / fps)))
            valid.append(bool(f.valid) and np.isfinite(f.rotation).all())
            curves.append(f.curves)
            rots.append(f.rotation)
    finally:
        tracker.close()
    rots = np.array(rots)
    m = FRONTAL_ROTATION @ rots
    angles = np.stack([np.arctan2(m[:, 0, 2], m[:, 2, 2]), np.arcsin(np.clip(-m[:, 1, 2], -1, 1)),
                       np.arctan2(m[:, 1, 0], m[:, 1, 1])], axis=1)
    return np.array(valid), np.array(curves), rots, angles


def scores(ours: np.ndarray, ref: np.ndarray, keep: np.ndarray) -> list[tuple[float, float]]:
    """(correlation, mean absolute error in degrees) per angle over the frames ``keep``."""
    out = []
    for k in range(3):
        a, b = np.degrees(ours[keep, k]), np.degrees(ref[keep, k])
        r = float(np.corrcoef(a, b)[0, 1]) if a.std() > 1e-9 and b.std() > 1e-9 else float("nan")
        out.append((r, float(np.abs(a - b).mean())))
    return out


def slopes_and_jitter(ours: np.ndarray, ref: np.ndarray, keep: np.ndarray) -> str:
    """Per angle: the slope of ``ours`` regressed on ``ref`` over ``keep``, and the jitter of each (mean absolute
    change between consecutive frames both in ``keep``), degrees."""
    pairs = keep[1:] & keep[:-1]
    cells = []
    for k, name in enumerate(ANGLES):
        a, b = np.degrees(ours[:, k]), np.degrees(ref[:, k])
        slope = float(np.polyfit(b[keep], a[keep], 1)[0]) if b[keep].std() > 1e-9 else float("nan")
        ja, jb = (float(np.abs(np.diff(v)[pairs]).mean()) for v in (a, b))
        cells.append(f"{name} slope {slope:.2f}, jitter {ja:.2f} (MediaPipe {jb:.2f})")
    return "  trained, second half: " + "; ".join(cells)


def row(label: str, s: list[tuple[float, float]], n: int) -> str:
    cells = " ".join(f"{'-' if np.isnan(r) else f'{r:6.2f}':>6s} {e:6.2f}" for r, e in s)
    return f"  {label:22s} {n:6d} {cells}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("clips", nargs="*", metavar="CLIP", help="videos (default: the three shared clips)")
    ap.add_argument("--frames", type=int, default=10 ** 6, help="most frames per clip (default all)")
    ap.add_argument("--model", help="face_landmarker.task (default $FACEPUPPET_FACE_LANDMARKER or the shared one)")
    ap.add_argument("--generic-only", action="store_true", help="score the built-in profile only (no training)")
    args = ap.parse_args(argv)

    from facepuppet.capture.color.train import train_profile

    model = args.model or os.environ.get("FACEPUPPET_FACE_LANDMARKER") or str(ASSETS / "models" /
                                                                                "face_landmarker.task")
    clips = [Path(c) for c in args.clips] or [ASSETS / "video" / c for c in CLIPS]
    head = " ".join(f"{a + ' r':>6s} {a + ' MAE':>6s}" for a in ANGLES)
    print("head pose of the colour tracker against MediaPipe's (correlation, mean absolute error in degrees)")
    print(f"  {'profile':22s} {'frames':>6s} {head}")
    for clip in clips:
        if not clip.is_file():
            print(f"{clip.name}: missing ({clip})")
            continue
        frames, fps = decode(clip, args.frames)
        half = len(frames) // 2
        mp_valid, mp_curves, mp_rots, mp_angles = track("mediapipe", {"model_path": model}, frames, fps)
        ref_std = np.degrees(mp_angles[mp_valid].std(axis=0))
        print(f"{clip.name} ({len(frames)} frames; MediaPipe's spread: yaw {ref_std[0]:.1f}, pitch "
              f"{ref_std[1]:.1f}, roll {ref_std[2]:.1f} deg)")
        g_valid, _, _, g_angles = track("color", {}, frames, fps)
        keep = mp_valid & g_valid
        print(row("generic, all frames", scores(g_angles, mp_angles, keep), int(keep.sum())))
        held = np.arange(len(frames)) >= half
        print(row("generic, second half", scores(g_angles, mp_angles, keep & held), int((keep & held).sum())))
        print(row("held at zero, all", scores(np.zeros_like(g_angles), mp_angles, keep), int(keep.sum())))
        if args.generic_only:
            continue
        labelled = np.flatnonzero(mp_valid[:half])[::EVERY][:MAX_LABELS]
        profile = train_profile([frames[k] for k in labelled], mp_curves[labelled], name=clip.stem,
                                rotations=mp_rots[labelled])
        t_valid, _, _, t_angles = track("color", {"profile": profile}, frames, fps)
        keep = mp_valid & t_valid & held
        print(row("trained, second half", scores(t_angles, mp_angles, keep), int(keep.sum())))
        print(slopes_and_jitter(t_angles, mp_angles, keep))
        spread = np.degrees(mp_angles[mp_valid & held].std(axis=0))
        turns = ", ".join(f"{a} {'turns' if s >= TURNS else 'still'}" for a, s in zip(ANGLES[:2], spread, strict=False))
        print(f"  MediaPipe's spread over the second half: yaw {spread[0]:.1f}, pitch {spread[1]:.1f}, roll "
              f"{spread[2]:.1f} deg ({turns}: the bars hold where the head turns)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
