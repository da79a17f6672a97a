"""The demo's error with the colour tracker, over several seeds (the bar of ``facepuppet demo`` is 0.5).

For each seed the whole demo runs with ``--tracker color`` (no preview) and with the true curves standing in
for a tracker; printed per seed: the relative vertex error of each (0 perfect, 1 = as far off as the
neutral face), the colour tracker's median curve error in pixels, and the wall time of the colour run.

Run: ``python benchmarks/eval_demo_color.py [--seeds 0 1 2] [--seconds 8] [--size 320] [--no-truth]``
(about 35 s per seed and tracker on one core; the first run also compiles the tracker, about a minute).
"""

from __future__ import annotations

import argparse
import sys
import tempfile

import numpy as np


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--seconds", type=float, default=8.0)
    ap.add_argument("--size", type=int, default=320)
    ap.add_argument("--no-truth", action="store_true", help="skip the runs with the true curves")
    args = ap.parse_args(argv)

    from facepuppet.demo.run import DemoConfig, run_demo

    colour, truth = [], []
    print(f"{'seed':>4}  {'color':>6}  {'curves px':>9}  {'seconds':>7}  {'truth':>6}")
    for seed in args.seeds:
        with tempfile.TemporaryDirectory() as tmp:
            c = run_demo(tmp, DemoConfig(seconds=args.seconds, size=args.size, seed=seed, tracker="color",
                                         preview=False, progress=False))
        colour.append(c.error)
        t_err = float("nan")
        if not args.no_truth:
            with tempfile.TemporaryDirectory() as tmp:
                t_err = run_demo(tmp, DemoConfig(seconds=args.seconds, size=args.size, seed=seed, tracker="truth",
                                                 preview=False, progress=False)).error
            truth.append(t_err)
        print(f"{seed:4d}  {c.error:6.3f}  {c.curve_error:9.2f}  {c.seconds:7.1f}  {t_err:6.3f}", flush=True)
    print(f"mean  {np.mean(colour):6.3f}" + (f"  {'':9}  {'':7}  {np.mean(truth):6.3f}" if truth else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
