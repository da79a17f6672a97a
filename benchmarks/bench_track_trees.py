"""Tracking speed of the colour tracker of two source trees side by side, on the same frames, in lockstep.

Each tree runs in a worker process of its own (``PYTHONPATH`` set to the tree's ``src``), both pinned to the same
CPU core with one thread per native pool (as :mod:`bench_track` pins itself); each decodes the clips once into
memory and warms its kernels up. The driver then has them track the same chunk of ``--chunk`` frames in turn (the
order swapped every chunk), each tree's tracker following the clip across its chunks, a fresh tracker per clip and
repeat, so that a change of the machine's load meets both alike. Only the ``track`` calls are timed, as the
worker's CPU time (:func:`time.thread_time`: the colour tracker runs on one thread).

Columns: ``A ms``, ``B ms``: CPU milliseconds per frame; ``A/B``: the total time's ratio, and the median and
quartiles of the chunks' ratios (above 1: B is faster). The load average is printed before and after.

    python benchmarks/bench_track_trees.py TREE_A TREE_B [--frames 300] [--repeats 2] [--chunk 10] [CLIP ...]

``TREE_A``, ``TREE_B``: repository roots (or their ``src`` folders), e.g. the main tree and a branch's worktree.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
ASSETS = Path(os.environ.get("FACEPUPPET_ASSETS", ROOT.parent / "shared" / "assets"))
CLIPS = ("performer_a.mp4", "performer_b_exaggerated.mp4", "performer_c.mp4")


def _worker(frames: int, clips: list[str]) -> int:
    """Serve the driver on stdin/stdout: ``new CLIP`` makes a fresh tracker, ``run CLIP LO HI`` tracks frames
    LO..HI-1 of the clip and answers the CPU seconds it took."""
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    from facepuppet.batch.worker import share_cores
    from facepuppet.capture.tracking import make_tracker
    from facepuppet.io.frames import open_media

    share_cores(1)
    decoded = {}
    for clip in clips:
        got = []
        with open_media(clip) as src:
            for rgb in src:
                got.append(rgb)
                if len(got) >= frames:
                    break
        decoded[clip] = got
    warm = make_tracker("color")
    for i, rgb in enumerate(decoded[clips[0]][:5]):
        warm.track(rgb, i * 33)
    warm.close()
    trackers = {}
    print(json.dumps({c: len(v) for c, v in decoded.items()}), flush=True)
    for line in sys.stdin:
        cmd = line.split()
        if cmd[0] == "new":
            trackers[cmd[1]] = make_tracker("color")
            print("ok", flush=True)
            continue
        clip, lo, hi = cmd[1], int(cmd[2]), int(cmd[3])
        track, got = trackers[clip].track, decoded[clip]
        c0 = time.thread_time()
        for i in range(lo, hi):
            track(got[i], int(round(i * 1000.0 / 30.0)))
        print(time.thread_time() - c0, flush=True)
    return 0


def _src(tree: str) -> str:
    """The ``src`` folder of a tree (the tree itself if it is one)."""
    p = Path(tree).resolve()
    return str(p / "src" if (p / "src" / "facepuppet").is_dir() else p)


def _ask(proc: subprocess.Popen, line: str) -> str:
    proc.stdin.write(line + "\n")
    proc.stdin.flush()
    return proc.stdout.readline().strip()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("tree_a", help="first source tree (repository root or its src)")
    ap.add_argument("tree_b", help="second source tree")
    ap.add_argument("clips", nargs="*", metavar="CLIP", help="videos (default: the three shared clips)")
    ap.add_argument("--frames", type=int, default=300, help="frames per clip (default 300)")
    ap.add_argument("--repeats", type=int, default=2, help="passes over each clip, fresh trackers each (default 2)")
    ap.add_argument("--chunk", type=int, default=10, help="frames per turn of each tree (default 10)")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    clips = [str(c) for c in args.clips] or [str(ASSETS / "video" / c) for c in CLIPS]
    if args.worker:
        return _worker(args.frames, clips)
    if args.frames < 1 or args.repeats < 1 or args.chunk < 1:
        ap.error("--frames, --repeats and --chunk must be >= 1")
    missing = [c for c in clips if not Path(c).is_file()]
    if missing:
        ap.error(f"no such clip: {missing[0]}")
    trees = [_src(args.tree_a), _src(args.tree_b)]
    for t in trees:
        if not (Path(t) / "facepuppet").is_dir():
            ap.error(f"{t}: not a facepuppet source tree")
    procs = []
    for t in trees:
        env = dict(os.environ, PYTHONPATH=t)
        procs.append(subprocess.Popen([sys.executable, __file__, t, t, *clips, "--frames", str(args.frames),
                                       "--worker"], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                                      env=env))
    try:
        lengths = [json.loads(p.stdout.readline()) for p in procs][0]
        load0 = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
        print(f"colour tracker, tree A {trees[0]} against tree B {trees[1]}: {args.frames} frames per clip, "
              f"{args.repeats} repeats, turns every {args.chunk} frames, one core")
        print(f"load average at start {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}")
        print(f"{'clip':28s} {'A ms':>7s} {'B ms':>7s} {'A/B':>6s} {'chunks A/B':>10s} {'IQR':>11s}")
        total, pooled = np.zeros(2), []
        for clip in clips:
            n = lengths[clip]
            spent, ratios = np.zeros(2), []
            for _ in range(args.repeats):
                for p in procs:
                    _ask(p, f"new {clip}")
                for j, lo in enumerate(range(0, n, args.chunk)):
                    hi = min(lo + args.chunk, n)
                    took = np.zeros(2)
                    for k in ((0, 1) if j % 2 == 0 else (1, 0)):
                        took[k] = float(_ask(procs[k], f"run {clip} {lo} {hi}"))
                    spent += took
                    ratios.append(took[0] / max(took[1], 1e-9))
            q1, med, q3 = np.percentile(ratios, [25, 50, 75])
            frames = n * args.repeats
            print(f"{Path(clip).name:28s} {1e3 * spent[0] / frames:7.3f} {1e3 * spent[1] / frames:7.3f} "
                  f"{spent[0] / spent[1]:6.3f} {med:10.3f} {q1:5.3f}-{q3:<5.3f}", flush=True)
            total += spent
            pooled += ratios
        q1, med, q3 = np.percentile(pooled, [25, 50, 75])
        print(f"{'all chunks':28s} {'':7s} {'':7s} {total[0] / total[1]:6.3f} {med:10.3f} {q1:5.3f}-{q3:<5.3f}")
        load1 = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
        print(f"load average at end {load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f}")
    finally:
        for p in procs:
            p.stdin.close()
            p.wait()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
