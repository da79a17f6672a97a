"""The demo's error with real trackers, side by side, over several seeds (the bar of ``facepuppet demo`` is 0.5).

For each seed the whole demo runs (no preview) with the colour tracker, with the MediaPipe landmark backend
when its model is found (``--model``, ``$FACEPUPPET_FACE_LANDMARKER`` or ../shared/assets/models), and with
the performer's true curves standing in for a tracker. The demo's colour tracker never uses the landmark
model (with it, it would place its first eye anchors on MediaPipe's eyes). Printed per seed:
the relative vertex error of each (0 perfect, 1 = as far off as the neutral face), the trackers' median curve
error in pixels and the wall time of the colour run.

Then, per family of feature points (brows, lids, outer and inner lips, nostrils), averaged over the seeds:
how far each tracker's points (head coordinates, head pose removed) wander from the true ones, as the RMS
over frames and points of the error once its mean over the performance is taken away (a constant offset
cancels in the mapping, which works on displacements from the neutral face), beside the RMS of the true
points' own motion away from the neutral face. A family whose wander is near its motion carries little of
the expression. The nostrils' ends and the eye corners are the points the head pose is solved from, so
their own wander in the image shows up here as the other families' (through the pose), not as theirs.

Run: ``python benchmarks/eval_demo_color.py [--seeds 0 1 2] [--seconds 8] [--size 320] [--model TASK]``
(about 35 s per seed and tracker on one core; the first run also compiles the tracker, about a minute).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

#: Families of curves whose points' wander is reported.
FAMILIES = {
    "brows": ("brow_left", "brow_right"),
    "lids": ("eye_left_upper", "eye_left_lower", "eye_right_upper", "eye_right_lower"),
    "outer lips": ("lip_upper_outer", "lip_lower_outer"),
    "inner lips": ("lip_upper_inner", "lip_lower_inner"),
    "nostrils": ("nostril_left", "nostril_right"),
}


def _family_points(point_names) -> dict[str, np.ndarray]:
    return {fam: np.array([i for i, n in enumerate(point_names) if n.split(":")[0] in curves])
            for fam, curves in FAMILIES.items()}


def wander(points: np.ndarray, true: np.ndarray, index: np.ndarray) -> float:
    """RMS (mm) over frames and points of the error of ``points`` (F, P, 3, cm) less its mean over frames."""
    e = points[:, index] - true[:, index]
    ok = np.isfinite(e).all(axis=(1, 2))
    e = e[ok] - e[ok].mean(axis=0)
    return 10.0 * float(np.sqrt(np.mean(e ** 2)))


def motion(true: np.ndarray, index: np.ndarray) -> float:
    """RMS (mm) of the true points' displacement from the first frame (the performance starts neutral)."""
    return 10.0 * float(np.sqrt(np.mean((true[:, index] - true[:1, index]) ** 2)))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--seconds", type=float, default=8.0)
    ap.add_argument("--size", type=int, default=320)
    ap.add_argument("--model", default=None, help="face_landmarker.task (default $FACEPUPPET_FACE_LANDMARKER, "
                                                  "then ../shared/assets/models)")
    args = ap.parse_args(argv)

    from facepuppet.demo.run import DemoConfig, run_demo
    from facepuppet.io.track import load_track

    model = args.model or os.environ.get("FACEPUPPET_FACE_LANDMARKER")
    if model is None and (ROOT.parent / "shared/assets/models/face_landmarker.task").is_file():
        model = str(ROOT.parent / "shared/assets/models/face_landmarker.task")
    trackers = ["truth", "color"] + (["mediapipe"] if model else [])
    if not model:
        print("no MediaPipe model found: the landmark backend is left out")

    errors = {t: [] for t in trackers}
    drift = {t: {f: [] for f in FAMILIES} for t in trackers}
    print(f"{'seed':>4}  {'color':>6}  {'curves px':>9}  {'seconds':>7}  {'mediapipe':>9}  {'curves px':>9}  "
          f"{'truth':>6}")
    for seed in args.seeds:
        runs, points = {}, {}
        for tracker in trackers:
            with tempfile.TemporaryDirectory() as tmp:
                runs[tracker] = run_demo(tmp, DemoConfig(seconds=args.seconds, size=args.size, seed=seed,
                                                         tracker=tracker, preview=False, progress=False,
                                                         model=model if tracker == "mediapipe" else None))
                track = load_track(Path(tmp) / "track.npz")
            points[tracker] = track.points
            errors[tracker].append(runs[tracker].error)
        index = _family_points(track.point_names)
        for tracker in trackers:
            for fam, idx in index.items():
                drift[tracker][fam].append(wander(points[tracker], points["truth"], idx)
                                           if tracker != "truth" else motion(points["truth"], idx))
        c, m = runs["color"], runs.get("mediapipe")
        mp_cols = f"{m.error:9.3f}  {m.curve_error:9.2f}" if m else f"{'-':>9}  {'-':>9}"
        print(f"{seed:4d}  {c.error:6.3f}  {c.curve_error:9.2f}  {c.seconds:7.1f}  {mp_cols}  "
              f"{runs['truth'].error:6.3f}", flush=True)
    mp_mean = f"{np.mean(errors['mediapipe']):9.3f}" if "mediapipe" in errors else f"{'-':>9}"
    print(f"mean  {np.mean(errors['color']):6.3f}  {'':9}  {'':7}  {mp_mean}  {'':9}  {np.mean(errors['truth']):6.3f}")

    print("\nwander of the feature points from the true ones (mm, mean taken away), beside the true motion")
    print(f"{'family':<12}{'color':>8}{'mediapipe':>11}{'true motion':>13}")
    for fam in FAMILIES:
        mp = f"{np.mean(drift['mediapipe'][fam]):11.2f}" if "mediapipe" in drift else f"{'-':>11}"
        print(f"{fam:<12}{np.mean(drift['color'][fam]):8.2f}{mp}{np.mean(drift['truth'][fam]):13.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
