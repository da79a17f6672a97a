"""Tracking speed after decoding: the colour tracker beside the MediaPipe backend on the same frames, interleaved.

Each clip's frames are decoded once into memory; only the backends' ``track`` calls are timed (decoding is not).
The two backends take turns over the same frames in short chunks (``--chunk`` frames: the colour tracker's chunk,
then MediaPipe's on the same frames, the order swapped every chunk), each backend's tracker following the clip
across its chunks, so that a change of the machine's load meets both alike; the whole clip is tracked so
``--repeats`` times, each time by fresh trackers (made untimed). Before timing, a throwaway tracker of each backend
tracks a few frames: loading the compiled kernels from numba's cache and MediaPipe's first inference are costs of
the process, not per-frame work. A fresh tracker's first frame (finding the face) is timed, in the first chunk.

Time is taken as the process's CPU time (all its threads; :func:`time.process_time`) and as the wall clock
(:func:`time.perf_counter`) around each chunk. The figure of merit is each chunk's ratio of MediaPipe's time to the
colour tracker's on the same frames: the median over all chunks of all repeats, with its interquartile range
(the middle half of the chunks' ratios). By default the process is pinned to one CPU core and the native pools
of OpenCV, FFmpeg and BLAS get one thread; MediaPipe starts threads of its own (its graph's executors and
inference), which then share that core, and the CPU time counts all of them: both backends get the same one core.
``--all-cores`` pins nothing (then MediaPipe's threads may spread over the cores, and its CPU time is the sum).

Columns: ``colour ms``, ``mediapipe ms``: CPU milliseconds per frame (all timed frames over their CPU time);
``ratio`` (by CPU time) and ``wall ratio``: medians of the chunks' ratios, ``IQR`` the quartiles of the CPU ones;
``found``: fraction of frames with a face; ``searches``: the colour tracker's fresh searches for the face per
repeat (1: it found the face in the first frame and followed it). The header gives the load average before and
after: on a loaded machine the per-frame times are noise, the interleaved ratio much less so. A backend that
cannot be built gets a line saying why.

    python benchmarks/bench_track.py [--frames 300] [--repeats 3] [--chunk 10] [--model face_landmarker.task]
                                     [--profile P.npz] [--all-cores] [CLIP ...]
"""

from __future__ import annotations

import argparse
import gc
import os
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
ASSETS = Path(os.environ.get("FACEPUPPET_ASSETS", ROOT.parent / "shared" / "assets"))
CLIPS = ("performer_a.mp4", "performer_b_exaggerated.mp4", "performer_c.mp4")
BUDGET_FPS = 1000.0  # colour tracker, frames per second on one core
GOAL_RATIO = 10.0  # colour tracker's speed over MediaPipe's
BACKENDS = ("color", "mediapipe")


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


def thread_count() -> int:
    """Threads of this process (Linux), or -1."""
    try:
        return len(os.listdir("/proc/self/task"))
    except OSError:
        return -1


def warm_up(backend: str, options: dict, frames: list[np.ndarray]) -> None:
    """Track a few frames with a throwaway tracker: one-off costs of the process (loading the compiled
    kernels from numba's cache, the model's first inference) are not per-frame work."""
    from facepuppet.capture.tracking import make_tracker

    tracker = make_tracker(backend, **options)
    try:
        for i, rgb in enumerate(frames[:5]):
            tracker.track(rgb, i * 33)
    finally:
        tracker.close()


def interleaved(options: dict[str, dict], frames: list[np.ndarray], fps: float, chunk: int) -> dict:
    """One pass over ``frames`` by a fresh tracker of each backend, taking turns every ``chunk`` frames.

    Returns
    -------
    dict
        ``cpu``, ``wall``: {backend: (n_chunks,) seconds}; ``valid``: {backend: frames with a face};
        ``searches``: the colour tracker's fresh searches for the face.
    """
    from facepuppet.capture.tracking import make_tracker

    trackers = {b: make_tracker(b, **options[b]) for b in BACKENDS}
    stamps = [int(round(i * 1000.0 / fps)) for i in range(len(frames))]
    n_chunks = (len(frames) + chunk - 1) // chunk
    cpu = {b: np.zeros(n_chunks) for b in BACKENDS}
    wall = {b: np.zeros(n_chunks) for b in BACKENDS}
    valid = dict.fromkeys(BACKENDS, 0)
    gc.collect()
    try:
        for j in range(n_chunks):
            lo, hi = j * chunk, min((j + 1) * chunk, len(frames))
            for b in (BACKENDS if j % 2 == 0 else BACKENDS[::-1]):
                track, ok = trackers[b].track, 0
                w0, c0 = time.perf_counter(), time.process_time()
                for i in range(lo, hi):
                    ok += track(frames[i], stamps[i]).valid
                c1, w1 = time.process_time(), time.perf_counter()
                cpu[b][j], wall[b][j], valid[b] = c1 - c0, w1 - w0, valid[b] + ok
        searches = int(getattr(trackers["color"], "searches", -1))
    finally:
        for t in trackers.values():
            t.close()
    return {"cpu": cpu, "wall": wall, "valid": valid, "searches": searches}


def quartiles(x: np.ndarray) -> tuple[float, float, float]:
    """(25th, 50th, 75th) percentiles of ``x``."""
    q = np.percentile(np.asarray(x, dtype=float), [25, 50, 75])
    return float(q[0]), float(q[1]), float(q[2])


def pin_one_core() -> None:
    """Pin the process to one core and give the native pools (OpenCV, FFmpeg's decoder, BLAS) one thread."""
    import cv2

    from facepuppet.batch.worker import share_cores

    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    share_cores(1)
    cv2.setNumThreads(1)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("clips", nargs="*", metavar="CLIP", help="videos (default: the three shared clips)")
    ap.add_argument("--frames", type=int, default=300, help="frames per clip (default 300)")
    ap.add_argument("--repeats", type=int, default=3, help="passes over each clip, fresh trackers each (default 3)")
    ap.add_argument("--chunk", type=int, default=10, help="frames per turn of each backend (default 10)")
    ap.add_argument("--model", help="face_landmarker.task (default $FACEPUPPET_FACE_LANDMARKER or the shared one)")
    ap.add_argument("--profile", help="colour tracker's performer profile")
    ap.add_argument("--all-cores", action="store_true", help="do not pin the process to one core")
    args = ap.parse_args(argv)
    if args.frames < 1 or args.repeats < 1 or args.chunk < 1:
        ap.error("--frames, --repeats and --chunk must be >= 1")

    if not args.all_cores:
        pin_one_core()
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    model = args.model or os.environ.get("FACEPUPPET_FACE_LANDMARKER") or str(ASSETS / "models" /
                                                                                "face_landmarker.task")
    clips = [Path(c) for c in args.clips] or [ASSETS / "video" / c for c in CLIPS]
    options = {"color": {"profile": args.profile} if args.profile else {}, "mediapipe": {"model_path": model}}

    load0 = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    print(f"tracking speed after decoding: track() calls only, {args.frames} frames per clip, {args.repeats} "
          f"repeats, backends interleaved every {args.chunk} frames, {cores} core(s) "
          f"{'(pinned)' if not args.all_cores else '(not pinned)'}")
    print(f"load average at start {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}")
    head = (f"{'clip':28s} {'frames':>6s} {'colour ms':>9s} {'found':>5s} {'searches':>8s} {'mediapipe ms':>12s} "
            f"{'found':>5s} {'ratio':>6s} {'IQR':>11s} {'wall ratio':>10s}  verdict")
    print(head)
    pooled, pooled_wall, threads = [], [], None
    for clip in clips:
        if not clip.is_file():
            print(f"{clip.name:28s} missing ({clip})")
            continue
        frames, fps = decode(clip, args.frames)
        try:
            for b in BACKENDS:
                before = thread_count()
                warm_up(b, options[b], frames)
                if b == "mediapipe" and threads is None:
                    threads = thread_count() - before
            runs = [interleaved(options, frames, fps, args.chunk) for _ in range(args.repeats)]
        except Exception as e:  # noqa: BLE001 - a benchmark reports a missing backend instead of stopping
            print(f"{clip.name:28s} backend unavailable: "
                  f"{type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}"[:200])
            continue
        cpu = {b: np.concatenate([r["cpu"][b] for r in runs]) for b in BACKENDS}
        wall = {b: np.concatenate([r["wall"][b] for r in runs]) for b in BACKENDS}
        ratio = cpu["mediapipe"] / np.maximum(cpu["color"], 1e-9)
        wall_ratio = wall["mediapipe"] / np.maximum(wall["color"], 1e-9)
        pooled.append(ratio)
        pooled_wall.append(wall_ratio)
        n = len(frames) * args.repeats
        ms = {b: 1e3 * cpu[b].sum() / n for b in BACKENDS}
        found = {b: sum(r["valid"][b] for r in runs) / n for b in BACKENDS}
        searches = "/".join(str(r["searches"]) for r in runs)
        q1, med, q3 = quartiles(ratio)
        verdict = []
        if 1e3 / ms["color"] < BUDGET_FPS:
            verdict.append(f"under {BUDGET_FPS:.0f} fps")
        if med < GOAL_RATIO:
            verdict.append(f"under {GOAL_RATIO:.0f}x")
        print(f"{clip.name:28s} {len(frames):6d} {ms['color']:9.2f} {found['color']:5.2f} {searches:>8s} "
                    f"{ms['mediapipe']:12.2f} {found['mediapipe']:5.2f} {med:6.1f} {q1:5.1f}-{q3:<5.1f} "
                    f"{np.median(wall_ratio):10.1f}  {', '.join(verdict) or 'ok'}", flush=True)
    if not pooled:
        return 0
    q1, med, q3 = quartiles(np.concatenate(pooled))
    print(f"{'all chunks':28s} {'':6s} {'':9s} {'':5s} {'':8s} {'':12s} {'':5s} {med:6.1f} {q1:5.1f}-{q3:<5.1f} "
          f"{np.median(np.concatenate(pooled_wall)):10.1f}  goal: colour >= {BUDGET_FPS:.0f} fps and ratio >= "
          f"{GOAL_RATIO:.0f}x")
    load1 = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    print(f"load average at end {load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f}; MediaPipe's own threads: "
          f"{threads if threads is not None else '?'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
