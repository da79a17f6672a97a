"""`facepuppet track`: a video, image or folder of images -> a track file (and optionally an overlay video)."""

from __future__ import annotations

import argparse
import contextlib
import logging
from pathlib import Path

log = logging.getLogger(__name__)


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "track", help="track the face in a video, image, image folder or camera:N",
        description="Track the performer's facial features (curves, feature points, head pose) in every frame "
                    "and write them to a track file (.npz). MEDIA is a video file, an image, a folder of images "
                    "or camera:N.")
    p.add_argument("media", metavar="MEDIA", help="video file, image, folder of images, or camera:N")
    p.add_argument("-o", "--output", required=True, metavar="TRACK.npz", help="track file to write")
    p.add_argument("--backend", default="color", choices=("color", "mediapipe"),
                   help="color: the paper's colour tracker (default); mediapipe: the landmark backend "
                        "(optional extra)")
    p.add_argument("--profile", metavar="PROFILE.npz", help="performer profile of the colour tracker (facepuppet "
                   "calibrate --train-profile makes one)")
    p.add_argument("--model", metavar="PATH", help="MediaPipe face_landmarker.task (default: "
                   "$FACEPUPPET_FACE_LANDMARKER)")
    p.add_argument("--preview", metavar="OVERLAY.mp4", help="also write the frames with the tracked curves and "
                   "head axes drawn on them")
    p.add_argument("--max-frames", type=int, metavar="N", help="track at most N frames")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(run=run)


def _check_output(path: str, option: str) -> None:
    folder = Path(path).parent
    if not folder.is_dir():
        raise ValueError(f"{option} {path}: folder {folder} does not exist")
    if Path(path).is_dir():
        raise ValueError(f"{option} {path}: is a folder")


def run(args: argparse.Namespace) -> int:
    from facepuppet.capture.tracking import make_tracker, track_media
    from facepuppet.io.frames import is_still, open_media
    from facepuppet.io.track import save_track

    if args.max_frames is not None and args.max_frames < 1:
        raise ValueError(f"--max-frames must be at least 1, got {args.max_frames}")
    _check_output(args.output, "-o")
    if args.preview:
        _check_output(args.preview, "--preview")
    if args.backend != "color" and args.profile:
        raise ValueError("--profile applies to the colour tracker only (--backend color)")
    if args.backend != "mediapipe" and args.model:
        raise ValueError("--model applies to --backend mediapipe only")
    options: dict = {}
    if args.backend == "mediapipe":
        options = {"model_path": args.model, "running_mode": "image" if is_still(args.media) else "video"}
    elif args.profile:
        options = {"profile": args.profile}
    with contextlib.ExitStack() as stack:
        source = stack.enter_context(open_media(args.media))  # a bad medium fails before a model loads
        tracker = make_tracker(args.backend, **options)
        stack.callback(tracker.close)
        on_frame = None
        if args.preview:
            from facepuppet.capture.overlay import OverlayWriter

            # written while tracking (one pass, works for a camera too); kept only if everything succeeds
            overlay = stack.enter_context(OverlayWriter(args.preview, source.frame_size, source.fps))

            def on_frame(i, rgb, features):
                overlay.write(rgb, features)

        track = track_media(source, tracker, progress=not args.no_progress, max_frames=args.max_frames,
                            on_frame=on_frame)
        save_track(args.output, track)
    log.info("%s: %d of %d frames tracked -> %s", args.media, int(track.valid.sum()), track.n_frames, args.output)
    wrote = ", ".join(x for x in (args.output, args.preview) if x)
    print(f"track: {track.n_frames} frames ({int(track.valid.sum())} with a face), {args.backend} tracker; "
          f"wrote {wrote}")
    return 0
