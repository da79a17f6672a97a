"""``facepuppet live``: the character moving while the performer performs."""

from __future__ import annotations

import argparse
import contextlib
import sys

HELP = "animate the character live from a camera (or a video standing in for one) and stream it"


def register(sub) -> None:
    p = sub.add_parser(
        "live", help=HELP,
        description="Track the performer frame by frame as the camera delivers them, map every frame with the "
                    "rig and send the weights and head rotation out as they come: to a browser viewer, to a "
                    "VMC receiver (VSeeFace, VNyan, Warudo), to Unreal's Live Link; optionally record the take "
                    "as GLB and CSV (exactly as 'facepuppet animate' writes them). Ctrl+C, SIGTERM, 'q' or the "
                    "source's end stop it; 'n' (or the viewer's button) takes the current face as neutral.")
    p.add_argument("source", metavar="SOURCE",
                   help="camera:N (a device), or a video file / image folder standing in for a camera")
    p.add_argument("--rig", required=True, metavar="RIG.npz", help="rig file (facepuppet rig)")
    p.add_argument("--backend", choices=("color", "mediapipe"), default="color",
                   help="tracker (default color, the paper's); use the one the rig was made with")
    p.add_argument("--profile", metavar="PROFILE", help="colour tracker's performer profile")
    p.add_argument("--model", metavar="TASK", help="MediaPipe face_landmarker.task (default: "
                                                   "$FACEPUPPET_FACE_LANDMARKER)")
    p.add_argument("--viewer", metavar="[HOST:]PORT", help="serve the browser viewer (page and WebSocket) here; "
                                                          "host 127.0.0.1 unless given")
    p.add_argument("--vmc", metavar="HOST:PORT", help="send the VMC protocol (OSC over UDP) here, e.g. 39539")
    p.add_argument("--livelink", metavar="HOST:PORT", help="send Live Link Face packets (UDP) here, e.g. 11111")
    p.add_argument("--record", metavar="OUT.glb", help="record the take as an animated character")
    p.add_argument("--csv", metavar="OUT.csv", help="record the take's weights as CSV")
    p.add_argument("--stats", metavar="STATS.json", help="write the session's frames, drops, latency and fps")
    p.add_argument("--pace", choices=("realtime", "fast"), default="realtime",
                   help="realtime: frames as they come, late ones dropped (default); fast: every frame of a "
                        "file, as fast as it goes")
    p.add_argument("--max-frames", type=int, metavar="N", help="stop after N frames")
    p.add_argument("--gain", action="append", metavar="G",
                   help="expression gain: a number for all key-models, NAME=NUMBER for one key-model or face "
                        "region (mouth, brows; repeatable)")
    p.add_argument("--smoothing", default="on", metavar="on|off|K=V,...", help="One-Euro smoothing (as animate)")
    p.add_argument("--no-head", action="store_true", help="do not send or record the head rotation")
    p.add_argument("--no-status", action="store_true", help="no status line")
    p.set_defaults(run=run,
                   inputs=(("source", "SOURCE"), ("rig", "--rig"), ("profile", "--profile"), ("model", "--model")),
                   outputs=(("record", "--record"), ("csv", "--csv"), ("stats", "--stats")))


def run(args: argparse.Namespace) -> int:
    from facepuppet.live.frame import parse_address
    from facepuppet.live.session import LiveConfig, run_live
    from facepuppet.pipeline.gain import parse_gain
    from facepuppet.pipeline.provenance import check_rig_backend, check_rig_profile
    from facepuppet.pipeline.rig import load_rig
    from facepuppet.pipeline.smoothing import parse_smoothing
    from facepuppet.pipeline.tracking import TrackerOptions

    viewer = parse_address(args.viewer, what="--viewer") if args.viewer else None
    vmc = parse_address(args.vmc, what="--vmc") if args.vmc else None
    livelink = parse_address(args.livelink, what="--livelink") if args.livelink else None
    config = LiveConfig(
        tracker=TrackerOptions(backend=args.backend, profile=args.profile, model=args.model, progress=False),
        smoothing=parse_smoothing(args.smoothing), gain=parse_gain(args.gain), head_rotation=not args.no_head,
        pace=args.pace, max_frames=args.max_frames, status=not args.no_status)
    rig = load_rig(args.rig)
    check_rig_backend(rig, args.backend, args.rig)
    if args.backend == "color":
        check_rig_profile(rig, args.profile, args.rig)
    with contextlib.ExitStack() as stack:
        senders = []
        if viewer is not None:
            from facepuppet.live.viewer import ViewerServer

            server = ViewerServer(rig.character, *viewer, names=rig.names)
            stack.callback(server.close)
            senders.append(server)
            print(f"live: viewer at {server.url}", file=sys.stderr, flush=True)
        if vmc is not None:
            from facepuppet.live.vmc import VmcSender

            senders.append(stack.enter_context(contextlib.closing(VmcSender(rig.names, *vmc))))
        if livelink is not None:
            from facepuppet.live.livelink import LiveLinkSender

            senders.append(stack.enter_context(contextlib.closing(LiveLinkSender(rig.names, *livelink))))
        result = run_live(args.source, rig, config=config, record=args.record, csv=args.csv, stats=args.stats,
                          senders=senders, on_start=lambda: print("live: running (q or Ctrl+C stops)",
                                                                   file=sys.stderr, flush=True))
    if result.frames == 0:
        print("live: stopped before the first frame; nothing written")
        return 0
    s = result.stats
    wrote = ", ".join(x for x in (args.record, args.csv, args.stats) if x)
    print(f"live: {result.frames} frames ({result.with_face} with a face), {result.dropped} dropped; "
          f"{s['fps'] or 0:.0f} fps, latency p50 {s['latency_ms']['p50'] or 0:.1f} ms, "
          f"p95 {s['latency_ms']['p95'] or 0:.1f} ms" + (f"; wrote {wrote}" if wrote else ""))
    return 0
