"""`facepuppet calibrate`: capture the performer's key expressions from a marked video, automatically, or live."""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

#: How a camera is named wherever a medium is (as in ``track`` and ``animate``).
CAMERA_PREFIX = "camera:"


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "calibrate", help="capture the performer's key expressions (for facepuppet rig)",
        description="Capture the performer's neutral face and key expressions (feature points) for the "
                    "character's key-models: from a video with a marks file (--marks), from a video picked "
                    "automatically by MediaPipe's blendshape scores for an ARKit-named character (--auto), or "
                    "live from a camera (MEDIA camera:N, or --camera N). Marks file: one 'WHEN,NAME' per line; "
                    "WHEN is seconds ('1.5s'), a clock time ('00:01.5') or a frame number ('45'); NAME is "
                    "'neutral' or a key-model name. --train-profile first trains the colour tracker's "
                    "performer profile on MEDIA.")
    p.add_argument("media", nargs="?", metavar="MEDIA",
                   help="video of the key expressions, image folder, or camera:N")
    p.add_argument("-o", "--output", required=True, metavar="EXAMPLES.npz",
                   help="key expressions file to write (for facepuppet rig --performer)")
    how = p.add_mutually_exclusive_group()
    how.add_argument("--marks", metavar="MARKS.csv", help="marks file naming the expression at times or frames")
    how.add_argument("--auto", action="store_true",
                     help="pick the frames by MediaPipe's blendshape scores (needs --character with ARKit names)")
    how.add_argument("--camera", metavar="N",
                     help="capture live from camera N, as MEDIA camera:N does (camera:VIDEO: a video standing "
                          "in for the camera)")
    p.add_argument("--character", metavar="CHARACTER",
                   help="the character (.glb / .vrm, OBJ folder, or built-in: toy) whose key-models to capture "
                        "key expressions for")
    p.add_argument("--backend", default="color", choices=("color", "mediapipe"),
                   help="tracker making the feature points; use the one you will animate with (default color)")
    p.add_argument("--profile", metavar="PROFILE.npz", help="performer profile of the colour tracker")
    p.add_argument("--train-profile", metavar="PROFILE.npz", dest="train_profile",
                   help="first train the colour tracker's performer profile on MEDIA, labelled by MediaPipe, "
                        "save it here and use it")
    p.add_argument("--make-profile", metavar="PROFILE.npz", dest="train_profile", help=argparse.SUPPRESS)
    p.add_argument("--model", metavar="TASK", help="MediaPipe face_landmarker.task "
                   "(default: $FACEPUPPET_FACE_LANDMARKER)")
    p.add_argument("--track", metavar="TRACK.npz", help="reuse a track of MEDIA made by facepuppet track")
    p.add_argument("--window", type=int, default=5, metavar="N", help="frames averaged per expression (5)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(run=run,
                   inputs=(("media", "MEDIA"), ("marks", "--marks"), ("character", "--character"),
                           ("profile", "--profile"), ("model", "--model"), ("track", "--track")),
                   outputs=(("output", "-o"), ("train_profile", "--train-profile")))


def _camera(args: argparse.Namespace) -> str | None:
    """The camera to capture from (``camera:N``), or None for a recorded video; checks the combinations."""
    media_is_camera = bool(args.media) and args.media.startswith(CAMERA_PREFIX)
    if args.camera is not None:
        return args.camera if args.camera.startswith(CAMERA_PREFIX) else f"{CAMERA_PREFIX}{args.camera}"
    if media_is_camera:
        if args.marks or args.auto:
            raise ValueError(f"MEDIA {args.media}: --marks and --auto need a recorded video, not a camera")
        return args.media
    if not (args.marks or args.auto):
        raise ValueError("say how to capture the key expressions: --marks MARKS.csv, --auto, or a camera "
                         "(MEDIA camera:N or --camera N)")
    return None


def _check_auto(args: argparse.Namespace, character, scores) -> None:
    """Everything ``--auto`` lacks, named in one error: the character, and MediaPipe's package and model when
    no track brings the blendshape scores."""
    import importlib.util
    import os

    missing = []
    if character is None:
        missing.append("--character (its ARKit key-model names say what to look for)")
    if scores is None:
        model = args.model or os.environ.get("FACEPUPPET_FACE_LANDMARKER")
        if not model:
            missing.append("--model face_landmarker.task (or $FACEPUPPET_FACE_LANDMARKER): MediaPipe's blendshape "
                           "scores pick the frames")
        elif not Path(model).expanduser().is_file():
            missing.append(f"the face landmarker model {model} (not found)")
        if importlib.util.find_spec("mediapipe") is None:
            missing.append("the mediapipe package: pip install 'facepuppet[mediapipe]'")
    if missing:
        raise ValueError("--auto needs " + "; and ".join(missing))


def run(args: argparse.Namespace) -> int:
    from facepuppet.io.performer import save_performer
    from facepuppet.pipeline import examples
    from facepuppet.pipeline.tracking import TrackerOptions

    camera = _camera(args)
    config = examples.ExamplesConfig(
        tracker=TrackerOptions(backend=args.backend, profile=args.profile, model=args.model,
                               progress=False if args.no_progress else None),
        window=args.window)
    character = None
    if args.character:
        from facepuppet.demo.characters import load_character_arg

        character = load_character_arg(args.character)
    track = None
    if args.track:
        from facepuppet.io.track import load_track
        from facepuppet.pipeline.provenance import check_track_media

        track = load_track(args.track)
        check_track_media(track, args.media)
    labels = None
    if args.train_profile:
        if not args.media or args.media.startswith(CAMERA_PREFIX):
            raise ValueError("--train-profile needs MEDIA, a recorded clip of the performer")
        from facepuppet.pipeline.profile import train_profile_on_media

        labels = train_profile_on_media(args.media, args.train_profile, model=args.model,
                                        progress=False if args.no_progress else None)
        config = examples.ExamplesConfig(tracker=replace(config.tracker, profile=args.train_profile),
                                         window=args.window)
        print(f"calibrate: trained the colour tracker's performer profile on {args.media}; "
              f"wrote {args.train_profile}")
    if camera is not None:
        if character is None:
            raise ValueError(f"{camera} needs --character (its key-models are shown to copy)")
        result = examples.from_camera(camera, character, config=config)
        source = camera
    else:
        if not args.media:
            raise ValueError("MEDIA (the video of the key expressions) is required with --marks and --auto")
        source = args.media
        if args.auto:
            scores = track if track is not None and track.extras and "blendshapes" in track.extras else labels
            _check_auto(args, character, scores)
            result = examples.from_auto(args.media, character.names, config=config, scores_track=scores,
                                        track=track if track is not None and track.backend == args.backend
                                        else None)
        else:
            result = examples.from_marks(args.media, args.marks, config=config, track=track,
                                         names=character.names if character is not None else None)
    from facepuppet._util.digest import file_digest

    made_with = track.backend if track is not None and args.marks else args.backend
    profile = config.tracker.profile if made_with == "color" else None
    result = replace(result, backend=made_with, profile_hash=file_digest(profile) if profile else None)
    save_performer(args.output, result)
    left_out = [w[len("left out "):] for w in result.warnings if w.startswith("left out ")]
    for w in result.warnings:
        if not w.startswith("left out "):
            print(f"facepuppet calibrate: warning: {w}", file=sys.stderr)
    if left_out:
        print(f"facepuppet calibrate: left out {len(left_out)} key-models: {'; '.join(left_out)}", file=sys.stderr)
    print(f"calibrate: neutral + {len(result.names)} key expressions ({', '.join(result.names)}) from {source}; "
          f"wrote {args.output}")
    return 0
