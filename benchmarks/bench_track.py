"""Per-frame tracking time (after decoding) of the colour tracker vs the MediaPipe backend on the same frames.

  python benchmarks/bench_track.py [--frames N] [--model face_landmarker.task]

Decodes N frames of each shared clip first, then times only ``tracker.track`` per frame. Prints frames per
second for each backend and the ratio colour / MediaPipe (goal >= 10). The colour row is skipped with a note
while facepuppet.capture.color_tracker does not exist.
"""

import argparse
import os
import sys
import time
from pathlib import Path

import cv2

from facepuppet.capture.tracking import make_tracker
from facepuppet.errors import FacepuppetError

ROOT = Path(__file__).resolve().parents[1]
ASSETS = Path(os.environ.get("FACEPUPPET_ASSETS", ROOT.parent / "shared" / "assets"))
CLIPS = ("performer_a.mp4", "performer_b_exaggerated.mp4", "performer_c.mp4")


def decode(path, n):
    cap, frames = cv2.VideoCapture(str(path)), []
    while len(frames) < n:
        ok, bgr = cap.read()
        if not ok:
            break
        frames.append(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))
    cap.release()
    return frames


def fps(tracker, frames, fps_src=30.0):
    t0 = time.perf_counter()
    for i, rgb in enumerate(frames):
        tracker.track(rgb, int(round(i * 1000 / fps_src)))
    return len(frames) / (time.perf_counter() - t0)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=200)
    ap.add_argument("--model", default=os.environ.get("FACEPUPPET_FACE_LANDMARKER",
                                                       str(ASSETS / "models" / "face_landmarker.task")))
    args = ap.parse_args()
    cv2.setNumThreads(1)
    print(f"{'clip':28s} {'frames':>6s} {'color fps':>10s} {'mediapipe fps':>14s} {'ratio':>7s}")
    note = None
    for clip in CLIPS:
        frames = decode(ASSETS / "video" / clip, args.frames)
        mp = make_tracker("mediapipe", model_path=args.model)
        try:
            f_mp = fps(mp, frames)
        finally:
            mp.close()
        try:
            color = make_tracker("color")
            try:
                f_c = fps(color, frames)
            finally:
                color.close()
        except FacepuppetError as e:
            f_c, note = float("nan"), str(e)
        print(f"{clip:28s} {len(frames):6d} {f_c:10.0f} {f_mp:14.0f} {f_c / f_mp:7.2f}")
    if note:
        print(f"colour row skipped: {note}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
