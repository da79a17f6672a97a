"""`facepuppet calibrate`: make a performer's key expressions from a marked video, automatically, or live."""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "calibrate", help="make the performer's key expressions (for facepuppet rig)",
        description="Make the performer's neutral face and key expressions (feature points) from footage: "
                    "a video with a marks file (--marks), a video picked automatically by MediaPipe's "
                    "blendshape scores for an ARKit-named character (--auto), or a camera, interactively "
                    "(--camera). Marks file: one 'WHEN,NAME' per line; WHEN is seconds ('1.5s'), a clock "
                    "time ('00:01.5') or a frame number ('45'); NAME is 'neutral' or a key-model name.")
    p.add_argument("media", nargs="?", metavar="MEDIA", help="calibration video, image folder")
    p.add_argument("-o", "--output", required=True, metavar="EXAMPLES.npz", help="key expressions file to write")
    how = p.add_mutually_exclusive_group(required=True)
    how.add_argument("--marks", metavar="MARKS.csv", help="marks file naming the expression at times or frames")
    how.add_argument("--auto", action="store_true",
                     help="pick the frames by MediaPipe's blendshape scores (needs --character with ARKit names)")
    how.add_argument("--camera", metavar="N",
                     help="capture live from camera N (or camera:VIDEO, a video standing in for the camera)")
    p.add_argument("--character", metavar="CHARACTER",
                   help="the character (.glb or OBJ folder) whose key-models to make expressions for")
    p.add_argument("--backend", default="color", choices=("color", "mediapipe"),
                   help="tracker making the feature points; use the one you will animate with (default color)")
    p.add_argument("--profile", metavar="PROFILE", help="colour tracker's performer profile")
    p.add_argument("--make-profile", metavar="PROFILE.npz",
                   help="first train the colour tracker's performer profile on MEDIA, labelled by MediaPipe, "
                        "save it here and use it")
    p.add_argument("--model", metavar="TASK", help="MediaPipe face_landmarker.task "
                   "(default: $FACEPUPPET_FACE_LANDMARKER)")
    p.add_argument("--track", metavar="TRACK.npz", help="reuse a track of MEDIA made by facepuppet track")
    p.add_argument("--window", type=int, default=5, metavar="N", help="frames averaged per expression (5)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from facepuppet.pipeline import calibrate as cal
    from facepuppet.pipeline.tracking import TrackerOptions

    config = cal.CalibrateConfig(
        tracker=TrackerOptions(backend=args.backend, profile=args.profile, model=args.model,
                               progress=False if args.no_progress else None),
        window=args.window)
    character = None
    if args.character:
        from facepuppet.io.character import load_character

        character = load_character(args.character)
    track = None
    if args.track:
        from facepuppet.io.track import load_track

        track = load_track(args.track)
    labels = None
    if args.make_profile:
        if not args.media:
            raise ValueError("--make-profile needs MEDIA (a clip of the performer)")
        labels = cal.make_profile(args.media, args.make_profile, model=args.model,
                                  progress=False if args.no_progress else None)
        config = cal.CalibrateConfig(tracker=replace(config.tracker, profile=args.make_profile),
                                     window=args.window)
        print(f"calibrate: trained the colour tracker's profile on {args.media}; wrote {args.make_profile}")
    if args.camera is not None:
        if character is None:
            raise ValueError("--camera needs --character (its key-models are shown to copy)")
        cam = args.camera if args.camera.startswith("camera:") else f"camera:{args.camera}"
        result = cal.calibrate_interactive(cam, character, config=config)
        source = cam
    else:
        if not args.media:
            raise ValueError("MEDIA (the calibration video) is required with --marks and --auto")
        source = args.media
        if args.auto:
            if character is None:
                raise ValueError("--auto needs --character (its ARKit key-model names say what to look for)")
            scores = track if track is not None and track.extras and "blendshapes" in track.extras else labels
            result = cal.calibrate_auto(args.media, character.names, config=config, scores_track=scores,
                                        track=track if track is not None and track.backend == args.backend
                                        else None)
        else:
            result = cal.calibrate_marks(args.media, args.marks, config=config, track=track,
                                         names=character.names if character is not None else None)
    cal.save_examples(args.output, result)
    left_out = [w[len("left out "):] for w in result.warnings if w.startswith("left out ")]
    for w in result.warnings:
        if not w.startswith("left out "):
            print(f"facepuppet calibrate: warning: {w}", file=sys.stderr)
    if left_out:
        print(f"facepuppet calibrate: left out {len(left_out)} key-models: {'; '.join(left_out)}", file=sys.stderr)
    print(f"calibrate: neutral + {len(result.names)} key expressions ({', '.join(result.names)}) from {source}; "
          f"wrote {args.output}")
    return 0
