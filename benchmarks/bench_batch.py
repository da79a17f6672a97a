"""Benchmark of `facepuppet batch`: many clips on 1 and 2 local workers and on Ray, beside single `animate` runs.

Setup: a rig is made from one shared clip (``--auto`` key expressions against an ARKit-named character built
here from the ICT FaceKit model in ../shared/assets, never written into the repository); the batch is
``--copies`` copies (default 12) of the shared clips, cycled (performer_a, performer_b_exaggerated, performer_c,
performer_a, ...). The colour tracker runs with its built-in profile (``--profile builtin``, what ``animate``
uses without ``--profile``), or with a profile trained on the first clip (MediaPipe labels) and used for every
clip (``--profile trained``: one performer's profile on other performers, which makes the tracker search for
the face again on most frames of performer_c: a heavier and more threaded load than a take of one's own).

Timed in the same run, each as its own ``python -m facepuppet`` process (start-up included, as a user runs it):

- the sum of single ``facepuppet animate`` runs, one per clip (the reference);
- ``facepuppet batch --workers 1``, ``--workers 2`` (local engine) and ``--engine ray --workers 2`` (a local
  Ray runtime started by the command);
- ``facepuppet batch --workers 1`` pinned to one core (Linux; its worker's thread pools then get one thread):
  the reference of the scaling over cores, since the unpinned single worker keeps more than one core busy while
  OpenCV's loops and FFmpeg's decoder run on their other threads.

Printed: seconds, frames per second, the CPU seconds of the run's processes (user + system of every process the
run waited for: the batch and its local workers; Ray's workers belong to its runtime and are not counted) and
the cores they kept busy on average (CPU / wall), the speed-up over ``--workers 1`` and over the single runs,
Ray's overhead against the local engine with the same workers, 2 workers on 2 cores against 1 worker on 1 core,
and the 1-minute load average as each run started (other work on the machine slows the wall times, hardly the
CPU seconds). Bars: 2 workers >= 1.7x one worker (2-core machine); Ray's overhead <= 15 % of the local engine's
time. Every batch's outputs are checked byte for byte against the single runs'. Last, the machine's own
scaling: a CPU-bound loop in 2 processes at once against 1 (2 CPUs of a virtual machine may share one core).

Run: ``python benchmarks/bench_batch.py [--copies 12] [--profile builtin|trained] [--assets PATH] [--no-ray]
[--no-one-core]``
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CLIPS = ("performer_a", "performer_b_exaggerated", "performer_c")
ONE_CORE = "batch --workers 1, pinned to 1 core"


def make_rig(assets: Path, clip: Path, model: str, folder: Path, *, trained: bool) -> tuple[Path | None, Path]:
    """A rig (ICT FaceKit character, --auto key expressions) from ``clip``, and the colour-tracker profile it
    was made with (trained on ``clip`` when ``trained``, else None: the built-in one)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_animate import ict_character
    from facepuppet.pipeline.examples import ExamplesConfig, from_auto
    from facepuppet.pipeline.profile import train_profile_on_media
    from facepuppet.pipeline.rig import fit_rig, save_rig
    from facepuppet.pipeline.tracking import TrackerOptions

    profile, labels = None, None
    if trained:
        profile = folder / "profile.npz"
        labels = train_profile_on_media(clip, profile, model=model, progress=False)
    character = ict_character(assets)
    options = TrackerOptions(backend="color", profile=None if profile is None else str(profile), model=model,
                             progress=False)
    performer = from_auto(clip, character.names, config=ExamplesConfig(tracker=options), scores_track=labels)
    rig, _ = fit_rig(performer, character)
    save_rig(folder / "rig.npz", rig)
    return profile, folder / "rig.npz"


def children_cpu() -> float:
    """User + system CPU seconds of the processes this one has waited for, so far."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def facepuppet(*args: str, cpus: set[int] | None = None) -> tuple[float, float]:
    """Run ``python -m facepuppet ARGS`` (on the CPUs ``cpus`` only, if given); seconds of wall time and CPU
    seconds of the processes it waited for. Exit codes other than 0 stop the benchmark."""
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src") + os.pathsep + os.environ.get("PYTHONPATH", "")}
    pin = None if cpus is None else (lambda: os.sched_setaffinity(0, cpus))
    c0, t0 = children_cpu(), time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "facepuppet", *args], env=env, capture_output=True, text=True,
                          preexec_fn=pin)          # sets only the CPU affinity of the child
    dt, cpu = time.perf_counter() - t0, children_cpu() - c0
    if done.returncode != 0:
        raise SystemExit(f"facepuppet {' '.join(args)} failed ({done.returncode}):\n{done.stderr[-2000:]}")
    return dt, cpu


#: Iterations of the CPU-bound loop of :func:`machine_scaling` (about 2 s of one core).
SPIN = 30_000_000


def machine_scaling() -> float:
    """How much faster 2 processes spinning a CPU-bound loop finish 2 loops than 1 process does (2.0: two whole
    cores; less where the 2 CPUs share a physical core or the machine is busy)."""
    loop = [sys.executable, "-c", f"x = 0\nfor i in range({SPIN}): x += i & 7"]
    t0 = time.perf_counter()
    subprocess.run(loop, check=True)
    one = time.perf_counter() - t0
    t0 = time.perf_counter()
    procs = [subprocess.Popen(loop) for _ in range(2)]
    for p in procs:
        p.wait()
    return 2 * one / (time.perf_counter() - t0)


def frame_count(path: Path) -> int:
    import cv2

    cap = cv2.VideoCapture(str(path))
    n = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
    cap.release()
    return n


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--assets", default=os.environ.get("FACEPUPPET_ASSETS", ROOT.parent / "shared" / "assets"))
    ap.add_argument("--copies", type=int, default=12, help="clips in the batch (copies of the shared clips)")
    ap.add_argument("--model", default=None, help="face_landmarker.task (default: assets/models)")
    ap.add_argument("--no-ray", action="store_true", help="leave the Ray engine out")
    ap.add_argument("--profile", choices=("builtin", "trained"), default="builtin",
                    help="the colour tracker's profile: built-in, or trained on the first clip (module notes)")
    ap.add_argument("--no-one-core", action="store_true", help="leave out the run of 1 worker pinned to 1 core")
    args = ap.parse_args(argv)
    assets = Path(args.assets)
    model = args.model or os.environ.get("FACEPUPPET_FACE_LANDMARKER") or str(assets / "models" /
                                                                                "face_landmarker.task")
    tmp = Path(tempfile.mkdtemp(prefix="bench-batch-"))
    t0 = time.perf_counter()
    profile, rig = make_rig(assets, assets / "video" / f"{CLIPS[0]}.mp4", model, tmp,
                            trained=args.profile == "trained")
    print(f"setup (rig from {CLIPS[0]}, profile {args.profile}): {time.perf_counter() - t0:.0f} s")

    clips_dir = tmp / "clips"
    clips_dir.mkdir()
    clips = []
    for k in range(args.copies):
        src = assets / "video" / f"{CLIPS[k % len(CLIPS)]}.mp4"
        dst = clips_dir / f"{k:02d}-{src.stem}.mp4"
        shutil.copyfile(src, dst)
        clips.append(dst)
    frames = sum(frame_count(c) for c in clips)
    common = ["--rig", str(rig), *(["--profile", str(profile)] if profile else []), "--model", model,
              "--no-progress"]

    single_dir = tmp / "single"
    single_dir.mkdir()
    load = {"sum of single animate runs": os.getloadavg()[0]}
    singles = [facepuppet("animate", str(c), "-o", str(single_dir / f"{c.stem}.glb"),
                          "--csv", str(single_dir / f"{c.stem}.csv"), *common) for c in clips]
    t_single, cpu_single = sum(t for t, _ in singles), sum(c for _, c in singles)
    runs = [("batch --workers 1", ["--workers", "1"], None), ("batch --workers 2", ["--workers", "2"], None)]
    if not args.no_ray and importlib.util.find_spec("ray") is not None:
        runs.append(("batch --engine ray --workers 2", ["--engine", "ray", "--workers", "2"], None))
    if not args.no_one_core and hasattr(os, "sched_setaffinity"):
        runs.append((ONE_CORE, ["--workers", "1"], {min(os.sched_getaffinity(0))}))
    times, cpus = {}, {}
    for label, extra, pinned in runs:
        out = tmp / label.replace(" ", "_").replace("-", "").replace(",", "")
        load[label] = os.getloadavg()[0]
        times[label], cpus[label] = facepuppet("batch", *map(str, clips), "-o", str(out), "--csv", *common, *extra,
                                               cpus=pinned)
        for c in clips:
            for ext in ("glb", "csv"):
                if (out / f"{c.stem}.{ext}").read_bytes() != (single_dir / f"{c.stem}.{ext}").read_bytes():
                    raise SystemExit(f"{label}: {c.stem}.{ext} differs from animate's")

    print(f"\n{args.copies} clips, {frames} frames (colour tracker, GLB + CSV); each line one process "
          f"(the single runs: one each)")
    print(f"{'run':<38}{'seconds':>9}{'frames/s':>10}{'CPU s':>8}{'CPU ms/frame':>14}{'cores':>7}"
          f"{'vs 1 worker':>13}{'vs single':>11}{'load':>7}")
    one = times["batch --workers 1"]
    rows = [("sum of single animate runs", t_single, cpu_single), *((k, times[k], cpus[k]) for k in times)]
    for label, dt, cpu in rows:
        cpu_text = (f"{'n/a':>8}{'n/a':>14}{'n/a':>7}" if "ray" in label else
                    f"{cpu:>8.1f}{1000 * cpu / frames:>14.1f}{cpu / dt:>7.2f}")
        print(f"{label:<38}{dt:>9.1f}{frames / dt:>10.0f}{cpu_text}{one / dt:>12.2f}x{t_single / dt:>10.2f}x"
              f"{load[label]:>7.2f}")
    print("CPU s: user + system of the run's processes (Ray's workers are its runtime's: n/a); cores: CPU s / "
          "seconds; load: the 1-minute load average as the run started")
    print("outputs of every batch: byte for byte those of the single animate runs")
    two = times["batch --workers 2"]
    print(f"bar: 2 workers >= 1.7x 1 worker: {one / two:.2f}x")
    if "batch --engine ray --workers 2" in times:
        ray = times["batch --engine ray --workers 2"]
        print(f"bar: Ray's overhead <= 15 % of the local engine's time: {100 * (ray - two) / two:+.1f} %")
    if ONE_CORE in times:
        print(f"scaling: 2 workers on 2 cores vs 1 worker on 1 core: {times[ONE_CORE] / two:.2f}x; the unpinned "
              f"1 worker kept {cpus['batch --workers 1'] / one:.2f} cores busy (2 workers can be at most "
              f"{2 * one / cpus['batch --workers 1']:.2f}x as fast as it)")
    print(f"the machine: 2 processes of a CPU-bound loop go {machine_scaling():.2f}x as fast as 1 (the ceiling "
          f"of any 2-worker speed-up here)")
    shutil.rmtree(tmp, ignore_errors=True)
    print(f"load: {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f} "
          f"(1, 5, 15 min) on {os.cpu_count()} cores")
    return 0


if __name__ == "__main__":
    sys.exit(main())
