"""Speed of the mapping stage, each figure next to a plain-numpy reference measured in the same run.

Budgets: weights() of one frame <= 100 us (also the regional mapping's); synthesize() of an 11,248-vertex
character <= 1 ms per frame; fit of 13 examples <= 50 ms (the regional mapping, which finds its regions on
the mesh: <= 1 s). Uses the ICT-FaceKit model from ../shared/assets when present (or
$FACEPUPPET_ASSETS), else a synthetic performer and character of the same sizes.

The regional rows are followed by the regional solver's plain-numpy path (no budget), measured in the same
run, and the largest difference of their weights.

    python benchmarks/bench_mapping.py [--frames 600] [--repeat 200]
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

from facepuppet import ExpressionMapper
from facepuppet.mapping._regional import RegionalSolver

_INF = float("inf")

ROOT = Path(__file__).resolve().parents[1]
KEYS = (("jawOpen",), ("mouthSmile_L", "mouthSmile_R"), ("mouthPucker",), ("mouthFunnel",),
        ("mouthFrown_L", "mouthFrown_R"), ("browInnerUp_L", "browInnerUp_R"), ("browDown_L", "browDown_R"),
        ("eyeBlink_L", "eyeBlink_R"), ("eyeWide_L", "eyeWide_R"), ("mouthStretch_L", "mouthStretch_R"),
        ("cheekPuff_L", "cheekPuff_R"), ("mouthRollLower", "mouthRollUpper"), ("browOuterUp_L", "browOuterUp_R"))


def scene(frames: int, rng: np.random.Generator) -> tuple[str, tuple, np.ndarray]:
    """(source, (SB, S, TB, T), X): 13 examples, 51 feature points, an 11,248-vertex character."""
    path = Path(os.environ.get("FACEPUPPET_ASSETS", ROOT.parent / "shared" / "assets"))
    path = path / "ict-facekit" / "ict_face_light.npz"
    if path.is_file():
        with np.load(path) as d:
            ict = {k: d[k] for k in d.files}
        names = [str(n) for n in ict["expr_names"]]
        E = ict["expr_deltas"].astype(float)
        ident = ict["id_deltas"].astype(float)
        performer = ict["neutral"] + np.tensordot(rng.normal(size=len(ident)), ident, 1)
        character = ict["neutral"] + np.tensordot(2.0 * rng.normal(size=len(ident)), ident, 1)
        keys = np.zeros((len(KEYS), len(names)))
        for i, k in enumerate(KEYS):
            keys[i, [names.index(n) for n in k]] = 1.0
        fp = ict["landmarks68"][17:68]
        W = np.clip(rng.normal(0.0, 0.4, size=(frames, len(names))), 0, 1)
        sb = performer[fp]
        data = (sb, sb + np.tensordot(keys, E[:, fp], 1), character, character + np.tensordot(keys, E, 1))
        return "ICT-FaceKit", data, sb + np.tensordot(W, E[:, fp], 1)
    sb = rng.normal(size=(51, 3))
    se = sb + rng.normal(scale=0.2, size=(13, 51, 3))
    tb = rng.normal(size=(11248, 3))
    te = tb + rng.normal(scale=0.2, size=(13, 11248, 3))
    x = sb + rng.normal(scale=0.2, size=(frames, 51, 3))
    return "synthetic", (sb, se, tb, te), x


def per_call(fn, repeat: int) -> float:
    """Median seconds per call over ``repeat`` calls (after one warm-up)."""
    fn()
    times = np.empty(repeat)
    for i in range(repeat):
        t0 = time.perf_counter()
        fn()
        times[i] = time.perf_counter() - t0
    return float(np.median(times))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=600)
    ap.add_argument("--repeat", type=int, default=200)
    args = ap.parse_args(argv)
    rng = np.random.default_rng(0)
    source, (sb, se, tb, te), x = scene(args.frames, rng)
    M, F = len(se), len(x)
    V = (se - sb).reshape(M, -1)
    dT = te - tb
    rows = []

    t_fit = per_call(lambda: ExpressionMapper.fit(sb, se, tb, te), max(5, args.repeat // 20))
    t_fit_ref = per_call(lambda: (np.linalg.svd(V, full_matrices=False), dT.reshape(M, -1).copy()),
                         max(5, args.repeat // 20))
    rows.append(("fit, 13 examples (default)", t_fit, "SVD of V + copy of key-model offsets", t_fit_ref, 50e-3))
    t_fit_p = per_call(lambda: ExpressionMapper.fit(sb, se, tb, te, method="paper"), max(5, args.repeat // 20))
    rows.append(("fit, 13 examples (paper)", t_fit_p, "same", t_fit_ref, 50e-3))

    d_one = (x[0] - sb).reshape(-1)
    D = (x - sb).reshape(F, -1)
    t_ref_one = per_call(lambda: np.linalg.lstsq(V.T, d_one, rcond=None), args.repeat)
    for method in ("adaptive", "regional", "bounded", "lsq", "paper"):
        m = ExpressionMapper.fit(sb, se, tb, te, method=method)
        t_one = per_call(lambda m=m: m.weights(x[0]), args.repeat)
        rows.append((f"weights, 1 frame ({method})", t_one, "np.linalg.lstsq, 1 frame (unbounded)", t_ref_one,
                     100e-6))
    m = ExpressionMapper.fit(sb, se, tb, te)
    t_batch = per_call(lambda: m.weights(x), max(5, args.repeat // 20)) / F
    t_ref_batch = per_call(lambda: np.linalg.lstsq(V.T, D.T, rcond=None), max(5, args.repeat // 20)) / F
    rows.append((f"weights, per frame of {F} (default)", t_batch, f"np.linalg.lstsq, {F} rhs at once",
                 t_ref_batch, 100e-6))

    mr = ExpressionMapper.fit(sb, se, tb, te, method="regional")
    t_batch_r = per_call(lambda: mr.weights(x), max(5, args.repeat // 20)) / F
    rows.append((f"weights, per frame of {F} (regional, {len(mr.region_names)} regions)", t_batch_r,
                 f"np.linalg.lstsq, {F} rhs at once", t_ref_batch, 100e-6))
    # The regional solver's plain-numpy path (stacked products, one batched box QP), same weights.
    plain = RegionalSolver.from_arrays({k[7:]: v for k, v in mr.to_arrays().items() if k.startswith("solver_")})
    t_plain_one = per_call(lambda: plain.reference(D[:1]), args.repeat)
    t_plain = per_call(lambda: plain.reference(D), max(5, args.repeat // 20)) / F
    rows.append(("weights, 1 frame (regional, numpy path)", t_plain_one, "np.linalg.lstsq, 1 frame (unbounded)",
                 t_ref_one, _INF))
    rows.append((f"weights, per frame of {F} (regional, numpy path)", t_plain, f"np.linalg.lstsq, {F} rhs at once",
                 t_ref_batch, _INF))
    diff = float(np.abs(mr.weights(x) - plain.reference(D)).max())
    t_fit_r = per_call(lambda: ExpressionMapper.fit(sb, se, tb, te, method="regional"), 3)
    rows.append(("fit, 13 examples (regional)", t_fit_r, "SVD of V + copy of key-model offsets", t_fit_ref, 1.0))
    wr = mr.weights(x)
    t_syn_r = per_call(lambda: mr.synthesize(wr[0]), max(5, args.repeat // 10))
    rows.append(("synthesize, 1 frame, regional", t_syn_r, "tb + einsum('i,ivk->vk')",
                 per_call(lambda: tb + np.einsum("i,ivk->vk", wr[0, 0], dT), args.repeat), 1e-3))
    w = m.weights(x)
    t_syn = per_call(lambda: m.synthesize(w[0]), args.repeat)
    t_syn_ref = per_call(lambda: tb + np.einsum("i,ivk->vk", w[0], dT), args.repeat)
    rows.append((f"synthesize, 1 frame, {len(tb)} vertices", t_syn, "tb + einsum('i,ivk->vk')", t_syn_ref, 1e-3))
    t_syn_b = per_call(lambda: m.synthesize(w), max(3, args.repeat // 50)) / F
    t_syn_b_ref = per_call(lambda: tb + np.einsum("fi,ivk->fvk", w, dT), max(3, args.repeat // 50)) / F
    rows.append((f"synthesize, per frame of {F}", t_syn_b, "tb + einsum('fi,ivk->fvk')", t_syn_b_ref, 1e-3))

    print(f"data: {source}; {M} examples, {sb.shape[0]} feature points, {len(tb)} vertices, {F} frames; "
          f"load {os.getloadavg()[0]:.2f}")
    print(f"regional weights, compiled against the numpy path: largest difference {diff:.2g}")
    print(f"{'figure':40s} {'facepuppet':>12s} {'reference':>12s} {'ratio':>7s} {'budget':>10s}  reference is")
    for name, t, ref_name, t_ref, budget in rows:
        ok = "ok" if t <= budget else "OVER"
        print(f"{name:40s} {_fmt(t):>12s} {_fmt(t_ref):>12s} {t / t_ref:7.2f} {_fmt(budget):>10s} {ok:4s} "
              f"{ref_name}")
    return 0


def _fmt(seconds: float) -> str:
    if seconds == _INF:
        return "-"
    return f"{seconds * 1e6:.1f} us" if seconds < 1e-3 else f"{seconds * 1e3:.2f} ms"


if __name__ == "__main__":
    raise SystemExit(main())
