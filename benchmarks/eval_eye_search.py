"""The colour tracker's eye search at MediaPipe's face frame: where one step of it puts the eyes, and the scale it
pulls a frame found afresh to.

The first search for a face pulls each candidate frame onto the eyes it finds, a few steps in a row, and the face is
followed at the size it was found at. An eye search biased outward (an eyeliner's wing, the hair beside an eye lit
against the face, the eye's white not told from skin in a warm light) grows the frame at each step. Here the search
starts from the frame MediaPipe's eyes give (the eye centres the means of its lid curves) on every ``--every``-th
frame of each clip, as filmed and in the robustness benchmark's copies (``eval_robustness.altered`` and the drawn
glasses), with the built-in profile and no landmark model, as a fresh candidate is measured
(``ColorTracker.measure`` without following), in the light as filmed (the first search also tries each frame with
its light evened out, which is not done here: a crop whose cheeks look like skin to neither skin model in that
light counts as not found). MediaPipe runs on each copy's frame itself (image mode).

Printed per clip and copy: the share of frames whose eyes were found; each eye's centre off MediaPipe's, outward
(positive: away from the nose) and down, medians in face units (the eye-centre distance); and the scale of the
step (the eye distance found over MediaPipe's): median and 90th percentile. Then the mean and largest
``|log scale|`` of the medians over all rows. A search without bias gives a scale of 1 (the anchors' own height
offset shows in the down column).

    python benchmarks/eval_eye_search.py [--clips performer_a ...] [--variants as-filmed warm ...] [--every 5]
                                         [--model face_landmarker.task] [--assets PATH]
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import drawn  # noqa: E402  (this folder's module of things drawn on the face)
import eval_robustness  # noqa: E402  (the robustness copies' alterations)

ROOT = Path(__file__).resolve().parents[1]
CLIPS = ("performer_a", "performer_b_exaggerated", "performer_c")
AS_FILMED = "as-filmed"
VARIANTS = (AS_FILMED, "warm", "cool", "dim", "deep", "toplit", "sidelit", "lamp_left", "lamp_right", "glasses")


def frames_of(path: Path, every: int):
    """(index, RGB frame) of every ``every``-th frame of the video ``path``."""
    from facepuppet.io.frames import open_media

    with open_media(path) as src:
        for i, rgb in enumerate(src):
            if i % every == 0:
                yield i, rgb


def copy_frame(rgb: np.ndarray, variant: str, i: int, rng: np.random.Generator, mp) -> np.ndarray | None:
    """Frame ``i`` of the ``variant`` copy (``mp``: MediaPipe's tracker, for the glasses drawn on its curves), or
    None where the glasses have no face to go on."""
    if variant == AS_FILMED:
        return rgb
    if variant == "glasses":
        f = mp.track(rgb, 0)
        return drawn.glasses_copy_frame(rgb, f.curves, i) if f.valid else None
    return eval_robustness.altered(rgb, variant, rng)


def one_step(tracker, rgb: np.ndarray, curves: np.ndarray) -> tuple[float, ...] | None:
    """(outward right, outward left, down right, down left, scale) of one eye-search step from the frame of the
    eye centres of ``curves`` (C, 4, 2) on ``rgb``, face units; None where no eyes are found."""
    from facepuppet.capture.color.eye_anchors import eye_centres_of
    from facepuppet.capture.color.face import FaceFrame

    true = eye_centres_of(curves)
    frame = FaceFrame.from_eyes(true[0], true[1])
    got = tracker.measure(rgb, frame, follow=False, gain=1.0, outline=False)
    if got is None or not got.eyes_found:
        return None
    a, b, tx, ty = got.correction
    px = float(tracker.config.measure.px)
    A = frame.crop_matrix(px)
    anchors = tracker.anchors_px[:2] @ np.array([[a, b], [-b, a]]) + [tx, ty]      # the eyes found, crop pixels
    true_px = true @ A[:, :2].T + A[:, 2]
    d = (anchors - true_px) / px
    return (-d[0, 0], d[1, 0], d[0, 1], d[1, 1],
            float(np.linalg.norm(anchors[1] - anchors[0]) / np.linalg.norm(true_px[1] - true_px[0])))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--clips", nargs="+", default=list(CLIPS), metavar="NAME", help="clips of the assets' video folder")
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS), metavar="VARIANT",
                    choices=(AS_FILMED, "glasses") + tuple(v for v in eval_robustness.VARIANTS if v != "face80"),
                    help=f"copies ({AS_FILMED}: the clip itself; default: {' '.join(VARIANTS)})")
    ap.add_argument("--every", type=int, default=5, help="every how many frames one is measured (default 5)")
    ap.add_argument("--model", help="face_landmarker.task (default $FACEPUPPET_FACE_LANDMARKER or the assets')")
    ap.add_argument("--assets", type=Path,
                    default=Path(os.environ.get("FACEPUPPET_ASSETS", ROOT.parent / "shared" / "assets")))
    args = ap.parse_args(argv)
    if args.every < 1:
        ap.error(f"--every must be at least 1, got {args.every}")
    model = Path(args.model or os.environ.get("FACEPUPPET_FACE_LANDMARKER",
                                              args.assets / "models" / "face_landmarker.task"))
    missing = [p for p in [model] + [args.assets / "video" / f"{c}.mp4" for c in args.clips] if not p.is_file()]
    if missing:
        print(f"eval_eye_search: {missing[0]} is missing", file=sys.stderr)
        return 2

    from facepuppet.capture.color.tracker import ColorTracker
    from facepuppet.capture.tracking import make_tracker

    mp = make_tracker("mediapipe", model_path=model, running_mode="image")
    logs = []
    print(f"{'clip':26s} {'copy':11s} {'found':>5s} {'out R':>6s} {'out L':>6s} {'down R':>6s} {'down L':>6s} "
          f"{'scale':>6s} {'p90':>6s}")
    try:
        for clip in args.clips:
            for variant in args.variants:
                rng, tracker, rows, n = np.random.default_rng(0), ColorTracker(), [], 0
                for i, rgb in frames_of(args.assets / "video" / f"{clip}.mp4", args.every):
                    seen = copy_frame(rgb, variant, i, rng, mp)
                    ref = None if seen is None else mp.track(seen, 0)
                    if ref is None or not ref.valid:
                        continue
                    n += 1
                    step = one_step(tracker, seen, ref.curves)
                    if step is not None:
                        rows.append(step)
                tracker.close()
                if not rows:
                    print(f"{clip:26s} {variant:11s} no eyes found in {n} frames")
                    continue
                r = np.array(rows)
                med = np.median(r, axis=0)
                logs.append(abs(np.log(med[4])))
                print(f"{clip:26s} {variant:11s} {len(r) / n:5.2f} {med[0]:+6.3f} {med[1]:+6.3f} {med[2]:+6.3f} "
                      f"{med[3]:+6.3f} {med[4]:6.3f} {np.percentile(r[:, 4], 90):6.3f}", flush=True)
    finally:
        mp.close()
    if logs:
        print(f"mean |log scale| {np.mean(logs):.4f}, largest {np.max(logs):.4f} over {len(logs)} rows")
    return 0


if __name__ == "__main__":
    sys.exit(main())
