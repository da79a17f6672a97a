"""Tracking speed after decoding: the colour tracker beside the MediaPipe backend on the same frames.

Each clip's frames are decoded once into memory; then each backend (a fresh tracker per clip, after a warm-up)
tracks them in order and only its ``track`` calls are timed, in process CPU time. By default the process is pinned
to one CPU core (the budget: the colour tracker >= 1,000 frames/s on one core, ten times MediaPipe or
more, on each clip). The colour tracker's column ``searches`` counts its fresh searches for the face (the first
frame's included): a tracker that keeps following the face it found searches once per clip. A backend that cannot
be built (colour tracker not importable, mediapipe or its model missing) gets a row saying why. The header
gives the machine's load average: timings on a loaded machine are noise.

    python benchmarks/bench_track.py [--frames 300] [--model face_landmarker.task] [--all-cores] [CLIP ...]
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
ASSETS = Path(os.environ.get("FACEPUPPET_ASSETS", ROOT.parent / "shared" / "assets"))
CLIPS = ("performer_a.mp4", "performer_b_exaggerated.mp4", "performer_c.mp4")
BUDGET_FPS = 1000.0  # colour tracker, frames per second on one core
GOAL_RATIO = 10.0  # colour tracker's speed over MediaPipe's


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


def warm_up(backend: str, options: dict, frames: list[np.ndarray]) -> None:
    """Track a few frames with a throwaway tracker: one-off costs of the process (loading the compiled
    kernels from numba's cache, the model's first inference) are not per-frame work."""
    from facepuppet.capture.tracking import make_tracker

    tracker = make_tracker(backend, **options)
    try:
        for i, rgb in enumerate(frames[:3]):
            tracker.track(rgb, i * 33)
    finally:
        tracker.close()


def time_backend(backend: str, options: dict, frames: list[np.ndarray], fps: float) -> tuple[float, float, int]:
    """(frames per second of the track calls, fraction of frames with a face, fresh searches for the face or -1
    where the backend does not count them), with a fresh tracker.

    Time is the process's CPU time (all its threads, on the one core it is pinned to): on a shared machine
    the wall clock also counts other programs' turns on that core.

    The timed run starts from a fresh tracker, so it includes finding the face in the first frame.
    """
    from facepuppet.capture.tracking import make_tracker

    tracker = make_tracker(backend, **options)
    try:
        valid = 0
        step = 1000.0 / fps
        t0 = time.process_time()
        for i, rgb in enumerate(frames):
            valid += tracker.track(rgb, int(round(i * step))).valid
        elapsed = time.process_time() - t0
        searches = int(getattr(tracker, "searches", -1))
    finally:
        tracker.close()
    return len(frames) / elapsed, valid / len(frames), searches


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("clips", nargs="*", metavar="CLIP", help="videos (default: the three shared clips)")
    ap.add_argument("--frames", type=int, default=300, help="frames per clip (default 300)")
    ap.add_argument("--model", help="face_landmarker.task (default $FACEPUPPET_FACE_LANDMARKER or the shared one)")
    ap.add_argument("--profile", help="colour tracker's performer profile")
    ap.add_argument("--all-cores", action="store_true", help="do not pin the process to one core")
    args = ap.parse_args(argv)

    import cv2

    if not args.all_cores and hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
        cv2.setNumThreads(1)
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    model = args.model or os.environ.get("FACEPUPPET_FACE_LANDMARKER") or str(ASSETS / "models" /
                                                                                "face_landmarker.task")
    clips = [Path(c) for c in args.clips] or [ASSETS / "video" / c for c in CLIPS]
    backends = {"color": {"profile": args.profile} if args.profile else {},
                "mediapipe": {"model_path": model}}

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"tracking speed after decoding (CPU time), {args.frames} frames per clip, {cores} core(s), "
          f"load average {load:.2f}")
    print(f"{'clip':30s} {'frames':>6s} {'colour fps':>11s} {'found':>6s} {'searches':>8s} {'mediapipe fps':>14s} "
          f"{'found':>6s} {'ratio':>7s}  budget")
    totals: dict[str, list[float]] = {"color": [], "mediapipe": []}
    for clip in clips:
        if not clip.is_file():
            print(f"{clip.name:30s} missing ({clip})")
            continue
        frames, fps = decode(clip, args.frames)
        res: dict[str, tuple[float, float] | str] = {}
        for name, opts in backends.items():
            try:
                warm_up(name, opts, frames)
                res[name] = time_backend(name, opts, frames, fps)
            except Exception as e:  # noqa: BLE001 - a benchmark reports a missing backend instead of stopping
                res[name] = f"{type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}"[:200]
        cells = []
        for name in backends:
            r = res[name]
            if isinstance(r, str):
                cells.append(f"{'-':>11s} {'-':>6s} {'-':>8s}" if name == "color" else f"{'-':>14s} {'-':>6s}")
            elif name == "color":
                totals[name].append(r[0])
                cells.append(f"{r[0]:11.0f} {r[1]:6.2f} {r[2]:8d}")
            else:
                totals[name].append(r[0])
                cells.append(f"{r[0]:14.0f} {r[1]:6.2f}")
        c, m = res["color"], res["mediapipe"]
        both = not isinstance(c, str) and not isinstance(m, str)
        ratio = f"{c[0] / m[0]:7.1f}" if both else f"{'-':>7s}"
        verdict = []
        if not isinstance(c, str) and c[0] < BUDGET_FPS:
            verdict.append(f"under {BUDGET_FPS:.0f} fps")
        if both and c[0] / m[0] < GOAL_RATIO:
            verdict.append(f"under {GOAL_RATIO:.0f}x")
        verdict = ", ".join(verdict) or "ok"
        print(f"{clip.name:30s} {len(frames):6d} {cells[0]} {cells[1]} {ratio}  {verdict}")
        for name in backends:
            if isinstance(res[name], str):
                print(f"  {name} backend unavailable: {res[name]}")
    if totals["color"] and totals["mediapipe"]:
        c, m = np.mean(totals["color"]), np.mean(totals["mediapipe"])
        print(f"{'mean':30s} {'':6s} {c:11.0f} {'':6s} {m:14.0f} {'':6s} {c / m:7.1f}  "
              f"goal: colour >= {BUDGET_FPS:.0f} fps and >= {GOAL_RATIO:.0f}x MediaPipe")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
