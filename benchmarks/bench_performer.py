"""Benchmark of the demo's renderers: the digital performer and the Toy, per frame, against a reference.

The reference, measured in the same run, is the cheapest thing any frame of that size costs: a copy of a
frame plus OpenCV's 5 x 5 Gaussian blur of it (what a camera pipeline would do to every frame anyway). The
bar for the performer is 5 ms per 480 x 480 frame.

Run: ``python benchmarks/bench_performer.py [--frames 200] [--size 480]``
"""

from __future__ import annotations

import argparse
import sys
import time

import cv2
import numpy as np


def per_frame(fn, n: int) -> float:
    fn(0)  # warm caches
    t = time.perf_counter()
    for i in range(n):
        fn(i)
    return (time.perf_counter() - t) / n * 1e3


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=200)
    ap.add_argument("--size", type=int, default=480)
    args = ap.parse_args(argv)

    from facepuppet.demo.performer import performer_curves, render_performer
    from facepuppet.demo.script import performance_script
    from facepuppet.demo.toy import toy_character, toy_colors
    from facepuppet.export.render import Camera, render_mesh

    size = (args.size, args.size)
    script = performance_script(max(args.frames / 30.0, 5.0), 30.0, seed=0)
    rng = np.random.default_rng(0)
    n = min(args.frames, script.n_frames)
    frame = np.zeros((args.size, args.size, 3), np.uint8)

    def reference(i):
        cv2.GaussianBlur(frame.copy(), (5, 5), 0)

    def performer(i):
        render_performer(script.weights[i], script.head_motion[i], size, rng)

    def curves(i):
        performer_curves(script.weights[i], script.head_motion[i], size)

    toy = toy_character()
    cam = Camera.fit(toy.neutral, size)
    colors = toy_colors()
    deltas = toy.targets - toy.neutral[None]

    def toy_frame(i):
        v = toy.neutral + np.tensordot(script.weights[i], deltas, axes=1)
        render_mesh(v, toy.faces, camera=cam, colors=colors)

    ref = per_frame(reference, n)
    rows = [("performer frame", per_frame(performer, n)), ("performer true curves", per_frame(curves, n)),
            ("toy frame (render_mesh)", per_frame(toy_frame, n))]
    sys.stdout.write(f"{n} frames of {args.size} x {args.size}; reference (copy + 5x5 Gaussian blur): "
                     f"{ref:.3f} ms\n")
    sys.stdout.write(f"{'what':<26}{'ms/frame':>10}{'x reference':>13}\n")
    for name, ms in rows:
        sys.stdout.write(f"{name:<26}{ms:>10.3f}{ms / ref:>13.1f}\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
