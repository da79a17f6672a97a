"""`facepuppet track`: a video, image or folder of images -> a track file (and optionally an overlay video)."""

from __future__ import annotations

import argparse
import contextlib
import logging

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
    p.set_defaults(run=run,
                   inputs=(("media", "MEDIA"), ("profile", "--profile"), ("model", "--model")),
                   outputs=(("output", "-o"), ("preview", "--preview")))


def run(args: argparse.Namespace) -> int:
    import sys

    from tqdm import tqdm

    from facepuppet._util.digest import file_digest, media_record
    from facepuppet._util.interrupt import between_frames, check
    from facepuppet.capture import CURVE_NAMES, POINT_NAMES
    from facepuppet.capture.tracking import make_tracker
    from facepuppet.errors import FacepuppetError
    from facepuppet.io.frames import is_still, open_media
    from facepuppet.io.track_writer import TrackWriter
    from facepuppet.pipeline.stream import source_frames

    if args.max_frames is not None and args.max_frames < 1:
        raise ValueError(f"--max-frames must be at least 1, got {args.max_frames}")
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
        # the track is spooled frame by frame beside the output (memory flat in the take's length)
        writer = stack.enter_context(TrackWriter(
            args.output, fps=source.fps, frame_size=source.frame_size, curve_names=CURVE_NAMES,
            point_names=POINT_NAMES, backend=tracker.name, static_extras=getattr(tracker, "static_extras", None),
            profile_hash=file_digest(args.profile) if args.profile else None, stack=stack))
        overlay = None
        if args.preview:
            from facepuppet.export.overlay import draw_overlay
            from facepuppet.export.preview import open_preview

            # written while tracking (one pass, works for a camera too); kept only if everything succeeds;
            # entered last, so its checks run before any output is renamed
            overlay = stack.enter_context(open_preview(args.preview, source.fps, source.frame_size))
        total = source.frame_count if args.max_frames is None else min(source.frame_count or args.max_frames,
                                                                       args.max_frames)
        bar = stack.enter_context(tqdm(total=total, unit="frame", desc=f"track ({tracker.name})", leave=False,
                                       disable=args.no_progress or not sys.stderr.isatty(), dynamic_ncols=True))
        with between_frames():
            for frame in source_frames(source, max_frames=args.max_frames):
                check()
                features = tracker.track(frame.rgb, int(round(frame.time * 1000.0)))
                writer.add(features, frame.time)
                if overlay is not None:
                    overlay.write(draw_overlay(frame.rgb, features))
                bar.update(1)
        if writer.n_frames == 0:
            raise FacepuppetError(f"{args.media}: no frames to track")
        if writer.n_valid == 0:
            raise FacepuppetError(f"{args.media}: no face found in any of its {writer.n_frames} frame(s)")
        writer.set_media(media_record(args.media, writer.n_frames))
        writer.finish()
    log.info("%s: %d of %d frames tracked -> %s", args.media, writer.n_valid, writer.n_frames, args.output)
    wrote = ", ".join(x for x in (args.output, args.preview) if x)
    print(f"track: {writer.n_frames} frames ({writer.n_valid} with a face), {args.backend} tracker; "
          f"wrote {wrote}")
    return 0
