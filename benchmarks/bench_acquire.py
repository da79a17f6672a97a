"""Finding the face afresh: the colour tracker's acquisition and the face cascade's part of it, upright only beside
upright and turned (:data:`facepuppet.capture.color.detect.TILTS`), on the same frames in the same run.

Each sampled frame (every ``--step``-th of the first ``--frames``) is searched by the cascade upright only and at
all tilts, in turns, ``--repeats`` times; a fresh colour tracker then finds the face in it (its first ``track``
call: the whole acquisition, the cascade included). Times are wall-clock milliseconds, medians over frames and
repeats; ``ratio``: all tilts over upright only, per frame, the median. Acquisition runs when a face is first
seen or lost, not per frame followed. The load average is printed before and after: on a loaded machine the
milliseconds are noise, the ratio less so.

    python benchmarks/bench_acquire.py [--frames 300] [--step 30] [--repeats 3] [CLIP ...]
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CLIPS = ("performer_a.mp4", "performer_b_exaggerated.mp4", "performer_c.mp4")


def _frames(path: Path, frames: int, step: int) -> list[np.ndarray]:
    import cv2

    cap = cv2.VideoCapture(str(path))
    out = []
    for k in range(frames):
        ok, bgr = cap.read()
        if not ok:
            break
        if k % step == 0:
            out.append(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))
    cap.release()
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("clips", nargs="*", help="videos (default: the shared clips)")
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--step", type=int, default=30)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args(argv)
    from facepuppet.capture.color.detect import TILTS, face_windows
    from facepuppet.capture.color.tracker import ColorTracker

    clips = [Path(c) for c in args.clips] or [ROOT.parent / "shared" / "assets" / "video" / c for c in CLIPS]
    for c in clips:
        if not c.is_file():
            ap.error(f"{c}: no such video")
    print(f"load average before: {' '.join(f'{v:.2f}' for v in os.getloadavg())}; tilts {TILTS}")
    print(f"{'clip':30s} {'upright ms':>10s} {'tilts ms':>9s} {'ratio':>6s} {'acquire ms':>10s} {'found':>6s}")
    ColorTracker().track(_frames(clips[0], 1, 1)[0], 0)           # compiled kernels loaded, untimed
    for clip in clips:
        frames = _frames(clip, args.frames, args.step)
        up, all_, ratios, acq, found = [], [], [], [], []
        for _ in range(args.repeats):
            for rgb in frames:
                t0 = time.perf_counter()
                face_windows(rgb, tilts=(0.0,))
                t1 = time.perf_counter()
                face_windows(rgb)
                t2 = time.perf_counter()
                up.append(t1 - t0)
                all_.append(t2 - t1)
                ratios.append((t2 - t1) / max(t1 - t0, 1e-9))
                tracker = ColorTracker()
                t0 = time.perf_counter()
                f = tracker.track(rgb, 0)
                acq.append(time.perf_counter() - t0)
                found.append(f.valid)
        print(f"{clip.name:30s} {1e3 * np.median(up):10.1f} {1e3 * np.median(all_):9.1f} {np.median(ratios):6.2f} "
              f"{1e3 * np.median(acq):10.1f} {np.mean(found):6.2f}")
    print(f"load average after: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
