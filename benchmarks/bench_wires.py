"""Speed of the wire deformer, next to a plain-numpy reference measured in the same run.

Budget (issue 17): deforming an 11,248-vertex mesh with 12 wires <= 2 ms per frame after the bind. Uses the
ICT-FaceKit face from ../shared/assets when present (or $FACEPUPPET_ASSETS) with 12 wires found from its
key-models, else a synthetic mesh of the same size with 12 straight-ish wires. The reference deforms every
vertex with every wire (dense (12, 11248) arrays from the same bind), then combines.

    python benchmarks/bench_wires.py [--repeat 200] [--radius 0.08]
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

from facepuppet.io.character import Character
from facepuppet.synthesis import WireDeformer, bind_points, falloff, find_wire_paths

ROOT = Path(__file__).resolve().parents[1]
N_VERTICES, N_WIRES = 11248, 12


def scene(rng: np.random.Generator) -> tuple[str, np.ndarray, list[np.ndarray], np.ndarray]:
    """(source, vertices (V, 3), reference curves, wire curves per key-model (M, n_wires) list of lists)."""
    path = Path(os.environ.get("FACEPUPPET_ASSETS", ROOT.parent / "shared" / "assets"))
    path = path / "ict-facekit" / "ict_face_light.npz"
    if path.is_file():
        with np.load(path) as d:
            base = d["neutral"].astype(float)
            targets = base[None] + d["expr_deltas"].astype(float)
            ch = Character(neutral=base, targets=targets, names=tuple(map(str, d["expr_names"])),
                           faces=d["faces"])
        paths = list(find_wire_paths(ch).values())[:N_WIRES]
        return "ICT-FaceKit", base, [base[p] for p in paths], [[t[p] for p in paths] for t in targets]
    base = rng.uniform(-10, 10, size=(N_VERTICES, 3))
    refs = []
    for _ in range(N_WIRES):
        a = rng.uniform(-8, 8, size=3)
        refs.append(a + np.linspace(0, 1, 15)[:, None] * rng.normal(scale=4, size=3))
    keys = [[r + rng.normal(scale=0.5, size=r.shape) for r in refs] for _ in range(20)]
    return "synthetic", base, refs, keys


def reference_deform(points, binds, refs, wires, radii, scales, exponent=1.0):
    """Plain numpy: every wire on every point (dense, bind given), then the displacement-weighted combination."""
    deltas, weights = [], []
    for b, ref, wire, r, s in zip(binds, refs, wires, radii, scales, strict=True):
        f = falloff(b.distance / r)[:, None]
        seg, t = b.seg, b.t[:, None]
        rp = b.closest
        wp = (1 - t) * wire[seg] + t * wire[seg + 1]

        def tangent(c, seg=seg, t=t):
            e = np.diff(c, axis=0)
            e /= np.linalg.norm(e, axis=1, keepdims=True) + 1e-300
            v = np.zeros_like(c)
            v[:-1] += e
            v[1:] += e
            v /= np.linalg.norm(v, axis=1, keepdims=True) + 1e-300
            g = (1 - t) * v[seg] + t * v[seg + 1]
            return g / (np.linalg.norm(g, axis=1, keepdims=True) + 1e-300)

        tr, tw = tangent(ref), tangent(wire)
        v = (points - rp) * (1 + (s - 1) * f)
        ax = np.cross(tr, tw)
        sn = np.linalg.norm(ax, axis=1, keepdims=True)
        k = np.where(sn > 1e-12, ax / np.maximum(sn, 1e-300), 0.0)
        ang = f * np.arctan2(sn, np.sum(tr * tw, axis=1, keepdims=True))
        v = v * np.cos(ang) + np.cross(k, v) * np.sin(ang) + k * np.sum(k * v, 1, keepdims=True) * (1 - np.cos(ang))
        delta = rp + v + f * (wp - rp) - points
        deltas.append(delta)
        weights.append(np.where(f[:, 0] > 0, np.linalg.norm(delta, axis=1) ** exponent, 0.0))
    d, w = np.stack(deltas), np.stack(weights)
    den = w.sum(axis=0)
    num = np.einsum("kn,knj->nj", w, d)
    return points + np.divide(num, den[:, None], out=np.zeros_like(num), where=den[:, None] > 0)


def timings(fn, repeat: int) -> tuple[float, float]:
    """(median, fastest) seconds per call over ``repeat`` calls after one warm-up."""
    fn()
    times = np.empty(repeat)
    for i in range(repeat):
        t = time.perf_counter()
        fn()
        times[i] = time.perf_counter() - t
    return float(np.median(times)), float(times.min())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=200, help="timed frames per figure")
    ap.add_argument("--radius", type=float, default=0.08, help="wire radius, fraction of the bbox diagonal")
    args = ap.parse_args(argv)
    rng = np.random.default_rng(7)
    source, base, refs, keys = scene(rng)
    diag = float(np.linalg.norm(np.ptp(base, axis=0)))
    radii = np.full(len(refs), args.radius * diag)
    scales = np.linspace(0.9, 1.2, len(refs))
    frames = []
    for _ in range(16):                       # wire curves of a blended frame: random weights of the keys
        w = rng.uniform(0, 1, size=len(keys)) / len(keys) * 4
        frames.append([r + sum(w[i] * (keys[i][k] - r) for i in range(len(keys))) for k, r in enumerate(refs)])

    t = time.perf_counter()
    d = WireDeformer(base, refs, radii)
    bind = time.perf_counter() - t
    got = d.deform(frames[0], scales)
    binds = [bind_points(base, r) for r in refs]
    want = reference_deform(base, binds, refs, frames[0], radii, scales)
    err = float(np.abs(got - want).max())
    it = iter(range(10**9))
    fast, fast_min = timings(lambda: d.deform(frames[next(it) % 16], scales), args.repeat)
    ref, ref_min = timings(lambda: reference_deform(base, binds, refs, frames[next(it) % 16], radii, scales),
                           max(5, args.repeat // 4))
    d64 = WireDeformer(base, refs, radii, compiled=False)
    err64 = float(np.abs(d64.deform(frames[0], scales) - want).max())
    np64, np64_min = timings(lambda: d64.deform(frames[next(it) % 16], scales), args.repeat)
    d32 = WireDeformer(base, refs, radii, dtype=np.float32, compiled=False)
    err32 = float(np.abs(d32.deform(frames[0], scales) - want).max())
    fast32, fast32_min = timings(lambda: d32.deform(frames[next(it) % 16], scales), args.repeat)
    x = np.ones(len(d.pair_point))
    op, _ = timings(lambda: x * x, args.repeat)
    print(f"source: {source}, {len(base)} vertices, {len(refs)} wires, radius {radii[0]:.3g} "
          f"({args.radius:g} x diagonal), {len(d.pair_point)} bound (wire, vertex) pairs")
    print(f"{'figure':40s} {'value':>10s}")
    print(f"{'bind (ms, once)':40s} {bind * 1e3:10.2f}")
    print(f"{'WireDeformer.deform, compiled (ms/frame)':40s} {fast * 1e3:10.3f}   fastest {fast_min * 1e3:.3f}")
    print(f"{'numpy passes, float64 (ms / frame)':40s} {np64 * 1e3:10.3f}   fastest {np64_min * 1e3:.3f}")
    print(f"{'numpy passes, float32 (ms / frame)':40s} {fast32 * 1e3:10.3f}   fastest {fast32_min * 1e3:.3f}")
    print(f"{'plain numpy reference (ms / frame)':40s} {ref * 1e3:10.3f}   fastest {ref_min * 1e3:.3f}")
    print(f"{'ratio reference / deform (compiled)':40s} {ref / fast:10.1f}")
    print(f"{'ratio numpy float32 / compiled':40s} {fast32 / fast:10.1f}")
    print(f"{'budget (ms / frame)':40s} {2.0:10.3f}   compiled {'met' if fast <= 2e-3 else 'MISSED'}, "
          f"numpy float32 {'met' if fast32 <= 2e-3 else 'MISSED'}")
    print(f"{'max |deform - reference| (mesh units)':40s} {err:10.2e}   numpy float64 {err64:.2e}, float32 "
          f"{err32:.2e} (diagonal {diag:.3g})")
    print(f"{'one multiply over the pairs (us)':40s} {op * 1e6:10.1f}   (machine speed in this run)")
    print(f"{'load average (1 min) during the run':40s} {os.getloadavg()[0]:10.2f}   on {os.cpu_count()} cores")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
