"""Benchmark of `facepuppet live` on the shared clips: latency, drops, the smoother's lag, a long session.

For each clip of the shared assets, a rig is made as ``bench_animate.py`` makes it (MediaPipe labels the
colour tracker's performer profile; ``--auto`` key expressions against the ICT FaceKit character), once per
backend. Then, in the same run:

1. **Live at the clip's own frame rate** (``--pace realtime``, the file standing in for a camera): frames,
   frames dropped, and latency from the frame being read to the last packet sent (p50, p95, p99, max), with the
   VMC and Live Link senders to loopback ports nobody listens on; beside it, the **bare tracker** on the same
   frames (``tracker.track`` alone, frames decoded beforehand). Bar (colour tracker, 30 fps input): p95 <= 15
   ms and no frame dropped; goal p95 <= 5 ms.
2. **The smoother's lag**: smoothed against raw weights (the rig's jawOpen and blink channels), the lag in
   frames that maximises their cross-correlation. Bar: at most one frame.
3. **A long session** (``--soak-minutes``, default 30, colour tracker, ``--pace fast`` over the clip looped,
   recording GLB and CSV): resident memory after the first minute of the take and at the end, and latency in
   the first and the last minute. Bar: growth <= 10 MB.

Run: ``python benchmarks/bench_live.py [--clips performer_a,performer_c] [--assets PATH] [--soak-minutes 30]``
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_animate import ROOT, ict_character  # noqa: E402


def rss_mb() -> float:
    """Resident memory of this process, MB (Linux)."""
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def percentiles(ms: np.ndarray) -> tuple[float, float, float, float]:
    return tuple(float(x) for x in np.percentile(ms, [50, 95, 99])) + (float(ms.max()),)


class LoopedClip:
    """A clip played again and again as one long take (a MediaSource stand-in for run_live)."""

    def __init__(self, path: Path, frames: int) -> None:
        from facepuppet.io.frames import open_media

        with open_media(path) as src:
            self.fps, self.frame_size = src.fps, src.frame_size
        self.path, self.frames, self.is_camera, self.frame_count = str(path), frames, False, frames

    def __iter__(self):
        from facepuppet.io.frames import open_media

        n = 0
        while n < self.frames:
            with open_media(self.path) as src:
                for rgb in src:
                    if n >= self.frames:
                        return
                    n += 1
                    yield rgb


class Probe:
    """A sender that samples the process's memory and the frames' latency, per minute of the take."""

    def __init__(self, fps: float) -> None:
        self.fps, self.minute = fps, int(round(60 * fps))
        self.rss: dict[int, float] = {}
        self.latency: dict[int, list[float]] = {}

    def send(self, frame) -> None:
        m = frame.index // self.minute
        self.latency.setdefault(m, []).append((time.perf_counter() - frame.timestamp) * 1e3)
        if frame.index % self.minute == self.minute - 1:
            self.rss[m] = rss_mb()

    def close(self) -> None:
        pass


def make_rigs(clip: Path, model: str, character, tmp: Path) -> dict:
    """backend -> (rig, TrackerOptions), as bench_animate makes them."""
    from facepuppet.capture.color.profile import save_profile
    from facepuppet.capture.color.train import train_profile
    from facepuppet.capture.landmarks import MediaPipeTracker
    from facepuppet.capture.tracking import track_media
    from facepuppet.io.frames import open_media
    from facepuppet.pipeline.examples import ExamplesConfig, from_auto
    from facepuppet.pipeline.rig import fit_rig
    from facepuppet.pipeline.tracking import TrackerOptions

    with MediaPipeTracker(model) as mp:
        ref = track_media(clip, mp, progress=False)
    with open_media(clip) as src:
        frames = [f for k, f in enumerate(src) if k % 3 == 0]
    keep = ref.valid[::3]
    profile = train_profile([f for f, k in zip(frames, keep, strict=True) if k], ref.curves[::3][keep],
                            name=clip.stem)
    profile_path = tmp / f"{clip.stem}-profile.npz"
    save_profile(profile_path, profile)
    out = {}
    for backend in ("color", "mediapipe"):
        opts = TrackerOptions(backend=backend, profile=str(profile_path) if backend == "color" else None,
                              model=model, progress=False)
        performer = from_auto(clip, character.names, config=ExamplesConfig(tracker=opts), scores_track=ref,
                              track=ref if backend == "mediapipe" else None)
        out[backend] = (fit_rig(performer, character)[0], opts)
    return out


def bare_tracker(clip: Path, opts) -> np.ndarray:
    """Per-frame milliseconds of tracker.track alone on the clip's frames (decoded beforehand)."""
    from facepuppet.io.frames import open_media
    from facepuppet.pipeline.tracking import make_tracker_for

    with open_media(clip) as src:
        fps, frames = src.fps, list(src)
    spare = make_tracker_for(opts, clip)          # loads the compiled kernels, as the live session's warm-up
    spare.track(frames[0], 0)
    spare.close()
    tracker = make_tracker_for(opts, clip)
    ms = []
    try:
        for k, rgb in enumerate(frames):
            t0 = time.perf_counter()
            tracker.track(rgb, int(round(k * 1000 / fps)))
            ms.append((time.perf_counter() - t0) * 1e3)
    finally:
        tracker.close()
    return np.array(ms)


def smoother_lag(rig, clip: Path, opts) -> dict:
    """Lag (frames) maximising the cross-correlation of smoothed and raw weights, per channel."""
    from facepuppet.pipeline.animate import AnimateConfig, animate
    from facepuppet.pipeline.smoothing import SmoothingConfig

    on = animate(clip, rig, config=AnimateConfig(tracker=opts))
    off = animate(clip, rig, config=AnimateConfig(tracker=opts, smoothing=SmoothingConfig(enabled=False)))
    lags = {}
    for name in ("jawOpen", "eyeBlink_L", "eyeBlink_R", "mouthSmile_L"):
        if name not in on.names:
            continue
        j = on.names.index(name)
        a, b = on.weights[:, j], off.weights[:, j]
        if np.std(b) < 1e-6:
            continue
        best = max(range(-5, 6), key=lambda L: np.corrcoef(a[max(L, 0):len(a) + min(L, 0)],
                                                           b[max(-L, 0):len(b) - max(L, 0)])[0, 1])
        lags[name] = best
    return lags


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--assets", default=os.environ.get("FACEPUPPET_ASSETS", ROOT.parent / "shared" / "assets"))
    ap.add_argument("--clips", default="performer_a,performer_b_exaggerated,performer_c")
    ap.add_argument("--model", default=None, help="face_landmarker.task (default: assets/models)")
    ap.add_argument("--soak-minutes", type=float, default=30.0, help="length of the long session's take (0: skip)")
    args = ap.parse_args(argv)
    assets = Path(args.assets)
    model = args.model or os.environ.get("FACEPUPPET_FACE_LANDMARKER") or str(assets / "models" /
                                                                                "face_landmarker.task")
    from facepuppet.live.livelink import LiveLinkSender
    from facepuppet.live.session import LiveConfig, run_live
    from facepuppet.live.vmc import VmcSender

    character = ict_character(assets)
    tmp = Path(tempfile.mkdtemp(prefix="bench-live-"))
    rows, lag_rows, soak = [], [], None
    for name in args.clips.split(","):
        clip = assets / "video" / f"{name}.mp4"
        rigs = make_rigs(clip, model, character, tmp)
        for backend, (rig, opts) in rigs.items():
            senders = [VmcSender(rig.names, "127.0.0.1", 39539), LiveLinkSender(rig.names, "127.0.0.1", 11111)]
            try:
                res = run_live(clip, rig, config=LiveConfig(tracker=opts, pace="realtime", status=False,
                                                            keys=False), senders=senders)
            finally:
                for s in senders:
                    s.close()
            lat = res.stats["latency_ms"]
            bare = percentiles(bare_tracker(clip, opts))
            rows.append((name, backend, res.frames, res.dropped, lat["p50"], lat["p95"], lat["p99"], lat["max"],
                         *bare))
            if backend == "color":
                lag_rows.append((name, smoother_lag(rig, clip, opts)))
        if soak is None and args.soak_minutes > 0:
            rig, opts = rigs["color"]
            fps = LoopedClip(clip, 0).fps
            n = int(round(args.soak_minutes * 60 * fps))
            probe = Probe(fps)
            t0 = time.perf_counter()
            res = run_live(LoopedClip(clip, n), rig, config=LiveConfig(tracker=opts, pace="fast", status=False,
                                                                       keys=False),
                           record=tmp / "soak.glb", csv=tmp / "soak.csv", senders=[probe])
            soak = (name, res.frames, time.perf_counter() - t0, probe)

    print("\nlive at the clip's frame rate: latency from frame read to last packet sent, ms "
          "(bare tracker: tracker.track alone, same frames)")
    print(f"{'clip':<26}{'backend':<11}{'frames':>7}{'dropped':>8}{'p50':>7}{'p95':>7}{'p99':>7}{'max':>8}"
          f"{'bare p50':>10}{'p95':>7}{'p99':>7}{'max':>8}")
    for r in rows:
        print(f"{r[0]:<26}{r[1]:<11}{r[2]:>7}{r[3]:>8}" + "".join(f"{x:>7.1f}" for x in r[4:7]) + f"{r[7]:>8.1f}"
              + f"{r[8]:>10.1f}" + "".join(f"{x:>7.1f}" for x in r[9:11]) + f"{r[11]:>8.1f}")
    print("bar: colour tracker p95 <= 15 ms and 0 dropped (goal p95 <= 5 ms)")
    print("\nsmoother's lag: frames by which smoothed weights follow the raw ones (max cross-correlation)")
    for name, lags in lag_rows:
        print(f"{name:<26}" + "  ".join(f"{k} {v:+d}" for k, v in lags.items()))
    print("bar: at most 1 frame")
    if soak is not None:
        name, frames, secs, probe = soak
        minutes = sorted(probe.rss)
        first, last = minutes[0], minutes[-1]
        p95 = {m: float(np.percentile(probe.latency[m], 95)) for m in (first, last)}
        print(f"\nlong session: {name} looped, {frames} frames ({frames / probe.fps / 60:.1f} min of take) in "
              f"{secs:.0f} s, recording GLB + CSV")
        print(f"resident memory after minute {first + 1}: {probe.rss[first]:.1f} MB, after minute {last + 1}: "
              f"{probe.rss[last]:.1f} MB, growth {probe.rss[last] - probe.rss[first]:+.1f} MB (bar <= 10 MB)")
        print(f"latency p95 in minute {first + 1}: {p95[first]:.1f} ms, in minute {last + 1}: {p95[last]:.1f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
