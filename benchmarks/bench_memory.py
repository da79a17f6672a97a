"""Peak memory of `facepuppet track` and `facepuppet animate` against the take's length.

Long videos are made from the shared clips (their frames looped, written with OpenCV into a temporary folder),
then each command runs in a child process, which reports its own peak resident memory (``VmHWM`` of
``/proc/self/status`` as it exits: the high-water mark of its own address space since ``exec``; the ``ru_maxrss``
that ``wait4`` returns also counts the parent's pages, which the child shared until ``exec``). The bar: the
peak grows by at most 30 MB from the shortest to the longest take (memory flat in the take's length).
`animate` tracks the video itself (no ``--track``) and writes GLB and CSV.

Usage::

    PYTHONPATH=src python benchmarks/bench_memory.py                 # 1, 10 and 20 minutes
    PYTHONPATH=src python benchmarks/bench_memory.py --minutes 0.5 2 --size 240
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
ASSETS = Path(os.environ.get("FACEPUPPET_ASSETS", ROOT.parent / "shared" / "assets"))
#: Growth of the peak allowed from the shortest to the longest take, MB.
BAR_MB = 30.0


def make_video(path: Path, minutes: float, size: int | None) -> int:
    """Loop the shared clips' frames into ``minutes`` of 30 fps video; returns the frame count."""
    import cv2

    frames = []
    for clip in ("performer_a.mp4", "performer_c.mp4"):
        cap = cv2.VideoCapture(str(ASSETS / "video" / clip))
        while len(frames) < 600:
            ok, bgr = cap.read()
            if not ok:
                break
            if size:
                bgr = cv2.resize(bgr, (size, size), interpolation=cv2.INTER_AREA)
            frames.append(bgr)
        cap.release()
    if not frames:
        raise SystemExit(f"no clips under {ASSETS / 'video'}")
    n = int(round(minutes * 60 * 30))
    h, w = frames[0].shape[:2]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, (w, h))
    for k in range(n):
        # forward then backward through the frames: no jump where the loop starts again
        period = 2 * len(frames) - 2
        j = k % period
        writer.write(frames[j if j < len(frames) else period - j])
    writer.release()
    return n


def make_rig(path: Path) -> None:
    """A rig of the built-in Toy fitted to synthetic key expressions (memory does not depend on its fit)."""
    from facepuppet.capture import POINT_NAMES
    from facepuppet.demo.toy import toy_character
    from facepuppet.io.performer import Performer
    from facepuppet.pipeline.rig import fit_rig, save_rig

    toy = toy_character()
    rng = np.random.default_rng(0)
    neutral = rng.normal(0, 3, (len(POINT_NAMES), 3))
    examples = neutral[None] + rng.normal(0, 0.5, (len(toy.names), len(POINT_NAMES), 3))
    rig, _ = fit_rig(Performer(neutral, examples, tuple(toy.names), tuple(POINT_NAMES), backend="color"), toy)
    save_rig(path, rig)


def peak_mb(argv: list[str]) -> tuple[float, float]:
    """Run ``python -m facepuppet ARGV``; (peak resident memory in MB, seconds)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", _CHILD, *argv], env=env, stdout=subprocess.DEVNULL,
                          stderr=subprocess.PIPE, check=False)
    err = proc.stderr.decode(errors="replace").strip()
    if proc.returncode != 0:
        raise SystemExit(f"facepuppet {' '.join(argv)} failed: {err}")
    marks = [line for line in err.splitlines() if line.startswith(_MARK)]
    if not marks:
        raise SystemExit(f"facepuppet {' '.join(argv)}: no peak memory reported ({err})")
    return float(marks[-1][len(_MARK):]) / 1024.0, time.perf_counter() - t0


#: What the child prints last on stderr: its peak resident memory in kB.
_MARK = "bench_memory VmHWM kB "
#: The child: `python -m facepuppet ARGV`, then its own high-water mark (an atexit hook, so after the CLI exits).
_CHILD = f"""
import atexit, runpy, sys

def _peak():
    with open("/proc/self/status") as fh:
        kb = next(line.split()[1] for line in fh if line.startswith("VmHWM:"))
    sys.stderr.write("\\n{_MARK}" + kb + "\\n")

atexit.register(_peak)
sys.argv = ["facepuppet", *sys.argv[1:]]
runpy.run_module("facepuppet", run_name="__main__", alter_sys=True)
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, nargs="+", default=[1.0, 10.0, 20.0])
    ap.add_argument("--size", type=int, default=None, help="scale the frames to SIZE x SIZE (faster)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench_memory_") as tmp:
        tmp = Path(tmp)
        make_rig(tmp / "rig.npz")
        # the colour tracker's kernels compile (or load from numba's cache) before anything is measured
        warm = tmp / "warm.mp4"
        make_video(warm, 0.05, args.size)
        peak_mb(["track", str(warm), "-o", str(tmp / "warm.npz"), "--no-progress"])
        rows = []
        for minutes in args.minutes:
            video = tmp / f"take_{minutes:g}.mp4"
            n = make_video(video, minutes, args.size)
            track, t_track = peak_mb(["track", str(video), "-o", str(tmp / "t.npz"), "--no-progress"])
            anim, t_anim = peak_mb(["animate", str(video), "--rig", str(tmp / "rig.npz"), "-o", str(tmp / "a.glb"),
                                    "--csv", str(tmp / "a.csv"), "--no-progress"])
            rows.append((minutes, n, track, anim, t_track, t_anim))
            video.unlink()
            print(f"{minutes:6g} min {n:7d} frames   track {track:7.1f} MB ({t_track:6.0f} s)   "
                  f"animate {anim:7.1f} MB ({t_anim:6.0f} s)", flush=True)
    first, last = rows[0], rows[-1]
    for name, i in (("track", 2), ("animate", 3)):
        growth = last[i] - first[i]
        print(f"{name}: peak {first[i]:.1f} MB at {first[0]:g} min -> {last[i]:.1f} MB at {last[0]:g} min: "
              f"growth {growth:+.1f} MB (bar {BAR_MB:g} MB: {'met' if growth <= BAR_MB else 'NOT met'})")


if __name__ == "__main__":
    main()
