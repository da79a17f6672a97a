"""Benchmark of `facepuppet animate` on the shared real clips: speed end to end, and whether weights follow.

For each clip of ../shared/assets/video:

1. MediaPipe tracks it once (its blendshape scores are the reference, its curves label the colour tracker's
   performer profile, trained on every third frame).
2. ``calibrate --auto`` makes the key expressions against an ARKit-named character built here from the ICT
   FaceKit model in ../shared/assets (never written into the repository), once per backend; each is rigged.
3. ``animate`` runs end to end (decode, track, map, smooth, write GLB + CSV; no preview), timed (best of
   ``--repeat`` runs: the machine is shared), with the colour tracker and with the MediaPipe backend in the
   same run: frames per second and their ratio (bar: colour >= 200 frames/s). Decoding alone is timed too,
   the ceiling of any backend.
4. The animated jawOpen, eyeBlink and mouthSmile weights (left and right averaged) are correlated with
   MediaPipe's own blendshape scores of the same frames (bar >= 0.6).

Run: ``python benchmarks/bench_animate.py [--clips performer_a,performer_c] [--assets PATH] [--repeat 3]``
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CHANNELS = {"jawOpen": ("jawOpen",), "eyeBlink": ("eyeBlinkLeft", "eyeBlinkRight"),
            "mouthSmile": ("mouthSmileLeft", "mouthSmileRight")}


def ict_character(assets: Path):
    """The ICT FaceKit face (11,248 vertices) with its 53 ARKit-named expressions as key-models."""
    from facepuppet.io.character import Character

    with np.load(assets / "ict-facekit" / "ict_face_light.npz") as d:
        neutral = d["neutral"].astype(float)
        targets = neutral[None] + d["expr_deltas"].astype(float)
        return Character(neutral, targets, tuple(str(n) for n in d["expr_names"]), d["faces"].astype(np.int64),
                         name="ict")


def channel(weights: np.ndarray, names, parts) -> np.ndarray:
    """Mean weight of the key-models standing for the ARKit blendshapes ``parts``; NaN if none was kept."""
    from facepuppet.arkit import arkit_parts

    cols = []
    for i, n in enumerate(names):
        p = arkit_parts(n)
        if p is not None and set(p[0]) & set(parts) and (p[1] is None or len(parts) == 1):
            cols.append(i)
    return weights[:, cols].mean(axis=1) if cols else np.full(len(weights), np.nan)


def corr(a: np.ndarray, b: np.ndarray) -> float:
    ok = np.isfinite(a) & np.isfinite(b)
    if ok.sum() < 3 or np.std(a[ok]) == 0 or np.std(b[ok]) == 0:
        return float("nan")
    return float(np.corrcoef(a[ok], b[ok])[0, 1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--assets", default=os.environ.get("FACEPUPPET_ASSETS", ROOT.parent / "shared" / "assets"))
    ap.add_argument("--clips", default="performer_a,performer_b_exaggerated,performer_c")
    ap.add_argument("--model", default=None, help="face_landmarker.task (default: assets/models)")
    ap.add_argument("--repeat", type=int, default=3, help="timed runs of animate per backend (best is kept)")
    args = ap.parse_args(argv)
    assets = Path(args.assets)
    model = args.model or os.environ.get("FACEPUPPET_FACE_LANDMARKER") or str(assets / "models" /
                                                                                "face_landmarker.task")

    from facepuppet.capture.color.profile import save_profile
    from facepuppet.capture.color.train import train_profile
    from facepuppet.capture.landmarks import BLENDSHAPE_NAMES, MediaPipeTracker
    from facepuppet.capture.tracking import track_media
    from facepuppet.io.frames import open_media
    from facepuppet.io.performer import Performer
    from facepuppet.pipeline.animate import AnimateConfig, animate
    from facepuppet.pipeline.examples import ExamplesConfig, from_auto
    from facepuppet.pipeline.rig import fit_rig
    from facepuppet.pipeline.tracking import TrackerOptions

    character = ict_character(assets)
    col = {n: i for i, n in enumerate(BLENDSHAPE_NAMES)}
    speed_rows, corr_rows = [], []
    tmp = Path(tempfile.mkdtemp(prefix="bench-animate-"))
    for clip_name in args.clips.split(","):
        clip = assets / "video" / f"{clip_name}.mp4"
        with MediaPipeTracker(model) as mp:
            ref = track_media(clip, mp, progress=False)
        scores = ref.extras["blendshapes"]
        with open_media(clip) as src:
            frames = [f for k, f in enumerate(src) if k % 3 == 0]
        keep = ref.valid[::3]
        profile = train_profile([f for f, k in zip(frames, keep, strict=True) if k], ref.curves[::3][keep],
                                name=clip_name)
        profile_path = tmp / f"{clip_name}-profile.npz"
        save_profile(profile_path, profile)
        del frames

        results = {}
        for backend in ("color", "mediapipe"):
            opts = TrackerOptions(backend=backend, profile=str(profile_path) if backend == "color" else None,
                                  model=model, progress=False)
            cal = from_auto(clip, character.names, config=ExamplesConfig(tracker=opts), scores_track=ref,
                            track=ref if backend == "mediapipe" else None)
            rig, _ = fit_rig(Performer(cal.neutral, cal.examples, cal.names, cal.point_names, cal.noise,
                                       cal.nuisance), character)
            dt = np.inf
            for _ in range(max(args.repeat, 1)):
                t0 = time.perf_counter()
                anim = animate(clip, rig, glb=tmp / f"{clip_name}-{backend}.glb",
                               csv=tmp / f"{clip_name}-{backend}.csv", config=AnimateConfig(tracker=opts))
                dt = min(dt, time.perf_counter() - t0)
            results[backend] = (anim, dt, cal)
            for ch, parts in CHANNELS.items():
                ref_ch = scores[:, [col[p] for p in parts]].mean(axis=1)
                corr_rows.append((clip_name, backend, ch, corr(channel(anim.weights, anim.names, parts), ref_ch),
                                  len(cal.names)))
        t_decode = np.inf
        for _ in range(max(args.repeat, 1)):
            t0 = time.perf_counter()
            with open_media(clip) as src:
                for _frame in src:
                    pass
            t_decode = min(t_decode, time.perf_counter() - t0)
        n = results["color"][0].track.n_frames
        fc, fm = n / results["color"][1], n / results["mediapipe"][1]
        speed_rows.append((clip_name, n, n / t_decode, fc, fm, fc / fm, float(np.mean(results["color"][0].valid))))

    print("\nanimate end to end (decode, track, map, smooth, write GLB + CSV), frames per second")
    print(f"{'clip':<26}{'frames':>7}{'decode':>8}{'colour':>8}{'mediapipe':>11}{'ratio':>7}{'colour cover':>14}")
    for clip_name, n, fd, fc, fm, r, cov in speed_rows:
        print(f"{clip_name:<26}{n:>7}{fd:>8.0f}{fc:>8.0f}{fm:>11.0f}{r:>7.1f}{cov:>14.2f}")
    print(f"bar: colour >= 200 frames/s (best of {max(args.repeat, 1)} runs each; ratio = colour / mediapipe; "
          "decode = decoding alone)")
    print("\ncorrelation of animated weights with MediaPipe's blendshape scores (same frames), --auto against ICT")
    print(f"{'clip':<26}{'backend':<11}{'channel':<12}{'r':>7}{'keys kept':>11}")
    for clip_name, backend, ch, r, kept in corr_rows:
        print(f"{clip_name:<26}{backend:<11}{ch:<12}{r:>7.2f}{kept:>11}")
    print("bar: r >= 0.6")
    return 0


if __name__ == "__main__":
    sys.exit(main())
