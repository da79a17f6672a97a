"""The colour tracker on altered copies of the shared clips: dim, warm, noisy and small faces.

The tracker should hold up on footage unlike the three shared clips (dim light, small faces, ...). This makes
such footage from the shared clips and measures it with the shared yardstick:

- ``dim``: every channel times 0.35 (an underexposed room);
- ``warm``: red times 1.3, green 0.95, blue 0.65 (tungsten light on an uncorrected camera);
- ``noisy``: Gaussian noise of standard deviation 12 grey levels per channel (a cheap sensor in low light);
- ``small``: the frame shrunk to 2/5 and set on a grey (90) frame of the original size (a face far away);
- ``face80``: the frame shrunk so that the face is 80 px wide (:data:`FACE_WIDTH` eye-centre distances, the
  distance MediaPipe finds on the clip's first frames) and set on a grey frame the same way.

Each copy is written as MPEG-4 into a temporary folder, tracked with ``--backend color`` and the built-in
profile (no landmark model: the copies test the colour pipeline alone), and scored by
``../shared/eval/track_agreement.py`` (mean NME against MediaPipe on the same frames, jitter ratio, coverage).
The bars of the shared clips are NME <= 0.05, jitter ratio <= 1.5, coverage >= 0.98.

Run: ``python benchmarks/eval_robustness.py [--clips performer_a performer_c] [--variants dim warm noisy small face80]
[--assets PATH] [--jobs 2]`` (about a minute per copy on one core, MediaPipe's reference included).
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
VARIANTS = ("dim", "warm", "noisy", "small", "face80")
#: A face's width in eye-centre distances (bizygomatic breadth over the distance of the pupils, adults).
FACE_WIDTH = 2.2
#: The face80 copy's face width, pixels.
SMALL_FACE = 80.0


def _shrunk(rgb: np.ndarray, f: float) -> np.ndarray:
    """The frame shrunk by ``f`` and set on a grey (90) frame of the original size, a third down, a quarter in."""
    import cv2

    h, w = rgb.shape[:2]
    s = cv2.resize(rgb, (max(round(w * f), 1), max(round(h * f), 1)), interpolation=cv2.INTER_AREA)
    out = np.full_like(rgb, 90)
    out[h // 3:h // 3 + s.shape[0], w // 4:w // 4 + s.shape[1]] = s[:h - h // 3, :w - w // 4]
    return out


def face_unit(src: Path, model: Path, frames: int = 10) -> float:
    """The median eye-centre distance (pixels) MediaPipe (model file ``model``) finds on the first ``frames`` of
    ``src``."""
    import cv2

    from facepuppet.capture.color.eye_anchors import eye_centres_of
    from facepuppet.capture.tracking import make_tracker

    cap = cv2.VideoCapture(str(src))
    tracker, units = make_tracker("mediapipe", model_path=model, running_mode="image"), []
    for i in range(frames):
        ok, bgr = cap.read()
        if not ok:
            break
        f = tracker.track(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB), 33 * i)
        if f.valid:
            right, left = eye_centres_of(f.curves)
            units.append(float(np.hypot(*(left - right))))
    cap.release()
    tracker.close()
    if not units:
        raise RuntimeError(f"{src}: no face in the first {frames} frames")
    return float(np.median(units))


def altered(rgb: np.ndarray, variant: str, rng: np.random.Generator, unit: float | None = None) -> np.ndarray:
    """One RGB frame (H, W, 3) uint8 as the ``variant`` copy shows it (module docstring); ``unit``: the clip's
    eye-centre distance in pixels (``face80`` only)."""
    import cv2

    x = rgb.astype(np.float32)
    if variant == "dim":
        x = x * 0.35
    elif variant == "warm":
        x = x * np.array([1.3, 0.95, 0.65], dtype=np.float32)
    elif variant == "noisy":
        x = x + rng.normal(0.0, 12.0, x.shape).astype(np.float32)
    elif variant == "small":
        h, w = rgb.shape[:2]
        s = cv2.resize(rgb, (w * 2 // 5, h * 2 // 5), interpolation=cv2.INTER_AREA)
        out = np.full_like(rgb, 90)
        out[h // 3:h // 3 + s.shape[0], w // 4:w // 4 + s.shape[1]] = s
        return out
    elif variant == "face80":
        if unit is None:
            raise ValueError("the face80 copy needs the clip's eye-centre distance (unit)")
        return _shrunk(rgb, min(SMALL_FACE / (FACE_WIDTH * unit), 1.0))
    else:
        raise ValueError(f"unknown variant {variant!r}; choose from {', '.join(VARIANTS)}")
    return np.clip(x + 0.5, 0, 255).astype(np.uint8)


def write_copy(src: Path, variant: str, out: Path, model: Path | None = None) -> None:
    """Write the ``variant`` copy of the video ``src`` to ``out`` (MPEG-4, same size and rate); ``model``: the
    MediaPipe model file (``face80`` only)."""
    import cv2

    cap = cv2.VideoCapture(str(src))
    fps = cap.get(cv2.CAP_PROP_FPS) or 30.0
    rng = np.random.default_rng(0)
    unit = face_unit(src, model) if variant == "face80" else None
    writer = None
    while True:
        ok, bgr = cap.read()
        if not ok:
            break
        rgb = altered(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB), variant, rng, unit)
        if writer is None:
            writer = cv2.VideoWriter(str(out), cv2.VideoWriter_fourcc(*"mp4v"), fps, rgb.shape[1::-1])
        writer.write(cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    cap.release()
    if writer is None:
        raise RuntimeError(f"{src}: no frames")
    writer.release()


def measure(job: tuple[str, str, str, str]) -> tuple[str, str, str]:
    """Make, track and score one copy; returns (clip, variant, the yardstick's summary line)."""
    clip, variant, assets, tmp = job
    os.environ.pop("FACEPUPPET_FACE_LANDMARKER", None)
    from facepuppet.capture.color.tracker import ColorTracker
    from facepuppet.capture.tracking import track_media
    from facepuppet.io.track import save_track

    video = Path(tmp) / f"{clip}_{variant}.mp4"
    write_copy(Path(assets) / "video" / f"{clip}.mp4", variant, video, Path(assets) / "models" / "face_landmarker.task")
    track = Path(tmp) / f"{clip}_{variant}.npz"
    save_track(track, track_media(video, ColorTracker(), progress=False))
    env = dict(os.environ, FACEPUPPET_FACE_LANDMARKER=str(Path(assets) / "models" / "face_landmarker.task"))
    done = subprocess.run([sys.executable, str(ROOT.parent / "shared" / "eval" / "track_agreement.py"),
                           str(video), str(track)], capture_output=True, text=True, env=env)
    lines = [line for line in done.stdout.splitlines() if line.startswith("mean NME")]
    return clip, variant, lines[0] if lines else f"yardstick failed: {done.stderr.strip()[-200:]}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--clips", nargs="+", default=["performer_a", "performer_c"])
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=VARIANTS)
    ap.add_argument("--assets", default=str(ROOT.parent / "shared" / "assets"))
    ap.add_argument("--jobs", type=int, default=2, help="copies measured at once (processes)")
    args = ap.parse_args(argv)
    for clip in args.clips:
        if not (Path(args.assets) / "video" / f"{clip}.mp4").is_file():
            ap.error(f"--clips: {Path(args.assets) / 'video' / (clip + '.mp4')} does not exist")

    print(f"{'copy':24s} {'NME':>7s} {'jitter':>7s} {'coverage':>9s}")
    with tempfile.TemporaryDirectory(prefix="facepuppet-robust-") as tmp, \
            ProcessPoolExecutor(max(1, args.jobs)) as pool:
        jobs = [(c, v, args.assets, tmp) for c in args.clips for v in args.variants]
        for clip, variant, line in pool.map(measure, jobs):
            m = re.search(r"MediaPipe ([\d.nan]+); jitter ratio ([\d.nan]+); coverage ([\d.]+)", line)
            if m:
                print(f"{clip + '_' + variant:24s} {m[1]:>7s} {m[2]:>7s} {m[3]:>9s}", flush=True)
            else:
                print(f"{clip + '_' + variant:24s} {line}", flush=True)
    print("bars (shared clips): NME <= 0.05, jitter ratio <= 1.5, coverage >= 0.98")
    return 0


if __name__ == "__main__":
    sys.exit(main())
