"""Tracking through large head turns, against ground truth: the digital performer turning its head.

The shared clips' heads barely turn (MediaPipe's yaw spreads 1.3-4.2 degrees), so how the trackers hold on
through a real turn is measured here on the digital performer (:mod:`facepuppet.demo.performer`), whose
curves and head pose are known exactly. It acts the demo's performance (every key expression, seed 3) while
its head sweeps ``--yaw`` degrees either way (0.11 Hz) and, with ``--pitch``, nods that far (0.17 Hz), eased in
over the first second; 480 x 480 frames at 30 /s. ``--seeds`` acts several performances (each seed's
expressions, its sweep started ``seed - 3`` radians into its cycle) and pools their frames: tracking through a
turn hangs on single frames (a face lost and found again, an eye held on a brow), so one performance's figures
move by more than a change's effect.

Printed per tracker (the colour tracker with the built-in profile; MediaPipe's backend beside it when its model
is found): with several seeds, each one's coverage and mean curve error; then over all their frames the
coverage and the frames tracked wrong (valid, but with an NME over 0.5 or the roll more than 20 degrees off:
another thing taken for the face, worse than a frame marked lost), and per band of the true |yaw| the frames
tracked and the mean curve error (NME: the mean distance of each curve's control points from the true ones
over the true eye-centre distance; the painted curves are the reference, so MediaPipe's own contours are not
quite on them either); then the correlation, mean absolute error (degrees) and slope (of the tracked yaw
regressed on the true one) of yaw, pitch and roll over the frames tracked.

    python benchmarks/eval_head_turns.py [--yaw 30] [--pitch 0] [--seconds 12] [--seeds 3 ...]
                                         [--model face_landmarker.task]
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
from eval_head_pose import track  # noqa: E402

BANDS = ((0, 10), (10, 20), (20, 30), (30, 90))   # degrees of |yaw|
WRONG_NME = 0.5                                    # a frame tracked with a larger NME ...
WRONG_ROLL = 20.0                                  # ... or its roll off by more degrees is tracked wrong


def performance(yaw_deg: float, pitch_deg: float, seconds: float, seed: int = 3):
    """(frames (F, 480, 480, 3) uint8, true curves (F, C, 4, 2), true (yaw, pitch, roll) (F, 3) radians) of the
    performance of ``seed`` (its expressions; its yaw's phase ``seed - 3`` radians)."""
    from facepuppet.demo.performer import render_performer
    from facepuppet.demo.script import Script, performance_script

    script = performance_script(seconds=seconds, fps=30.0, seed=seed)
    t = np.arange(script.n_frames) / 30.0
    motion = script.head_motion.copy()
    ease = np.clip(t, 0.0, 1.0)
    motion[:, 0] = ease * np.radians(yaw_deg) * np.sin(2 * np.pi * 0.11 * t + (seed - 3))
    motion[:, 1] = ease * np.radians(pitch_deg) * np.sin(2 * np.pi * 0.17 * t + 1.0)
    frames, curves = render_performer(Script(script.weights, motion, 30.0), size=(480, 480))
    return frames, curves, motion[:, :3]


def eye_distance(curves: np.ndarray) -> np.ndarray:
    """(F,) distance of the eye centres (each the midpoint of its upper lid's ends), pixels."""
    from facepuppet.capture.curves import CURVE_NAMES

    left = curves[:, CURVE_NAMES.index("eye_left_upper"), [0, 3]].mean(axis=1)
    right = curves[:, CURVE_NAMES.index("eye_right_upper"), [0, 3]].mean(axis=1)
    return np.linalg.norm(left - right, axis=1)


def curve_error(curves: np.ndarray, truth_curves: np.ndarray) -> np.ndarray:
    """(F,) NME of each frame: the mean distance of the curves' control points from the true ones over the true
    eye-centre distance."""
    return np.linalg.norm(curves - truth_curves, axis=-1).mean(axis=(1, 2)) / eye_distance(truth_curves)


def report(name: str, valid, curves, angles, truth_curves, truth_angles) -> None:
    nme = curve_error(curves, truth_curves)
    yaw = np.degrees(np.abs(truth_angles[:, 0]))
    off = np.degrees(np.abs((angles[:, 2] - truth_angles[:, 2] + np.pi) % (2 * np.pi) - np.pi))
    wrong = valid & ((nme > WRONG_NME) | (off > WRONG_ROLL))
    print(f"{name}: coverage {valid.mean():.3f}; frames tracked wrong {wrong.sum()} of {len(valid)}")
    for lo, hi in BANDS:
        band = (yaw >= lo) & (yaw < hi)
        if band.any():
            kept = band & valid
            err = f"{nme[kept].mean():.3f}" if kept.any() else "-"
            print(f"  |yaw| {lo:2d}-{hi:2d} deg: {band.sum():4d} frames, tracked {kept.sum():4d}, NME {err}")
    for k, angle in enumerate(("yaw", "pitch", "roll")):
        a, b = np.degrees(angles[valid, k]), np.degrees(truth_angles[valid, k])
        if b.std() < 1e-6:
            print(f"  {angle:5s}: not turned in this performance (MAE {np.abs(a - b).mean():.2f})")
            continue
        r = float(np.corrcoef(a, b)[0, 1]) if a.std() > 1e-9 else float("nan")
        slope = float(np.polyfit(b, a, 1)[0])
        print(f"  {angle:5s}: r {r:5.2f}, MAE {np.abs(a - b).mean():5.2f}, slope {slope:5.2f} "
              f"(true spread {b.std():.1f})")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--yaw", type=float, default=30.0, help="largest yaw either way, degrees (default 30)")
    ap.add_argument("--pitch", type=float, default=0.0, help="largest pitch either way, degrees (default 0)")
    ap.add_argument("--seconds", type=float, default=12.0, help="length of the performance (default 12)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[3],
                    help="performances to act and pool (default 3)")
    ap.add_argument("--model", help="face_landmarker.task (default $FACEPUPPET_FACE_LANDMARKER or the shared one)")
    args = ap.parse_args(argv)
    if not (0 <= args.yaw <= 60 and 0 <= args.pitch <= 40 and args.seconds >= 4.6):
        print("eval_head_turns: --yaw must be 0-60, --pitch 0-40 degrees and --seconds at least 4.6",
              file=sys.stderr)
        return 2
    model = args.model or os.environ.get("FACEPUPPET_FACE_LANDMARKER") or str(
        ROOT.parent / "shared" / "assets" / "models" / "face_landmarker.task")
    backends = [("colour tracker, built-in profile", "color", {})]
    if Path(model).is_file():
        backends.append(("MediaPipe backend", "mediapipe", {"model_path": model}))
    else:
        print(f"MediaPipe backend: skipped (no model at {model})")
    runs = {name: [] for name, _, _ in backends}           # per backend, per seed: (valid, curves, angles)
    truth = []                                              # per seed: (curves, angles)
    for seed in args.seeds:
        frames, truth_curves, truth_angles = performance(args.yaw, args.pitch, args.seconds, seed)
        print(f"seed {seed}: the digital performer, {len(frames)} frames, yaw up to {args.yaw:g} and pitch up to "
              f"{args.pitch:g} deg")
        truth.append((truth_curves, truth_angles))
        for name, backend, options in backends:
            valid, curves, _, angles = track(backend, options, list(frames), 30.0)
            runs[name].append((valid, curves, angles))
            if len(args.seeds) > 1:
                nme = curve_error(curves, truth_curves)[valid].mean()
                print(f"  {name}: coverage {valid.mean():.3f}, NME {nme:.3f}")
        del frames
    truth_curves = np.concatenate([c for c, _ in truth])
    truth_angles = np.concatenate([a for _, a in truth])
    for name, _, _ in backends:
        valid, curves, angles = (np.concatenate(x) for x in zip(*runs[name], strict=True))
        report(name, valid, curves, angles, truth_curves, truth_angles)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
