"""The work of one clip, the same in every engine: :func:`run_clip` calls :func:`~facepuppet.pipeline.animate.animate`.

A worker process keeps what does not change from clip to clip: each rig (:func:`cached_rig`, loaded once, keyed
by its content hash), the tracker (:func:`reused_tracker`: one per tracker options and profile contents, reset to
the start of a take before each clip, so that a clip's outputs are the same bytes as ``facepuppet animate``
writes), and with them the colour tracker's compiled kernels and the shared landmark backend. Its native thread
pools get one thread (:func:`share_cores`): a worker is one core's worth of work.

Progress goes out as ``(task index, frames)`` increments through a queue-like object with ``put`` (a
``multiprocessing`` queue locally, a Ray queue on a cluster), at most every :data:`PROGRESS_EVERY_S`.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import os
import signal
import sys
import threading
import time
from dataclasses import dataclass

from facepuppet._util.interrupt import Interrupted, handle_signals
from facepuppet.pipeline.animate import AnimateConfig

__all__ = ["ClipTask", "ClipResult", "run_clip", "run_guarded", "cached_rig", "rig_arrays", "rig_of_arrays",
           "reused_tracker", "share_cores", "WORKER_THREADS", "BLAS_THREAD_VARIABLES", "guard_worker", "one_line",
           "PROGRESS_EVERY_S", "PARENT_WATCH_S", "PARENT_GONE_REPEAT_S", "REUSED_BACKENDS", "warm_up"]

log = logging.getLogger(__name__)

#: Threads of each worker's native pools (:func:`share_cores`): a worker is one core's worth of work, as a Ray
#: actor reserving one CPU is counted.
WORKER_THREADS = 1

#: Environment variables that size the thread pools of BLAS and OpenMP libraries.
BLAS_THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")

#: Seconds between two progress messages of a worker.
PROGRESS_EVERY_S = 0.25

#: Seconds between two looks of a worker's watchdog at its parent process, and between two SIGTERMs it sends
#: once the parent is gone (long enough for a clip to stop and remove its temporary files after the first).
PARENT_WATCH_S = 1.0
PARENT_GONE_REPEAT_S = 10.0

#: prctl(2) option: the signal this process gets when its parent dies (linux/prctl.h).
_PR_SET_PDEATHSIG = 1

#: Tracker backends whose tracker a worker keeps across clips: their ``reset()`` sets up every state a new tracker
#: has. (The MediaPipe landmarker in video mode keeps tracking state and timestamps inside its graph: a reused one
#: would not see a clip as a new one does, so each clip gets a new tracker of that backend.)
REUSED_BACKENDS = frozenset({"color"})

#: Rigs loaded in this process: rig sha256 -> Rig.
_RIGS: dict[str, object] = {}

#: The tracker kept in this process: (backend, profile path, profile digest) -> tracker (the last one asked for).
_TRACKERS: dict[tuple, object] = {}


@dataclass(frozen=True, kw_only=True)
class ClipTask:
    """What a worker needs for one clip.

    Attributes
    ----------
    index : int
        The clip's place in the batch (progress messages and results carry it).
    clip, rig : str
        Paths every worker sees.
    rig_sha256 : str
        The rig's content hash (key of the worker's rig cache).
    outputs : dict of str -> str
        ``glb``, and ``csv`` / ``preview`` when asked.
    config : AnimateConfig
    """

    index: int
    clip: str
    rig: str
    rig_sha256: str
    outputs: dict
    config: AnimateConfig


@dataclass(frozen=True, kw_only=True)
class ClipResult:
    """How a clip went: ``ok``, frames, frames with a face, seconds, and the one-line error when not ok; when and
    where it ran: ``started`` (wall-clock ``time.time()`` as the worker began it, 0 if it never did) and
    ``worker`` (the worker's process id)."""

    index: int
    ok: bool
    frames: int = 0
    frames_with_face: int = 0
    seconds: float = 0.0
    error: str = ""
    started: float = 0.0
    worker: int = 0


def cached_rig(path: str, sha256: str, load=None):
    """The rig of ``path`` (content hash ``sha256``), loaded once per process: by ``load()`` when given (the
    Ray engine's fetch from the object store), else from the file."""
    rig = _RIGS.get(sha256)
    if rig is None:
        if load is None:
            from facepuppet.pipeline.rig import load_rig

            rig = load_rig(path)
        else:
            rig = load()
        rig = _RIGS[sha256] = rig
    return rig


def rig_arrays(path: str) -> dict:
    """The arrays of the rig file ``path``, inflated and checked, to be sent to workers elsewhere: reading them
    needs neither the mapping's modules nor the rig built (each worker builds it once, :func:`rig_of_arrays`)."""
    from facepuppet.pipeline.rig import read_rig_arrays

    return read_rig_arrays(path)


def rig_of_arrays(path: str, arrays):
    """The rig of file ``path`` from its arrays (:func:`rig_arrays`), or ``arrays`` itself when it is not a dict (a
    rig loaded before)."""
    if not isinstance(arrays, dict):
        return arrays
    from facepuppet.pipeline.rig import rig_from_arrays

    return rig_from_arrays(arrays, path)


def reused_tracker(options):
    """This process's tracker for ``options`` (a :class:`~facepuppet.pipeline.tracking.TrackerOptions`), reset to
    the start of a take; None for a backend not in :data:`REUSED_BACKENDS` (``animate`` then makes its own).

    The tracker is kept for the same backend and profile contents (a profile file rewritten between two clips
    gives a new tracker); asking for another one closes the one kept.
    """
    if options.backend not in REUSED_BACKENDS:
        return None
    from facepuppet._util.digest import file_digest

    key = (options.backend, options.profile, file_digest(options.profile) if options.profile else None)
    tracker = _TRACKERS.get(key)
    if tracker is None:
        from facepuppet.pipeline.tracking import make_tracker_for

        for old in _TRACKERS.values():
            old.close()
        _TRACKERS.clear()
        tracker = _TRACKERS[key] = make_tracker_for(options)
    else:
        tracker.reset()
    return tracker


def warm_up(options) -> list[tuple[str, float]]:
    """Load in this process what a worker's first clip would: ``animate``'s modules, the tracker kept for
    ``options`` (:func:`reused_tracker`) and, for the colour tracker, its compiled kernels (from numba's on-disk
    cache, shared by every process that imports this copy of facepuppet; compiled where missing). Changes no
    output: the kept tracker is reset before each clip.

    Returns
    -------
    list of (str, float)
        Each step's name and the wall-clock time (``time.time()``) it ended.
    """
    import facepuppet.pipeline.animate  # noqa: F401 - what a clip imports

    steps = [("imports", time.time())]
    reused_tracker(options)
    steps.append(("tracker", time.time()))
    if options.backend == "color":
        from facepuppet.capture.color.precompile import TASKS, run_task

        for name in TASKS:
            run_task(name)
        steps.append(("kernels", time.time()))
    return steps


def share_cores(threads: int = WORKER_THREADS) -> None:
    """Size this process's native thread pools to ``threads`` (at least 1): OpenCV's, FFmpeg's decoder's and BLAS's.

    A clip's work runs on one thread, but libraries start pools sized to the whole machine: OpenCV's parallel
    loops (the colour tracker's face cascade splits its work over one thread per core), FFmpeg's decoder (one
    frame thread per core, decoding ahead of the tracker) and BLAS. A worker with those pools keeps more than
    the one CPU it is counted as (and a Ray actor reserves) busy part of the time, and N workers on N cores
    start N threads each where one fits. With :data:`WORKER_THREADS` each, a worker is one core's worth of work
    and N workers take N cores. The thread counts change no output: FFmpeg decodes the same frames and the
    cascade finds the same faces with any number of threads.

    ``OPENCV_FFMPEG_THREADS`` is read when a video is opened (:func:`facepuppet.io.frames.open_media`), and the
    ``*_NUM_THREADS`` variables by the libraries loaded after this call; BLAS libraries already loaded are limited
    through ``threadpoolctl`` (a dependency of scikit-learn) where it is installed. numba's kernels are compiled
    without ``parallel`` and start no pool.
    """
    import cv2

    threads = max(1, int(threads))
    os.environ["OPENCV_FFMPEG_THREADS"] = str(threads)
    for name in BLAS_THREAD_VARIABLES:
        os.environ[name] = str(threads)
    cv2.setNumThreads(threads)
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        return
    threadpool_limits(limits=threads)


class _Progress:
    """Frames counted by ``animate``'s ``on_frame`` hook, sent on in batches."""

    def __init__(self, queue, index: int) -> None:
        self.queue, self.index = queue, index
        self.sent = self.count = 0
        self.last = time.monotonic()

    def __call__(self, _frame_index: int) -> None:
        self.count += 1
        now = time.monotonic()
        if now - self.last >= PROGRESS_EVERY_S:
            self.flush()
            self.last = now

    def flush(self) -> None:
        if self.queue is not None and self.count > self.sent:
            with contextlib.suppress(Exception):    # progress is a courtesy: a full or gone queue stops no clip
                self.queue.put((self.index, self.count - self.sent))
            self.sent = self.count


def one_line(error: BaseException) -> str:
    """An exception as one line: its message, with the type's name for errors the CLI does not expect."""
    from facepuppet.errors import FacepuppetError

    text = " ".join(str(error).split()) or type(error).__name__
    if not isinstance(error, (FacepuppetError, ValueError, OSError)):
        text = f"{type(error).__name__}: {text}"
    return text


def run_clip(task: ClipTask, queue=None, rig=None) -> ClipResult:
    """Animate one clip into its outputs (all or none); never raises for a failing clip.

    Parameters
    ----------
    task : ClipTask
    queue : object with ``put``, optional
        Where progress goes.
    rig : Rig, optional
        The rig itself (shipped by the engine); loaded from ``task.rig`` through the cache when None.
    """
    from facepuppet.pipeline.animate import animate

    t0, started = time.perf_counter(), time.time()
    progress = _Progress(queue, task.index)
    try:
        if rig is None:
            rig = cached_rig(task.rig, task.rig_sha256)
        config = dataclasses.replace(task.config, tracker=dataclasses.replace(task.config.tracker, progress=False))
        out = task.outputs
        anim = animate(task.clip, rig, glb=out.get("glb"), csv=out.get("csv"), preview=out.get("preview"),
                       config=config, keep_track=False, on_frame=progress, tracker=reused_tracker(config.tracker))
    except Exception as e:      # noqa: BLE001 - a failing clip is a row of the report, the batch goes on
        stop = next((x for x in (e.__cause__, e.__context__) if isinstance(x, Interrupted)), None)
        if stop is not None:    # a stop raised inside compiled code's C wrapper (SystemError): not the clip's fault
            raise stop from None
        progress.flush()
        log.debug("clip %s failed", task.clip, exc_info=True)
        return ClipResult(index=task.index, ok=False, frames=progress.count, seconds=time.perf_counter() - t0,
                          error=f"{task.clip}: {one_line(e)}" if task.clip not in str(e) else one_line(e),
                          started=started, worker=os.getpid())
    progress.flush()
    return ClipResult(index=task.index, ok=True, frames=int(len(anim.valid)), frames_with_face=int(anim.valid.sum()),
                      seconds=time.perf_counter() - t0, started=started, worker=os.getpid())


def _die_by_sigterm() -> None:
    """End this process at once, by SIGTERM's default action (no clean-up of the worker loop)."""
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    os.kill(os.getpid(), signal.SIGTERM)
    raise SystemExit(128 + signal.SIGTERM)      # not reached unless the signal is blocked


def guard_worker() -> None:
    """Make this worker process end cleanly with the batch.

    SIGTERM between clips ends the process; during a clip (:func:`run_guarded`) it stops the clip at the next
    frame (:mod:`facepuppet._util.interrupt`), whose temporary outputs are removed on the way out. On Linux the
    process also gets SIGTERM when its parent dies, however it died; on every system a watchdog thread looks at
    the parent every :data:`PARENT_WATCH_S` seconds and sends this process SIGTERM once the parent is gone, and
    again every :data:`PARENT_GONE_REPEAT_S` seconds (a stop that a clip's unwinding swallowed is asked again:
    an idle worker whose batch died ends, never waits for work forever). Ctrl-C is left to the batch, which
    ends its workers.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if sys.platform.startswith("linux"):
        import ctypes
        import multiprocessing

        with contextlib.suppress(OSError, AttributeError):
            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)
        parent = multiprocessing.parent_process()
        if parent is not None and os.getppid() != parent.pid:      # it died before the signal was asked for
            _die_by_sigterm()
    parent_pid = os.getppid()
    threading.Thread(target=_watch_parent, args=(parent_pid,), name="facepuppet-parent-watch", daemon=True).start()


def _watch_parent(parent_pid: int) -> None:
    """Send this process SIGTERM once its parent ``parent_pid`` is gone (looked at every :data:`PARENT_WATCH_S`
    seconds), and again every :data:`PARENT_GONE_REPEAT_S` seconds while it lives on."""
    while os.getppid() == parent_pid:
        time.sleep(PARENT_WATCH_S)
    while True:
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(PARENT_GONE_REPEAT_S)


def run_guarded(task: ClipTask, queue=None, rig=None) -> ClipResult:
    """:func:`run_clip`, ending the process once a SIGTERM has stopped and unwound the clip."""
    try:
        with handle_signals():
            signal.signal(signal.SIGINT, signal.SIG_IGN)
            return run_clip(task, queue, rig)
    except Interrupted:
        _die_by_sigterm()
