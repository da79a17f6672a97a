"""The colour tracker on real faces turning: the shared clips re-posed by a known sweep of yaw and pitch.

Each clip's face is turned by :mod:`turned` (MediaPipe's 3-D landmarks rotated, the face's mesh warped) by
``--yaw`` degrees either way at 0.11 Hz and ``--pitch`` at 0.17 Hz. The MediaPipe backend tracks the turned
copy (the reference, as in ``eval_head_pose.py``), and the colour tracker with its built-in profile tracks it
too. Printed per clip:

- the reference against the sweep put in (r per angle: that the copy turns as meant; the performer's own head
  motion and MediaPipe's error are the rest);
- the colour tracker against the reference: coverage; per angle the correlation, mean absolute error (degrees)
  and slope of its angle regressed on the reference's; the curves' NME (the mean distance of the curves'
  control points from MediaPipe's over MediaPipe's eye-centre distance), over all frames and the frames turned
  more than 15 degrees.

``--save DIR`` also writes each turned copy as ``DIR/<clip>_turned.mp4`` (for ``facepuppet track`` and
``../shared/eval/track_agreement.py``).

    python benchmarks/eval_turned.py [--yaw 30] [--pitch 15] [--frames N] [--model face_landmarker.task]
                                     [--save DIR] [CLIP ...]
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from eval_head_pose import ANGLES, ASSETS, CLIPS, scores, track  # noqa: E402
from eval_head_turns import curve_error  # noqa: E402
from turned import turned_frames  # noqa: E402

TURNED = 15.0     # degrees of added |yaw| from which a frame counts as turned


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("clips", nargs="*", metavar="CLIP", help="videos (default: the three shared clips)")
    ap.add_argument("--yaw", type=float, default=30.0, help="largest yaw added either way, degrees (default 30)")
    ap.add_argument("--pitch", type=float, default=15.0, help="largest pitch added either way, degrees (default 15)")
    ap.add_argument("--frames", type=int, default=10 ** 6, help="most frames per clip (default all)")
    ap.add_argument("--model", help="face_landmarker.task (default $FACEPUPPET_FACE_LANDMARKER or the shared one)")
    ap.add_argument("--save", type=Path, help="write each turned copy to this folder as <clip>_turned.mp4")
    args = ap.parse_args(argv)
    if not (0 <= args.yaw <= 40 and 0 <= args.pitch <= 25):
        print("eval_turned: --yaw must be 0-40 and --pitch 0-25 degrees", file=sys.stderr)
        return 2
    model = args.model or os.environ.get("FACEPUPPET_FACE_LANDMARKER") or str(ASSETS / "models" /
                                                                                "face_landmarker.task")
    if not Path(model).is_file():
        print(f"eval_turned: no MediaPipe model at {model} (--model)", file=sys.stderr)
        return 2
    clips = [Path(c) for c in args.clips] or [ASSETS / "video" / c for c in CLIPS]
    for clip in clips:
        if not clip.is_file():
            print(f"{clip.name}: missing ({clip})")
            continue
        frames, added = [], []
        for rgb, a in turned_frames(clip, model, args.yaw, args.pitch):
            frames.append(rgb)
            added.append(a)
            if len(frames) >= args.frames:
                break
        added = np.array(added)
        fps = clip_rate(clip)
        if args.save:
            save(frames, args.save / f"{clip.stem}_turned.mp4", fps)
        mp_valid, mp_curves, _, mp_angles = track("mediapipe", {"model_path": model}, frames, fps)
        put = [np.corrcoef(np.degrees(mp_angles[mp_valid, k]), added[mp_valid, k])[0, 1]
               if added[mp_valid, k].std() > 1e-9 else float("nan") for k in range(2)]
        print(f"{clip.name}, turned {args.yaw:g} / {args.pitch:g} deg ({len(frames)} frames): MediaPipe on the "
              f"copy against the sweep put in, r yaw {put[0]:.2f}, pitch {put[1]:.2f}")
        valid, curves, _, angles = track("color", {}, frames, fps)
        keep = mp_valid & valid
        print(f"  colour tracker, built-in profile: coverage {valid.mean():.3f} "
              f"(MediaPipe {mp_valid.mean():.3f})")
        for k, (name, (r, mae)) in enumerate(zip(ANGLES, scores(angles, mp_angles, keep), strict=True)):
            a, b = np.degrees(angles[keep, k]), np.degrees(mp_angles[keep, k])
            slope = float(np.polyfit(b, a, 1)[0]) if b.std() > 1e-9 else float("nan")
            print(f"  {name:5s}: r {r:5.2f}, MAE {mae:5.2f}, slope {slope:5.2f} "
                  f"(reference spread {b.std():.1f})")
        nme = curve_error(curves[keep], mp_curves[keep])
        far = np.abs(np.degrees(added[keep, 0])) > TURNED
        print(f"  curves' NME against MediaPipe: {nme.mean():.3f}; frames turned over {TURNED:g} deg "
              f"({int(far.sum())}): {nme[far].mean() if far.any() else float('nan'):.3f}")
    return 0


def clip_rate(clip: Path) -> float:
    """The frame rate of the video ``clip``."""
    from facepuppet.io.frames import open_media

    with open_media(clip) as src:
        return src.fps


def save(frames: list[np.ndarray], out: Path, fps: float) -> None:
    """Write RGB frames to ``out`` (MPEG-4 at ``fps``), through a temporary name."""
    import cv2

    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.stem + ".part.mp4")
    writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"mp4v"), fps, frames[0].shape[1::-1])
    for rgb in frames:
        writer.write(cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    writer.release()
    tmp.replace(out)


if __name__ == "__main__":
    raise SystemExit(main())
