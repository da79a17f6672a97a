"""Benchmark of `facepuppet batch`: many clips on 1 and 2 local workers and on Ray, beside single `animate` runs.

Setup: a rig is made from one shared clip (``--auto`` key expressions against an ARKit-named character built
here from the ICT FaceKit model in ../shared/assets, never written into the repository); the batch is
``--copies`` copies (default 12) of the shared clips, cycled (performer_a, performer_b_exaggerated, performer_c,
performer_a, ...). The colour tracker runs with its built-in profile (``--profile builtin``, what ``animate``
uses without ``--profile``), or with a profile trained on the first clip (MediaPipe labels) and used for every
clip (``--profile trained``: one performer's profile on other performers, which makes the tracker search for
the face again on most frames of performer_c: a heavier and more threaded load than a take of one's own).

Timed in the same run, each as its own ``python -m facepuppet`` process (start-up included, as a user runs it:
the local engine's worker processes and imports as much as Ray's):

- the sum of single ``facepuppet animate`` runs, one per clip, once before the rounds (the reference, and the
  outputs every batch must equal byte for byte);
- ``facepuppet batch --workers 1``, ``--workers 2`` (local engine);
- ``facepuppet batch --engine ray --address 127.0.0.1:PORT`` on a Ray cluster of 2 CPUs started for that run
  (``ray start --head --block`` on loopback, then one driver that connects and leaves, untimed: the first
  connection to a new cluster waits for its start-up; stopped after the run, so that no idle cluster runs beside
  the other configurations): what a cluster's user pays per batch; one such configuration per
  ``--cluster-niceness`` value, the niceness of the cluster's workers (default 15, Ray's own, which puts the
  actors behind every other process of a shared machine, and 0, a local worker's);
- ``facepuppet batch --engine ray --workers 2`` with its own Ray runtime (started and stopped by the command:
  the cold case, Ray's start-up and shutdown included; ``--no-cold`` leaves it out);
- ``facepuppet batch --workers 1`` pinned to one core (Linux; ``--no-one-core`` leaves it out): the check that
  one worker is one core's worth of work.

The machine's speed moves between runs (other work, the host), so the configurations run interleaved in
``--repeat`` rounds, the order rotated by one each round, and the bars are judged on each round's ratios (runs
minutes apart): the 2-worker speed-up over 1 worker, Ray's overhead over the local engine with 2 workers (on
the existing cluster: the bar's; with its own runtime), the pinned worker against the unpinned one, 1 worker
against the single runs. Printed: each run (seconds, frames per second, CPU seconds of the run's processes,
CPU ms a frame, cores kept busy, the 1-minute load average as it started), each round's ratios, the median of
each ratio over the rounds with its spread, and each configuration's median run. Ray runs print the engine's
timeline (``facepuppet -v batch``: the actors' niceness and start-up steps, their clips and idle gaps). CPU
seconds: user + system of every process the run waited for (the batch and its local workers); for Ray, of
every process of the batch's session, its own Ray runtime included, and of the cluster's over the run, looked
at 5 times a second. Bars: 2 workers >= 1.7x one worker (2-core machine); Ray's overhead <= 15 % of the local
engine's time. Last, the machine's own scaling: a CPU-bound loop in 2 processes at once against 1 (2 CPUs of
a virtual machine may share one core).

``--stages`` prints, before the runs, where one worker's CPU goes over the batch's clips: each stage's CPU seconds
on the worker's own thread (``time.thread_time`` around decoding, tracking, its first frame per clip, mapping,
the outputs) and the process's settings that size and place its threads (CPUs, niceness, the pools' variables,
OpenCV's and numba's threads, the BLAS pools), with 1 thread (a worker's) and with the machine's cores in its
native pools (``animate``'s default), each in a process of its own, with 1 thread inside a Ray actor of
1 CPU (a runtime of its own): the same clips' work in a local worker and in an actor, and in two 1-thread
processes at once with every other clip each (what two workers side by side spend on each stage). With
``--repeat 0`` only these.

Run: ``python benchmarks/bench_batch.py [--copies 12] [--repeat 3] [--profile builtin|trained] [--assets PATH]
[--no-ray] [--no-cold] [--no-one-core] [--cluster-niceness N] [--rig RIG.npz] [--stages]``
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import os
import resource
import secrets
import shutil
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CLIPS = ("performer_a", "performer_b_exaggerated", "performer_c")
ONE_WORKER, TWO_WORKERS = "batch --workers 1", "batch --workers 2"
ONE_CORE = "batch --workers 1, pinned to 1 core"
RAY_COLD = "Ray, own runtime (cold), 2 CPUs"
RAY_CLUSTER = "Ray, existing cluster of 2 CPUs"

#: Niceness Ray gives its worker processes unless told (``RAY_worker_niceness``).
RAY_NICENESS = 15

#: Seconds to wait for the benchmark's Ray cluster to start, and to stop.
CLUSTER_START_S, CLUSTER_STOP_S = 180, 60

#: Seconds between two looks at the CPU of a Ray run's processes, and the looks that also scan for new ones.
SAMPLE_S = 0.2
SCAN_EVERY = 5

#: Seconds a run's leftover processes (its own Ray runtime's, a stopped cluster's) get to end before the next run.
SESSION_GONE_S = 30


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


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class SessionCPU:
    """CPU seconds (user + system) that the processes of the sessions ``sids`` spend while it runs, from Linux's
    /proc, looked at every :data:`SAMPLE_S` seconds (a process is counted up to its last look: Ray's workers end
    and are reaped by their own parents, so the CPU of waited-for children cannot count them). Each look reads
    the processes found so far; every :data:`SCAN_EVERY`-th look also scans /proc for new ones (a full scan
    costs a few milliseconds of the CPU the runs share)."""

    def __init__(self, sids) -> None:
        self.sids = set(sids)
        self.first: dict[int, float] = {}
        self.last: dict[int, float] = {}
        self.looks = 0
        self.done = threading.Event()
        self.tick = os.sysconf("SC_CLK_TCK")
        self.look()
        self.first = dict(self.last)
        self.thread = threading.Thread(target=self.loop, daemon=True)
        self.thread.start()

    def look(self) -> None:
        scan = self.looks % SCAN_EVERY == 0
        self.looks += 1
        stats = Path("/proc").glob("[0-9]*/stat") if scan else (Path(f"/proc/{p}/stat") for p in list(self.last))
        for stat in stats:
            try:
                fields = stat.read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[3]) in self.sids:
                self.last[int(stat.parent.name)] = (int(fields[11]) + int(fields[12])) / self.tick

    def loop(self) -> None:
        while not self.done.wait(SAMPLE_S):
            self.look()

    def stop(self) -> float:
        self.done.set()
        self.thread.join()
        self.looks = 0                          # the last look scans: processes started since are counted
        self.look()
        return sum(v - self.first.get(p, 0.0) for p, v in self.last.items())


class Cluster:
    """A Ray cluster of ``cpus`` CPUs on loopback: ``ray start --head --block`` in a session of its own, so that
    stopping it ends only its own processes (SIGTERM to the command, which stops what it started; SIGKILL to its
    process group if it has not ended after CLUSTER_STOP_S)."""

    def __init__(self, cpus: int, env: dict) -> None:
        ray_cli = Path(sys.executable).with_name("ray")
        self.port = free_port()
        cmd = [str(ray_cli) if ray_cli.exists() else "ray", "start", "--head", "--block", "--num-cpus", str(cpus),
               "--node-ip-address", "127.0.0.1", "--port", str(self.port), "--include-dashboard=false",
               "--disable-usage-stats", "--dashboard-agent-listen-port", str(free_port())]
        #: What a driver needs in its environment: Ray's token authentication, with a token made for this cluster
        #: (the cluster is started with the same; a Ray without token authentication ignores both variables).
        self.client_env = {"RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": secrets.token_hex(16)}
        self.proc = subprocess.Popen(cmd, env={**env, **self.client_env, "RAY_USAGE_STATS_ENABLED": "0"},
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                     start_new_session=True)
        started = threading.Event()
        self.lines: list[str] = []

        def read() -> None:
            for line in self.proc.stdout:
                self.lines.append(line)
                if "Ray runtime started" in line:
                    started.set()

        threading.Thread(target=read, daemon=True).start()
        if not started.wait(CLUSTER_START_S) or self.proc.poll() is not None:
            self.stop()
            raise SystemExit("ray start did not start a cluster:\n" + "".join(self.lines[-30:]))
        self.address = f"127.0.0.1:{self.port}"
        self.env = {**env, **self.client_env}

    def first_driver(self) -> float:
        """Seconds a first driver (``ray.init`` then ``ray.shutdown``, its own process) takes: the first
        connection to a new cluster also waits for the cluster's own start-up work, which a cluster that has
        run jobs before has done."""
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-c", "import sys, ray; ray.init(address=sys.argv[1], "
                        "logging_level='WARNING'); ray.shutdown()", self.address], env=self.env, check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        return time.perf_counter() - t0

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(CLUSTER_STOP_S)
            except subprocess.TimeoutExpired:
                pass
        try:
            os.killpg(self.proc.pid, signal.SIGKILL)    # whatever of its session lives on
        except (ProcessLookupError, PermissionError):
            pass
        self.proc.wait()
        wait_session_gone(self.proc.pid, "the Ray cluster")


def session_pids(sid: int) -> list[int]:
    """Process ids of the live processes of session ``sid`` (Linux's /proc; zombies left out)."""
    pids = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[3]) == sid and fields[0] != "Z":
            pids.append(int(stat.parent.name))
    return pids


def wait_session_gone(sid: int, what: str) -> float:
    """Wait until session ``sid`` has no live process (a Ray runtime's processes end after its command), at most
    :data:`SESSION_GONE_S` seconds, then SIGKILL what is left: the next run starts on a machine without them.
    Returns the seconds waited."""
    t0 = time.perf_counter()
    while session_pids(sid) and time.perf_counter() - t0 < SESSION_GONE_S:
        time.sleep(SAMPLE_S)
    left = session_pids(sid)
    if left:
        print(f"  {what}: {len(left)} process(es) still there after {SESSION_GONE_S} s, killed")
        try:
            os.killpg(sid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
    return time.perf_counter() - t0


def children_cpu() -> float:
    """User + system CPU seconds of the processes this one has waited for, so far."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


ENV = {**os.environ, "PYTHONPATH": str(ROOT / "src") + os.pathsep + os.environ.get("PYTHONPATH", "")}


def facepuppet(*args: str, cpus: set[int] | None = None, cluster: Cluster | None = None,
               ray: bool = False, timeline: bool = False) -> tuple[float, float]:
    """Run ``python -m facepuppet ARGS`` in a session of its own (on the CPUs ``cpus`` only, if given); seconds of
    wall time and CPU seconds of the processes it waited for, or with ``ray`` of every process of its session (its
    own Ray runtime) and of ``cluster``'s (:class:`SessionCPU`). Exit codes other than 0 stop the benchmark."""
    env = ENV if cluster is None else {**ENV, **cluster.client_env}
    pin = None if cpus is None else (lambda: os.sched_setaffinity(0, cpus))
    c0, t0 = children_cpu(), time.perf_counter()
    verbose = ["-v"] if timeline else []
    proc = subprocess.Popen([sys.executable, "-m", "facepuppet", *verbose, *args], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, preexec_fn=pin,  # sets only the child's CPU affinity
                            start_new_session=True)
    sampler = SessionCPU([proc.pid, *([cluster.proc.pid] if cluster else [])]) if ray else None
    try:
        _, stderr = proc.communicate()
    except BaseException:
        os.killpg(proc.pid, signal.SIGTERM)     # its own session: a stopped benchmark leaves no batch behind
        proc.wait()
        raise
    dt, cpu = time.perf_counter() - t0, children_cpu() - c0
    if sampler is not None:
        cpu = sampler.stop()
    if ray and cluster is None:                 # its own runtime's processes end after it: not during the next run
        gone = wait_session_gone(proc.pid, "the batch's own Ray runtime")
        if timeline:
            print(f"  its own Ray runtime's last processes ended {gone:.1f} s after the command (not timed)")
    if timeline:                                # the engine's own timeline (facepuppet.batch.timeline)
        for line in stderr.splitlines():
            if "timeline:" in line:
                print("  " + line.split("timeline:", 1)[1].strip())
    done = subprocess.CompletedProcess(proc.args, proc.returncode, "", stderr)
    if done.returncode != 0:
        raise SystemExit(f"facepuppet {' '.join(args)} failed ({done.returncode}):\n{done.stderr[-2000:]}")
    return dt, cpu


#: Iterations of the CPU-bound loop of :func:`machine_scaling` (about 2 s of one core).
SPIN = 30_000_000


def autogroup() -> bool:
    """Whether Linux shares the CPU between sessions first (``sched_autogroup_enabled``), then between the
    processes of each session."""
    try:
        return Path("/proc/sys/kernel/sched_autogroup_enabled").read_text().strip() == "1"
    except OSError:
        return False


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


def stages(threads: int, rig: str, clips: list[str], where: str = "in a process of its own") -> None:
    """One worker's clips in this process with ``threads`` threads in its pools; print the process's settings
    that size its threads and each stage's CPU seconds on this thread (the wrappers below time the library's
    public methods, they change nothing)."""
    import collections

    clock = time.thread_time
    spent: dict[str, float] = collections.defaultdict(float)

    def timed(name, f):
        def wrapper(*a, **k):
            t = clock()
            try:
                return f(*a, **k)
            finally:
                spent[name] += clock() - t
        return wrapper

    t0 = clock()
    import cv2

    import facepuppet.capture.color.tracker as color
    import facepuppet.pipeline.outputs as outputs
    import facepuppet.pipeline.rig as rigs
    import facepuppet.pipeline.stream as stream
    from facepuppet.batch.jobs import file_sha256
    from facepuppet.batch.worker import ClipTask, run_clip, share_cores
    from facepuppet.pipeline.animate import AnimateConfig

    spent["imports"] = clock() - t0
    share_cores(threads)
    capture = cv2.VideoCapture

    class Capture:                              # cv2.VideoCapture with its read timed
        def __init__(self, *a):
            self.cap = capture(*a)

        def read(self):
            t = clock()
            try:
                return self.cap.read()
            finally:
                spent["decode (VideoCapture.read)"] += clock() - t

        def __getattr__(self, name):
            return getattr(self.cap, name)

    cv2.VideoCapture = Capture
    track = color.ColorTracker.track
    first = {"next": False}

    def track_timed(self, rgb, ms):
        t = clock()
        try:
            return track(self, rgb, ms)
        finally:
            dt = clock() - t
            spent["track"] += dt
            if first["next"]:
                spent["  of which each clip's first frame"] += dt
                first["next"] = False

    color.ColorTracker.track = track_timed
    stream.FrameMapper.step = timed("map, smooth, gain", stream.FrameMapper.step)
    for cls, name in ((outputs.GlbOutput, "GLB"), (outputs.CsvOutput, "CSV")):
        cls.write = timed(f"{name} per frame", cls.write)
        cls.finish = timed(f"{name} at the end", cls.finish)
    rigs.load_rig = timed("rig load", rigs.load_rig)
    out = Path(tempfile.mkdtemp(prefix="bench-batch-stages-"))
    sha, frames = file_sha256(rig), 0
    c0, t0, w0 = time.process_time(), clock(), time.perf_counter()
    try:
        for i, clip in enumerate(clips):
            first["next"] = True
            task = ClipTask(index=i, clip=clip, rig=rig, rig_sha256=sha, config=AnimateConfig(),
                            outputs={"glb": str(out / f"{i}.glb"), "csv": str(out / f"{i}.csv")})
            t = clock()
            result = run_clip(task)
            spent["clips, all stages"] += clock() - t
            if i == 0:
                spent["  of which the first clip"] = clock() - t
            frames += result.frames
    finally:
        shutil.rmtree(out, ignore_errors=True)
    wall, main, cpu = time.perf_counter() - w0, clock() - t0, time.process_time() - c0
    print(f"\none worker's stages {where}, {threads} thread(s) in its pools, {len(clips)} clips, {frames} frames: "
          f"{wall:.1f} s, process {cpu:.1f} CPU s ({cpu / wall:.2f} cores), its own thread {main:.1f} CPU s, "
          f"its other threads {cpu - main:.1f} CPU s (load {os.getloadavg()[0]:.2f})")
    print(f"  settings: {settings()}")
    named = sum(v for k, v in spent.items() if not k.startswith(" ") and k not in ("imports", "clips, all stages"))
    spent["the rest (frame loop, colour conversion, progress)"] = spent["clips, all stages"] - named
    for name, v in spent.items():
        print(f"  {name:<52}{v:>7.2f} CPU s{1000 * v / max(frames, 1):>8.2f} ms/frame")


def settings() -> str:
    """What sizes this process's threads and places them: its CPUs, niceness, threads now, the pools' variables,
    OpenCV's threads, numba's threading layer and threads, and the BLAS pools (threadpoolctl)."""
    import cv2
    import numba

    names = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "OPENCV_FFMPEG_THREADS")
    text = [f"CPUs {sorted(os.sched_getaffinity(0)) if hasattr(os, 'sched_getaffinity') else '?'}",
            f"nice {os.nice(0)}", f"threads {len(list(Path('/proc/self/task').glob('*')))}",
            *(f"{n}={os.environ.get(n, '-')}" for n in names), f"cv2 threads {cv2.getNumThreads()}",
            f"numba threads {numba.config.NUMBA_NUM_THREADS}, layer {numba.config.THREADING_LAYER}"]
    try:
        from threadpoolctl import threadpool_info

        text.append("pools " + ", ".join(f"{i['internal_api']} {i['num_threads']}" for i in threadpool_info()))
    except ImportError:
        pass
    return "; ".join(text)


def stage_runs(rig: Path, clips: list[Path], ray: bool) -> None:
    """:func:`stages` over the batch's clips in a process of its own with 1 thread in its pools (a local
    worker's), with the machine's cores (``animate``'s), inside a Ray actor of 1 CPU (its own runtime), and in two
    1-thread processes at once, each with every other clip (two workers' share of the work, side by side: what
    each stage costs when two workers run together)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else 1
    for threads in sorted({1, cores}):
        subprocess.run([sys.executable, __file__, "--stages-of", str(threads), str(rig), *map(str, clips)],
                       env=ENV, check=True)
    if ray:
        subprocess.run([sys.executable, __file__, "--stages-of", "ray", str(rig), *map(str, clips)],
                       env=ENV, check=True)
    pair = [subprocess.Popen([sys.executable, __file__, "--stages-of", "1", str(rig), *map(str, clips[k::2])],
                             env=ENV, stdout=subprocess.PIPE, text=True) for k in range(2)]
    for k, proc in enumerate(pair):
        out, _ = proc.communicate()
        print(f"\n(two at once, {k + 1} of 2, clips {k + 1}, {k + 3}, ...)" + out.rstrip("\n"))
        if proc.returncode:
            raise SystemExit(f"--stages-of failed ({proc.returncode})")


def stages_in_ray(rig: str, clips: list[str]) -> None:
    """:func:`stages` with 1 thread inside a Ray actor of 1 CPU, on a Ray runtime of this process's own."""
    import ray

    ray.init(address="local", num_cpus=2, include_dashboard=False, logging_level="WARNING")
    try:
        @ray.remote(num_cpus=1)
        class Stages:
            def run(self, rig, clips):
                stages(1, rig, clips, where="in a Ray actor")
                sys.stdout.flush()

        actor = Stages.remote()
        ray.get(actor.run.remote(rig, clips))
        time.sleep(1.0)                         # the actor's printed lines reach this process's stdout
    finally:
        ray.shutdown()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--assets", default=os.environ.get("FACEPUPPET_ASSETS", ROOT.parent / "shared" / "assets"))
    ap.add_argument("--copies", type=int, default=12, help="clips in the batch (copies of the shared clips)")
    ap.add_argument("--model", default=None, help="face_landmarker.task (default: assets/models)")
    ap.add_argument("--no-ray", action="store_true", help="leave the Ray engine out")
    ap.add_argument("--profile", choices=("builtin", "trained"), default="builtin",
                    help="the colour tracker's profile: built-in, or trained on the first clip (module notes)")
    ap.add_argument("--no-one-core", action="store_true", help="leave out the run of 1 worker pinned to 1 core")
    ap.add_argument("--rig", help="a rig made before (with the built-in profile) instead of making one")
    ap.add_argument("--repeat", type=int, default=3, help="rounds of the configurations, interleaved (module "
                    "notes): the bars' figures are the rounds' median ratios")
    ap.add_argument("--no-cold", action="store_true", help="leave out Ray with its own runtime (cold)")
    ap.add_argument("--cluster-niceness", type=int, nargs="+", default=[RAY_NICENESS, 0],
                    help="niceness of the Ray cluster's workers (RAY_worker_niceness for ray start), one cluster "
                    f"configuration each (default {RAY_NICENESS}, Ray's own, and 0, a local worker's)")
    ap.add_argument("--stages", action="store_true", help="first, where one worker's CPU goes (module notes)")
    ap.add_argument("--stages-of", nargs="+", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    sys.stdout.reconfigure(line_buffering=True)  # each run's line as it ends, also into a file
    if args.stages_of:
        if args.stages_of[0] == "ray":
            stages_in_ray(args.stages_of[1], args.stages_of[2:])
        else:
            stages(int(args.stages_of[0]), args.stages_of[1], args.stages_of[2:])
        return 0
    assets = Path(args.assets)
    model = args.model or os.environ.get("FACEPUPPET_FACE_LANDMARKER") or str(assets / "models" /
                                                                                "face_landmarker.task")
    tmp = Path(tempfile.mkdtemp(prefix="bench-batch-"))
    try:
        return bench(args, assets, model, tmp)
    finally:                                    # a failed or stopped run leaves no folder behind
        shutil.rmtree(tmp, ignore_errors=True)


def bench(args, assets: Path, model: str, tmp: Path) -> int:
    """The runs of :func:`main` in the folder ``tmp``: the single runs, then the rounds; prints each run, each
    round's ratios and their medians."""
    t_start = time.perf_counter()
    if args.rig:
        profile, rig = None, Path(args.rig)
    else:
        profile, rig = make_rig(assets, assets / "video" / f"{CLIPS[0]}.mp4", model, tmp,
                                trained=args.profile == "trained")
    print(f"setup (rig from {CLIPS[0]}, profile {args.profile}): {time.perf_counter() - t_start:.0f} s")

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
    ray = not args.no_ray and importlib.util.find_spec("ray") is not None
    if args.stages:
        stage_runs(rig, clips, ray)

    if args.repeat < 1:                         # nothing to compare the single runs with
        return 0
    single_dir = tmp / "single"
    single_dir.mkdir()
    t0, load0 = time.perf_counter(), os.getloadavg()[0]
    singles = [facepuppet("animate", str(c), "-o", str(single_dir / f"{c.stem}.glb"),
                          "--csv", str(single_dir / f"{c.stem}.csv"), *common) for c in clips]
    t_single, cpu_single = sum(t for t, _ in singles), sum(c for _, c in singles)
    print(f"sum of {len(clips)} single animate runs: {t_single:.1f} s, {frames / t_single:.0f} frames/s, "
          f"{cpu_single:.1f} CPU s (load {load0:.2f} -> {os.getloadavg()[0]:.2f}; "
          f"{time.perf_counter() - t0:.0f} s)")

    configs = [(ONE_WORKER, ["--workers", "1"], "local"), (TWO_WORKERS, ["--workers", "2"], "local")]
    if ray:
        for nice in args.cluster_niceness:
            configs.append((RAY_CLUSTER if nice == RAY_NICENESS else f"{RAY_CLUSTER}, workers nice {nice}",
                            ["--engine", "ray"], ("cluster", nice)))
        if not args.no_cold:
            configs.append((RAY_COLD, ["--engine", "ray", "--workers", "2"], "own"))
    if not args.no_one_core and hasattr(os, "sched_setaffinity"):
        configs.append((ONE_CORE, ["--workers", "1"], {min(os.sched_getaffinity(0))}))
    cluster = None
    rounds: list[dict[str, Run]] = []
    try:
        for k in range(args.repeat):
            shift = k % len(configs)
            order = configs[shift:] + configs[:shift]
            print(f"\nround {k + 1} of {args.repeat}: {', '.join(label for label, _, _ in order)}")
            done: dict[str, Run] = {}
            for label, extra, where in order:
                out = tmp / f"round{k + 1}" / "".join(ch if ch.isalnum() else "_" for ch in label)
                on_cluster = isinstance(where, tuple)
                if on_cluster:                  # a new cluster for its run alone: no idle cluster beside the others
                    t0 = time.perf_counter()
                    cluster = Cluster(2, {**ENV, "RAY_worker_niceness": str(where[1])})
                    started = time.perf_counter() - t0
                    print(f"  (Ray cluster at {cluster.address}: started in {started:.1f} s, a first driver "
                          f"connected and left in {cluster.first_driver():.1f} s; neither timed)")
                    time.sleep(1.0)
                    extra = [*extra, "--address", cluster.address]
                load = os.getloadavg()[0]
                dt, cpu = facepuppet("batch", *map(str, clips), "-o", str(out), "--csv", *common, *extra,
                                     cpus=where if isinstance(where, set) else None,
                                     cluster=cluster, ray=on_cluster or where == "own",
                                     timeline=on_cluster or where == "own")
                if cluster is not None:
                    cluster.stop()
                    cluster = None
                same_bytes(label, out, single_dir, clips)
                shutil.rmtree(out, ignore_errors=True)
                done[label] = Run(dt, cpu, load)
                print(f"  {label:<50}{dt:>7.1f} s{frames / dt:>6.0f} frames/s{cpu:>7.1f} CPU s"
                      f"{1000 * cpu / frames:>6.1f} CPU ms/frame{cpu / dt:>6.2f} cores  load {load:.2f}", flush=True)
            rounds.append(done)
            print("  round " + str(k + 1) + ": " + "; ".join(f"{name} {value}" for name, value, _ in
                                                               ratios(done, t_single)), flush=True)
    finally:
        if cluster is not None:
            cluster.stop()
    summary(rounds, ratios, t_single, cpu_single, frames, args)
    print(f"the machine: 2 processes of a CPU-bound loop go {machine_scaling():.2f}x as fast as 1 (the ceiling "
          f"of any 2-worker speed-up here)")
    if autogroup():
        print("Linux shares the CPU between sessions here (autogroup): each run is a session of its own, its "
              "workers sharing its share, and a Ray cluster's actors are in the cluster's session, beside the "
              "driver's: while other sessions work, the configurations' wall times do not compare (their CPU "
              "seconds do); the bars need a quiet machine")
    print(f"load: {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f} "
          f"(1, 5, 15 min) on {os.cpu_count()} cores; the whole benchmark {time.perf_counter() - t_start:.0f} s")
    return 0


@dataclasses.dataclass(frozen=True)
class Run:
    """One timed run: wall seconds, CPU seconds, the 1-minute load average as it started."""

    seconds: float
    cpu: float
    load: float


def same_bytes(label: str, out: Path, single_dir: Path, clips: list[Path]) -> None:
    """Stop the benchmark unless every output of the batch in ``out`` has the single ``animate`` run's bytes."""
    for c in clips:
        for ext in ("glb", "csv"):
            if (out / f"{c.stem}.{ext}").read_bytes() != (single_dir / f"{c.stem}.{ext}").read_bytes():
                raise SystemExit(f"{label}: {c.stem}.{ext} differs from animate's")


def ratios(done: dict[str, Run], t_single: float) -> list[tuple[str, str, float]]:
    """A round's ratios: (name, text, value) for the 2-worker speed-up over 1 worker, Ray's overheads over the
    local engine with 2 workers (on the existing cluster: the bar's; with its own runtime), the pinned worker's
    time over the unpinned one's, and 1 worker against the single runs (measured once, before the rounds); beside
    the time ratios, the CPU ones (``CPU``: the extra CPU seconds an engine spends, which other work on the machine
    hardly changes)."""
    out = []
    one, two = done[ONE_WORKER].seconds, done[TWO_WORKERS].seconds
    out.append(("2 workers / 1 worker", f"{one / two:.2f}x", one / two))
    cpu_two = done[TWO_WORKERS].cpu
    extra = 100 * (cpu_two - done[ONE_WORKER].cpu) / done[ONE_WORKER].cpu
    out.append(("CPU: 2 workers over 1 worker", f"{extra:+.1f} %", extra))
    for label in done:
        if label.startswith("Ray"):
            over = 100 * (done[label].seconds - two) / two
            out.append((f"{label}: overhead", f"{over:+.1f} %", over))
            extra = 100 * (done[label].cpu - cpu_two) / cpu_two
            out.append((f"CPU: {label} over 2 workers", f"{extra:+.1f} %", extra))
    if ONE_CORE in done:
        out.append(("1 worker pinned / unpinned", f"{done[ONE_CORE].seconds / one:.2f}x",
                    done[ONE_CORE].seconds / one))
    out.append(("1 worker / sum of single runs", f"{t_single / one:.2f}x", t_single / one))
    return out


def summary(rounds: list[dict[str, Run]], ratios_of, t_single: float, cpu_single: float, frames: int, args) -> None:
    """Each ratio's median over the rounds with its spread, and the runs' medians (the bars' figures)."""
    if not rounds:
        return
    print(f"\n{args.copies} clips, {frames} frames (colour tracker, GLB + CSV), {len(rounds)} round(s), the "
          f"configurations interleaved (their order rotated each round); each run one process, start-up included")
    w = max(38, *(len(label) + 1 for label in rounds[0]))
    print(f"{'median over the rounds':<{w}}{'seconds':>9}{'frames/s':>10}{'CPU s':>8}{'CPU ms/frame':>14}"
          f"{'cores':>7}{'load':>13}")
    print(f"{'sum of single animate runs (once)':<{w}}{t_single:>9.1f}{frames / t_single:>10.0f}{cpu_single:>8.1f}"
          f"{1000 * cpu_single / frames:>14.1f}{cpu_single / t_single:>7.2f}")
    for label in rounds[0]:
        runs = [r[label] for r in rounds if label in r]
        dt, cpu = statistics.median(r.seconds for r in runs), statistics.median(r.cpu for r in runs)
        loads = [r.load for r in runs]
        print(f"{label:<{w}}{dt:>9.1f}{frames / dt:>10.0f}{cpu:>8.1f}{1000 * cpu / frames:>14.1f}{cpu / dt:>7.2f}"
              f"{min(loads):>7.2f}-{max(loads):.2f}")
    print("CPU s: user + system of the run's processes (Ray: every process of its own runtime, or of the existing "
          f"cluster over the run, looked at every {SAMPLE_S} s); cores: CPU s / seconds; load: the 1-minute load "
          "average as the runs started")
    print("outputs of every batch: byte for byte those of the single animate runs")
    per = {}
    for r in rounds:
        for name, _, value in ratios_of(r, t_single):
            per.setdefault(name, []).append(value)
    bars = {"2 workers / 1 worker": "bar >= 1.7x", f"{RAY_CLUSTER}: overhead": "bar <= 15 %"}
    width = max(map(len, per)) + 1
    for name, values in per.items():
        unit = (lambda v: f"{v:+.1f} %") if "over" in name else (lambda v: f"{v:.2f}x")
        print(f"{name:<{width}} median {unit(statistics.median(values)):>9} (spread {unit(min(values))} to "
              f"{unit(max(values))}; rounds {', '.join(unit(v) for v in values)})"
              + (f"  {bars[name]}" if name in bars else ""))


if __name__ == "__main__":
    sys.exit(main())
