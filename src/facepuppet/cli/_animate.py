"""`facepuppet animate`: track a performance, map it onto a rig's character, write GLB / CSV / preview."""

from __future__ import annotations

import argparse


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "animate", help="animate a character from a performance video",
        description="Track the performance, map every frame with the rig, smooth, apply the expression gain "
                    "and write the animated character (GLB), optionally its weights as CSV (Live Link Face "
                    "layout for ARKit names) and a side-by-side preview video.")
    p.add_argument("media", metavar="MEDIA", help="video of the performance, image folder or camera:N")
    p.add_argument("--rig", required=True, metavar="RIG.npz", help="rig file (facepuppet rig)")
    p.add_argument("-o", "--output", metavar="OUT.glb", help="animated character to write")
    p.add_argument("--csv", metavar="OUT.csv", help="also write the weights as CSV")
    p.add_argument("--preview", metavar="OUT.mp4", help="also write a side-by-side preview video")
    p.add_argument("--track", metavar="TRACK.npz", help="reuse a track of MEDIA instead of tracking again")
    add_mapping_arguments(p)
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(run=run,
                   inputs=(("media", "MEDIA"), ("rig", "--rig"), ("profile", "--profile"), ("model", "--model"),
                           ("track", "--track")),
                   outputs=(("output", "-o"), ("csv", "--csv"), ("preview", "--preview")))


def add_mapping_arguments(p: argparse.ArgumentParser) -> None:
    """The options that decide how a performance is tracked and mapped (shared with `facepuppet batch`)."""
    p.add_argument("--backend", default="color", choices=("color", "mediapipe"),
                   help="tracker (default color, the paper's); use the one the key expressions were captured "
                        "with")
    p.add_argument("--profile", metavar="PROFILE.npz", help="performer profile of the colour tracker")
    p.add_argument("--model", metavar="TASK", help="MediaPipe face_landmarker.task "
                   "(default: $FACEPUPPET_FACE_LANDMARKER)")
    p.add_argument("--gain", action="append", metavar="G", default=[],
                   help="expression gain: a number for all key-models, NAME=NUMBER for one key-model or face "
                        "region (mouth, brows; repeatable)")
    p.add_argument("--smoothing", default="on", metavar="on|off|K=V,...",
                   help="One-Euro smoothing: on (default), off, or e.g. min_cutoff=1.5,beta=2,hold=0.25,ease=0.3")
    p.add_argument("--no-head", action="store_true", help="do not animate the head rotation")


def animate_config(args: argparse.Namespace):
    """The :class:`~facepuppet.pipeline.animate.AnimateConfig` of parsed :func:`add_mapping_arguments`."""
    from facepuppet.pipeline.animate import AnimateConfig
    from facepuppet.pipeline.gain import parse_gain
    from facepuppet.pipeline.smoothing import parse_smoothing
    from facepuppet.pipeline.tracking import TrackerOptions

    return AnimateConfig(
        tracker=TrackerOptions(backend=args.backend, profile=args.profile, model=args.model,
                               progress=False if args.no_progress else None),
        smoothing=parse_smoothing(args.smoothing), gain=parse_gain(args.gain), head_rotation=not args.no_head)


def run(args: argparse.Namespace) -> int:
    from facepuppet.pipeline.animate import animate

    if not (args.output or args.csv or args.preview):
        raise ValueError("nothing to write: give -o OUT.glb, --csv OUT.csv or --preview OUT.mp4")
    config = animate_config(args)
    anim = animate(args.media, args.rig, glb=args.output, csv=args.csv, preview=args.preview,
                   track=args.track, config=config, keep_track=False, keep_weights=False)
    n, ok = len(anim.valid), int(anim.valid.sum())
    t = anim.timings
    busy = t.get("track", 0.0) + t.get("map", 0.0) + t.get("write", 0.0)
    wrote = ", ".join(x for x in (args.output, args.csv, args.preview) if x)
    if anim.regions:
        channels = (f"{len(anim.names)} channels ({len(anim.regions)} regions x "
                    f"{len(anim.names) // len(anim.regions)} key-models)")
    else:
        channels = f"{len(anim.names)} key-models"
    print(f"animate: {n} frames ({ok} with a face), {channels}; "
          f"{n / busy if busy > 0 else float('inf'):.0f} frames/s (track, map, write); wrote {wrote}")
    return 0
