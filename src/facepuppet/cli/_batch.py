"""`facepuppet batch`: animate many clips into one folder, on worker processes here or on a Ray cluster."""

from __future__ import annotations

import argparse
import os

from facepuppet.cli._animate import add_mapping_arguments, animate_config


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "batch", help="animate many performances at once (resumable; local workers or Ray)",
        description="Animate every clip with its rig into OUTDIR/<name>.glb (and .csv, .mp4), each exactly as "
                    "'animate' writes it. OUTDIR/report.csv lists every clip's status, frames, seconds and "
                    "error, with content hashes: a rerun skips the clips already done with the same clip, rig "
                    "and options. Exit code 1 when any clip failed. See docs/batch.md.")
    p.add_argument("clips", nargs="*", metavar="CLIP", help="performance videos (or image folders)")
    p.add_argument("--list", metavar="LIST.csv",
                   help="CSV of clips instead: columns clip[,rig[,output]] (header optional; paths relative "
                        "to the list's folder; empty rig: --rig; empty output: the clip's stem)")
    p.add_argument("--rig", metavar="RIG.npz", help="rig of every clip (of the list's rows that name none)")
    p.add_argument("-o", "--output", required=True, metavar="OUTDIR", help="output folder (made if missing)")
    p.add_argument("--csv", action="store_true", help="also write OUTDIR/<name>.csv (the weights)")
    p.add_argument("--preview", action="store_true", help="also write OUTDIR/<name>.mp4 (side-by-side preview)")
    p.add_argument("--engine", default="local", choices=("local", "ray"),
                   help="local: worker processes here (default); ray: Ray tasks (pip install \"facepuppet[ray]\")")
    p.add_argument("--workers", type=int, metavar="N",
                   help=f"worker processes, or CPUs of a local Ray runtime (default {os.cpu_count()})")
    p.add_argument("--address", metavar="RAY_ADDRESS",
                   help="Ray cluster to use (e.g. auto or ray://head:10001); default: start a local one")
    add_mapping_arguments(p)
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(run=run, inputs=(("list", "--list"), ("rig", "--rig"), ("profile", "--profile"),
                                    ("model", "--model")),
                   outputs=(("output", "-o"),), folder_outputs=("output",))


def run(args: argparse.Namespace) -> int:
    from facepuppet.batch import BatchConfig, jobs_from_clips, read_list, run_batch

    if args.list and args.clips:
        raise ValueError("give clips or --list LIST.csv, not both")
    if not (args.list or args.clips):
        raise ValueError("nothing to do: give clips or --list LIST.csv")
    if args.workers is not None and args.workers < 1:
        raise ValueError(f"--workers: must be at least 1, got {args.workers}")
    if args.address and args.engine != "ray":
        raise ValueError("--address: only with --engine ray")
    jobs = read_list(args.list, args.rig) if args.list else jobs_from_clips(args.clips, args.rig)
    check_jobs(jobs, args)
    config = BatchConfig(animate=animate_config(args), csv=args.csv, preview=args.preview, engine=args.engine,
                         workers=args.workers, address=args.address,
                         progress=False if args.no_progress else None)
    summary = run_batch(jobs, args.output, config)
    c = {s: sum(r.status == s for r in summary.rows) for s in ("done", "skipped", "failed")}
    fps = summary.frames / summary.seconds if summary.seconds > 0 else 0.0
    print(f"batch: {len(summary.rows)} clips: {c['done']} done, {c['skipped']} skipped, {c['failed']} failed; "
          f"{summary.frames} frames in {summary.seconds:.1f} s ({fps:.0f} frames/s); report {summary.report}")
    return 1 if c["failed"] else 0


def check_jobs(jobs, args: argparse.Namespace) -> None:
    """Every job's clip, rig and outputs checked as any command's file arguments are
    (:func:`facepuppet.cli._paths.check_paths`), together with the batch's own, before any work: an output
    that is a clip, a rig, the list or another job's output is refused, as is a clip that is a FIFO."""
    from facepuppet.batch import REPORT_NAME
    from facepuppet.batch.jobs import output_paths
    from facepuppet.cli._paths import check_paths

    inputs = {"--list": args.list, "--rig": args.rig, "--profile": args.profile, "--model": args.model}
    for job in jobs:
        inputs[f"{job.source}: clip"] = job.clip
        inputs[f"{job.source}: rig"] = job.rig
    outputs: dict[str, str] = {}
    if os.path.isdir(args.output):     # a folder still to make holds nothing an output could replace
        outputs[f"-o {REPORT_NAME}"] = os.path.join(args.output, REPORT_NAME)
        for job in jobs:
            for kind, path in output_paths(args.output, job.name, csv=args.csv, preview=args.preview).items():
                outputs[f"{job.source}: output {kind}"] = str(path)
    check_paths(inputs, outputs)
