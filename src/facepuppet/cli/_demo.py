"""`facepuppet demo`: the whole chain on a digital performer and the built-in Toy, with ground truth."""

from __future__ import annotations

import argparse
import contextlib
import math
import os
from pathlib import Path

#: Longest demo performance, seconds, and the most memory its rendered frames may take, bytes.
MAX_SECONDS = 600.0
MAX_BYTES = 3 * 2**30


def register(subparsers) -> None:
    from facepuppet.demo.run import DEFAULT_TRACKER, TRACKERS

    p = subparsers.add_parser(
        "demo", help="run the built-in demo (no data, network or camera needed)",
        description="Render a digital performer, track it, capture its key expressions, rig the built-in Toy "
                    "character, animate it from a scripted performance, write every file into a folder and "
                    "print the error against ground truth.")
    p.add_argument("-o", "--output", default="facepuppet-demo", metavar="FOLDER",
                   help="folder to write into (default ./facepuppet-demo)")
    p.add_argument("--seconds", type=float, default=8.0, metavar="S", help="length of the performance (8)")
    p.add_argument("--seed", type=int, default=0, help="seed of the scripted performance")
    p.add_argument("--tracker", choices=tuple(TRACKERS), default=DEFAULT_TRACKER,
                   help="what tracks the performer: " + "; ".join(f"{k}: {v}" for k, v in TRACKERS.items())
                        + f" (default {DEFAULT_TRACKER})")
    p.add_argument("--model", metavar="TASK", default=None,
                   help="MediaPipe face_landmarker.task of --tracker mediapipe (default $FACEPUPPET_FACE_LANDMARKER)")
    p.add_argument("--no-preview", action="store_true", help="skip the side-by-side preview video")
    p.add_argument("--monkey", action="store_true",
                   help="also animate the built-in Monkey from the same performance (preview-monkey.mp4)")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.set_defaults(run=run,
                   inputs=(("model", "--model"),),
                   outputs=(("output", "-o"),),
                   folder_outputs=("output",))


def run(args: argparse.Namespace) -> int:
    from facepuppet.demo.run import FILES, TRACKERS, DemoConfig, run_demo

    if not math.isfinite(args.seconds) or args.seconds < 4.6:
        raise ValueError(f"--seconds must be at least 4.6 (each key expression gets its turn), got {args.seconds}")
    defaults = DemoConfig()
    need = args.seconds * defaults.fps * defaults.size ** 2 * 3 * 2   # the rendered frames, and a copy
    if args.seconds > MAX_SECONDS or need > MAX_BYTES:
        raise ValueError(f"--seconds {args.seconds:g}: at most {MAX_SECONDS:g} (the demo renders the whole "
                         f"performance in memory: {need / 2**30:.1f} GiB asked, at most {MAX_BYTES / 2**30:.0f})")
    if args.model is not None and args.tracker != "mediapipe":
        raise ValueError(f"--model is for --tracker mediapipe, not --tracker {args.tracker}")
    config = DemoConfig(seconds=args.seconds, seed=args.seed, tracker=args.tracker, preview=not args.no_preview,
                        progress=False if args.no_progress else None, model=args.model,
                        monkey=args.monkey)
    print(f"facepuppet demo: tracking with {TRACKERS[config.tracker]}")
    if config.tracker == "truth":
        print("  (no image is analysed: the chain runs on exact curves; the colour tracker is the default)")
    with _remove_on_failure(Path(args.output)):
        result = run_demo(args.output, config)
    print(f"wrote into {args.output}/")
    for name, path in result.files.items():
        print(f"  {path.name:<24} {FILES[name]}")
    steps = ", ".join(f"{k} {v:.1f} s" for k, v in result.timings.items())
    tracked = f"face tracked in {100 * result.coverage:.0f}% of them"
    if result.tracker != "truth":
        tracked += f", curves {result.curve_error:.1f} px from the true ones (median)"
    print(f"performance: {result.frames} frames; {tracked}")
    print(f"relative vertex error against ground truth: {result.error:.3f} "
          f"(0 perfect, 1 = as far off as the neutral face; bar 0.5, goal 0.3)"
          + (" -- with the TRUE curves as the track" if result.tracker == "truth" else ""))
    print(f"time: {result.seconds:.1f} s in all ({steps})")
    return 0


@contextlib.contextmanager
def _remove_on_failure(folder: Path):
    """On any failure or interrupt, remove what the demo created in ``folder`` (the folder too, if it made it)
    and end the worker processes it started; files that were there before are left alone."""
    from facepuppet.demo.run import FILES

    existed = folder.is_dir()
    before = {name for name in FILES if (folder / name).exists()} if existed else set()
    try:
        yield
    except BaseException:
        end_children()
        for name in FILES:
            if name not in before:
                with contextlib.suppress(OSError):
                    (folder / name).unlink()
        if not existed:
            with contextlib.suppress(OSError):
                folder.rmdir()
        raise


#: The module the demo's kernel-compiling worker processes run (``python -m ...``).
WORKER_MODULE = "facepuppet.capture.color.precompile"


def end_children(timeout: float = 5.0) -> None:
    """Terminate the kernel precompile workers this process started (its children running
    :data:`WORKER_MODULE`), by their process ids; other children (a caller's own) are left alone."""
    import signal
    import time

    pids = []
    for task in Path(f"/proc/{os.getpid()}/task").glob("*/children"):
        with contextlib.suppress(OSError, ValueError):
            pids += [int(p) for p in task.read_text().split()]
    ours = []
    for pid in pids:
        with contextlib.suppress(OSError):
            if WORKER_MODULE in Path(f"/proc/{pid}/cmdline").read_bytes().decode(errors="replace"):
                os.kill(pid, signal.SIGTERM)
                ours.append(pid)
    deadline = time.monotonic() + timeout
    for pid in ours:
        with contextlib.suppress(OSError):
            while os.waitpid(pid, os.WNOHANG) == (0, 0) and time.monotonic() < deadline:
                time.sleep(0.02)
