"""Held-out accuracy of every mapping method over many ICT-FaceKit scenes, as a ratio to the source-oracle.

Each scene pairs a performer and a character built from the ICT-FaceKit model (../shared/assets, read at run
time; no data is stored here) and drives the performer with a synthetic performance on all 53 ICT expressions;
the truth is the character posed with the same expression weights. A scene draws, independently:

- identities: ICT identity seeds for performer and character (ICT's expression shapes do not depend on the
  identity, so this changes only the noise scale, the inter-ocular distance), and the performer's own way of
  moving: a smooth random gain field over the face scaling its expression shapes (``warp``) or none;
- a character-sculpting model: ``mix`` (the shared yardstick's: gain 0.6–1.6 per shape plus two same-region
  neighbours at −0.15–0.35), ``gain`` (gain only), ``identity`` (the performer's shapes), ``strong`` (four
  same-region neighbours at −0.3–0.6), ``cross`` (two neighbours from any region);
- a performance: the yardstick's generator with another seed (``base``), ``sparse`` / ``dense`` (fewer or more
  expressions active), ``fast`` / ``slow``, ``asym`` (left and right halves independent), ``outside`` (key
  expressions damped: most motion is outside the key set), ``inside`` (only the key expressions move);
- a key set: the paper's 13 (``paper13``), a random 8–12 of them (``subset``), 13 random groups of the 53
  (``random``), the paper's 13 with three symmetric keys split into left and right (``asym``);
- noise on the feature points: 0, 0.01, 0.02, 0.05 of the inter-ocular distance (every scene at every level).

Score of a method in a scene: mean over frames of ||pred − truth|| / ||truth − neutral|| on the whole character
mesh, divided by the same score of the source-oracle (the best blend in [0, 1.5] fitted on the performer's whole
face, copied over; as in ../shared/eval/retarget_ict.py). Lower is better; below 1 beats the source-oracle.
Errors are computed exactly in the 53-dimensional expression space (pred − truth = (w K − W) E_c), so a scene
costs little more than the method's own solve.

    python benchmarks/eval_mapping_variants.py [--scenes 60] [--frames 300] [--methods bounded,lsq,paper]
        [--seed 0]

A method is a name in ``facepuppet.mapping.METHODS``, optionally with option overrides:
``bounded:angle_ridge=0.1,shrinkage=1``. ``regional`` is fitted with the character's mesh (ICT's neutral and
the scene's key-models) and scored exactly on the whole mesh region by region (``Scene.regional_score``).
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

from facepuppet import ExpressionMapper
from facepuppet.mapping import METHODS
from facepuppet.mapping._boxqp import solve_box_qp

ROOT = Path(__file__).resolve().parents[1]
PAPER13 = (("jawOpen",), ("mouthSmile_L", "mouthSmile_R"), ("mouthPucker",), ("mouthFunnel",),
           ("mouthFrown_L", "mouthFrown_R"), ("browInnerUp_L", "browInnerUp_R"), ("browDown_L", "browDown_R"),
           ("eyeBlink_L", "eyeBlink_R"), ("eyeWide_L", "eyeWide_R"), ("mouthStretch_L", "mouthStretch_R"),
           ("cheekPuff_L", "cheekPuff_R"), ("mouthRollLower", "mouthRollUpper"), ("browOuterUp_L", "browOuterUp_R"))
FEATURES = np.r_[17:27, 36:48, 27:36, 48:68]  # iBUG-68: brows, eyes, nose, mouth (the yardstick's 51 points)
NOISES = (0.0, 0.01, 0.02, 0.05)
CHARACTERS = ("mix", "gain", "identity", "strong", "cross")
PERFORMANCES = ("base", "sparse", "dense", "fast", "slow", "asym", "outside", "inside")
KEYSETS = ("paper13", "subset", "random", "asym")
PERFORMERS = ("plain", "warp")
# performance kind -> (offset subtracted before clipping, frequency scale, halves independent)
PERF_TABLE = {"base": (0.35, 1.0, False), "sparse": (0.6, 1.0, False), "dense": (0.15, 1.0, False),
              "fast": (0.35, 3.0, False), "slow": (0.35, 0.3, False), "asym": (0.35, 1.0, True),
              "outside": (0.35, 1.0, False), "inside": (0.35, 1.0, False)}


def load_ict() -> dict:
    path = Path(os.environ.get("FACEPUPPET_ASSETS", ROOT.parent / "shared" / "assets"))
    with np.load(path / "ict-facekit" / "ict_face_light.npz") as d:
        return {k: d[k] for k in d.files}


def stem(name: str) -> str:
    return name[:-2] if name.endswith(("_L", "_R")) else name


def region(name: str) -> str:
    return "brow" if name.startswith("brow") else "eye" if name.startswith("eye") else "mouth"


def performance(names, frames, rng, kind, key_cols):
    """(frames, 53) smooth sparse weights in [0, 1] (the yardstick's generator, with the kind's parameters)."""
    offset, speed, independent = PERF_TABLE[kind]
    t = np.arange(frames) / 30.0
    base, W = {}, np.zeros((frames, len(names)))
    for j, n in enumerate(names):
        key = n if independent else stem(n)
        if key not in base:
            f = speed * rng.uniform(0.05, 0.6, 4)
            ph, a = rng.uniform(0, 2 * np.pi, 4), rng.uniform(0.3, 1.0, 4)
            base[key] = (a[:, None] * np.sin(2 * np.pi * f[:, None] * t + ph[:, None])).sum(0) / a.sum()
        own = 0.25 * np.sin(2 * np.pi * speed * rng.uniform(0.05, 0.4) * t + rng.uniform(0, 6.3))
        W[:, j] = np.clip(1.6 * (base[key] + own) - offset, 0, 1)
    if kind == "outside":
        W[:, key_cols] *= 0.3
    elif kind == "inside":
        keep = np.zeros(len(names), bool)
        keep[key_cols] = True
        W[:, ~keep] = 0.0
    return W


def character_mix(names, rng, kind):
    """(53, 53) A: the character's shapes are A @ E."""
    n = len(names)
    if kind == "identity":
        return np.eye(n)
    A = np.diag(rng.uniform(0.6, 1.6, n))
    if kind == "gain":
        return A
    reg = [region(x) for x in names]
    count, lo, hi = {"mix": (2, -0.15, 0.35), "strong": (4, -0.3, 0.6), "cross": (2, -0.15, 0.35)}[kind]
    for i in range(n):
        pool = [j for j in range(n) if j != i and (kind == "cross" or reg[j] == reg[i])]
        for j in rng.choice(pool, size=count, replace=False):
            A[i, j] += rng.uniform(lo, hi)
    return A


def key_matrix(names, rng, kind):
    """(M, 53) key expressions as weights on the ICT shapes."""
    groups = [list(k) for k in PAPER13]
    if kind == "subset":
        groups = [groups[i] for i in sorted(rng.choice(13, size=int(rng.integers(8, 13)), replace=False))]
    elif kind == "random":
        stems = sorted({stem(n) for n in names})
        picked = rng.choice(len(stems), size=13, replace=False)
        groups = [[n for n in names if stem(n) == stems[i]] for i in picked]
    elif kind == "asym":
        pairs = [i for i, g in enumerate(groups) if len(g) == 2 and g[0].endswith("_L")]
        split = set(rng.choice(pairs, size=3, replace=False).tolist())
        groups = [h for i, g in enumerate(groups) for h in ([[g[0]], [g[1]]] if i in split else [g])]
    K = np.zeros((len(groups), len(names)))
    for i, g in enumerate(groups):
        K[i, [names.index(n) for n in g]] = 1.0
    return K


def smooth_field(points, rng, amount=0.3):
    """(V,) positive gain, smooth over the face: 1 + amount · a few random Gaussian bumps."""
    centre = points[rng.choice(len(points), size=4, replace=False)]
    scale = np.ptp(points, axis=0).max() * 0.25
    g = np.ones(len(points))
    for c in centre:
        g += amount * rng.uniform(-1, 1) * np.exp(-np.sum((points - c) ** 2, 1) / (2 * scale**2))
    return np.maximum(g, 0.3)


class Scene:
    """One performer/character/performance/key-set combination, everything the methods and scores need."""

    def __init__(self, ict, EEt, rng, frames, *, performer, character, perf, keys, yardstick=False):
        names = [str(n) for n in ict["expr_names"]]
        E = ict["expr_deltas"].astype(float)
        ident = ict["id_deltas"].astype(float)
        lm = ict["landmarks68"]
        self.label = f"{performer}/{character}/{perf}/{keys}"
        if yardstick:  # the shared yardstick's own scene (seed 11), as a check of this harness
            rng = np.random.default_rng(11)
            body = ict["neutral"] + np.tensordot(rng.normal(size=100), ident, 1)
            rng.normal(size=100)  # the character's identity (does not enter the scores)
            A = character_mix(names, rng, "mix")
            K = key_matrix(names, rng, "paper13")
            W = performance(names, frames, np.random.default_rng(3), "base", [])
            self.label = "yardstick"
        else:
            body = ict["neutral"] + np.tensordot(rng.normal(size=100), ident, 1)
            K = key_matrix(names, rng, keys)
            A = character_mix(names, rng, character)
            W = performance(names, frames, rng, perf, np.flatnonzero(K.any(0)))
        fp = lm[FEATURES]
        Es = E
        P = EEt
        if performer == "warp" and not yardstick:
            g = smooth_field(ict["neutral"], rng)
            Es = E * g[None, :, None]
            flat = Es.reshape(len(E), -1)
            P = flat @ flat.T
        self.iod = float(np.linalg.norm(body[lm[36]] - body[lm[45]]))
        self.sb = body[fp]
        self.se = self.sb + np.tensordot(K, Es[:, fp], 1)
        self.x = self.sb + np.tensordot(W, Es[:, fp], 1)
        self.K, self.W, self.A = K, W, A
        self.E, self.neutral = E, ict["neutral"].astype(float)
        self.Q = A @ EEt @ A.T  # Gram matrix of the character's shapes: errors live in the 53-d space
        den = np.sqrt(np.einsum("fi,ij,fj->f", W, self.Q, W))
        self.ok = den > 1e-3 * den.max()
        self.den = den
        # source-oracle: best blend in [0, 1.5] of the performer's whole-face keys, copied to the character
        Hs = K @ P @ K.T
        self.w_src = solve_box_qp(Hs, W @ P @ K.T, np.zeros(len(K)), np.full(len(K), 1.5))
        self.src = self.score(self.w_src)
        Ht = K @ self.Q @ K.T
        self.oracle = self.score(solve_box_qp(Ht, W @ self.Q @ K.T, np.zeros(len(K)), np.full(len(K), 1.5)))

    def score(self, w: np.ndarray) -> float:
        U = w @ self.K - self.W
        num = np.sqrt(np.maximum(np.einsum("fi,ij,fj->f", U, self.Q, U), 0.0))
        return float(np.mean(num[self.ok] / self.den[self.ok]))

    def targets(self) -> tuple[np.ndarray, np.ndarray]:
        """The character's neutral (V, 3) and key-models (M, V, 3) (ICT's neutral: shapes do not depend on it)."""
        return self.neutral, self.neutral + np.tensordot(self.K @ self.A, self.E, 1)

    def regional_score(self, w: np.ndarray, masks: np.ndarray, EEt: np.ndarray) -> float:
        """Score of regional weights w (F, R, M) with masks (R, V) (background first), exactly on the whole mesh.

        With U_k = (w_k K - W) A and M_0 = 1 - sum_{k>=1} M_k, the error at v is
        (U_0 + sum_{k>=1} M_k(v) D_k) E(v), D_k = U_k - U_0; its squared norm summed over v is
        U_0 EEt U_0^T + 2 sum_k U_0 G_k D_k^T + sum_kl D_k G_kl D_l^T with G_k = E diag(M_k) E^T and
        G_kl = E diag(M_k M_l) E^T, each summed only where the masks are non-zero.
        """
        U = np.einsum("frm,mj,jc->frc", w, self.K, self.A) - (self.W @ self.A)[:, None]
        U0, Dk = U[:, 0], U[:, 1:] - U[:, :1]
        n, R = len(self.E), len(masks) - 1
        err2 = np.einsum("fi,ij,fj->f", U0, EEt, U0)
        support = [np.flatnonzero(masks[k + 1] > 0) for k in range(R)]

        def gram(idx, s):
            e = self.E[:, idx]
            return (e * s[:, None]).reshape(n, -1) @ e.reshape(n, -1).T

        if getattr(self, "_gram_masks", None) is not masks:       # the same masks at every noise level
            self._gram_masks, self._grams = masks, {}
            for k in range(R):
                ik = support[k]
                self._grams[k, -1] = gram(ik, masks[k + 1, ik])
                for ll in range(k, R):
                    idx = np.intersect1d(ik, support[ll], assume_unique=True)
                    if len(idx):
                        self._grams[k, ll] = gram(idx, masks[k + 1, idx] * masks[ll + 1, idx])
        for (k, ll), G in self._grams.items():
            if ll < 0:
                err2 += 2.0 * np.einsum("fi,ij,fj->f", U0, G, Dk[:, k])
            else:
                term = np.einsum("fi,ij,fj->f", Dk[:, k], G, Dk[:, ll])
                err2 += term if k == ll else 2.0 * term
        num = np.sqrt(np.maximum(err2, 0.0))
        return float(np.mean(num[self.ok] / self.den[self.ok]))

    def noisy(self, level: float, seed: int) -> np.ndarray:
        if level == 0.0:
            return self.x
        return self.x + np.random.default_rng(seed).normal(scale=level * self.iod, size=self.x.shape)


def parse_method(spec: str) -> tuple[str, dict]:
    name, _, rest = spec.partition(":")
    opts = {}
    for item in filter(None, rest.split(",")):
        k, v = item.split("=")
        opts[k] = tuple(float(b) for b in v.split("/")) if "/" in v else float(v)
    if name not in METHODS:
        raise SystemExit(f"--methods: unknown method {name!r}; known: {', '.join(METHODS)}")
    return name, opts


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", type=int, default=60)
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--methods", default=",".join(METHODS), help="';'-separated list when options are given")
    ap.add_argument("--by", choices=("noise", "character", "perf", "keys", "performer"), action="append",
                    default=[], help="also break the mean ratio down by this factor")
    args = ap.parse_args(argv)
    specs = args.methods.split(";") if ";" in args.methods or ":" in args.methods else args.methods.split(",")
    methods = [parse_method(s) for s in specs]
    ict = load_ict()
    flat = ict["expr_deltas"].astype(float).reshape(len(ict["expr_deltas"]), -1)
    EEt = flat @ flat.T
    rng = np.random.default_rng(args.seed)
    t0 = time.perf_counter()
    scenes = [Scene(ict, EEt, rng, 600, performer="plain", character="mix", perf="base", keys="paper13",
                    yardstick=True)]
    for _ in range(args.scenes):
        combo = dict(performer=str(rng.choice(PERFORMERS)), character=str(rng.choice(CHARACTERS)),
                     perf=str(rng.choice(PERFORMANCES)), keys=str(rng.choice(KEYSETS)))
        scenes.append(Scene(ict, EEt, np.random.default_rng(rng.integers(2**32)), args.frames, **combo))
    t_build = time.perf_counter() - t0
    # rows: (method spec, scene index, noise, ratio)
    ratios = {s: np.zeros((len(scenes), len(NOISES))) for s in specs}
    fails = {s: 0 for s in specs}
    t0 = time.perf_counter()
    for si, sc in enumerate(scenes):
        xs = [sc.noisy(level, 1000 + si if si else 0) for level in NOISES]
        for spec, (name, opts) in zip(specs, methods, strict=True):
            regional = name == "regional"
            tb, te = sc.targets() if regional else (np.zeros((1, 3)), np.zeros((len(sc.se), 1, 3)))
            if regional and "n_regions" in opts:
                opts = {**opts, "n_regions": int(opts["n_regions"])}
            try:
                m = ExpressionMapper.fit(sc.sb, sc.se, tb, te, method=name, **opts)
            except Exception as e:  # noqa: BLE001 - a method that cannot fit a scene is counted, not fatal
                if not fails[spec]:
                    print(f"{spec}: cannot fit {sc.label}: {e}")
                fails[spec] += 1
                ratios[spec][si] = np.nan
                continue
            for ni, x in enumerate(xs):
                w = m.weights(x)
                score = sc.regional_score(w, m.region_masks, EEt) if regional else sc.score(w)
                ratios[spec][si, ni] = score / sc.src
    t_eval = time.perf_counter() - t0
    print(f"{len(scenes) - 1} held-out scenes x {len(NOISES)} noise levels ({args.frames} frames each) + the "
          f"yardstick's scene; seed {args.seed}; built in {t_build:.1f} s, evaluated in {t_eval:.1f} s")
    print(f"source-oracle error: mean {np.mean([s.src for s in scenes[1:]]):.3f}; "
          f"oracle/source-oracle: mean {np.mean([s.oracle / s.src for s in scenes[1:]]):.3f}")
    head = "  ".join(f"n={n:<4g}" for n in NOISES)
    print(f"{'method':42s} {'mean':>6s} {'worst':>6s} {'p90':>6s}  mean by noise: {head}   yardstick 0/0.02  fails")
    for spec in specs:
        r = ratios[spec][1:]
        by_noise = "  ".join(f"{np.nanmean(r[:, i]):6.3f}" for i in range(len(NOISES)))
        y = ratios[spec][0]
        print(f"{spec:42s} {np.nanmean(r):6.3f} {np.nanmax(r):6.3f} {np.nanpercentile(r, 90):6.3f}  "
              f"{'':15s}{by_noise}   {y[0]:.3f}/{y[2]:.3f}  {fails[spec]}")
    for factor in args.by:
        if factor == "noise":
            continue
        levels = {"character": CHARACTERS, "perf": PERFORMANCES, "keys": KEYSETS, "performer": PERFORMERS}[factor]
        idx = {"character": 1, "perf": 2, "keys": 3, "performer": 0}[factor]
        print(f"\nmean ratio by {factor}:")
        print(f"{'method':42s} " + " ".join(f"{lv:>9s}" for lv in levels))
        for spec in specs:
            r = ratios[spec][1:]
            cells = []
            for lv in levels:
                rows = [i for i, s in enumerate(scenes[1:]) if s.label.split("/")[idx] == lv]
                cells.append(f"{np.nanmean(r[rows]):9.3f}" if rows else f"{'-':>9s}")
            print(f"{spec:42s} " + " ".join(cells))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
