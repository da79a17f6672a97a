"""The colour tracker's kernels compiled before their first use, by worker processes in parallel.

numba compiles a kernel on its first call and keeps the machine code in its on-disk cache, where every later
process finds it (all the tracker's kernels load in under a second). On a fresh machine, though, the colour
tracker's first frame waits for the whole compile. :func:`precompile` splits that work
into :data:`TASKS` (the outline kernels of the eyes, the brows and the mouth, the rest of a frame's work, the
snakes) and hands them to worker processes, one per core, while the caller goes on (the demo renders its performer
meanwhile); :meth:`Precompile.wait` returns when the kernels are in the cache. With a warm cache each task only
loads its kernels.

The tasks call the kernels on small synthetic inputs of the types the tracker passes them (types select the
compiled code, values do not). Kernels and the functions they call are compiled so that processes compiling at
once never write the same cache entry differently (:mod:`facepuppet._util.jit`). A test runs the tracker
after :func:`precompile` and checks that it compiles nothing.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from typing import IO

import numpy as np

from facepuppet.capture.color import jobs

__all__ = ["TASKS", "Precompile", "precompile", "run_task", "wait_pending"]

#: The work :func:`precompile` can hand out, longest first: the outline kernels of each part (the eyes' task
#: also compiles the blob kernel, which the brows' and the mouth's then load from the cache), the rest of a
#: frame's work, and the lips' snakes (not needed where the profile's shape models read the lips).
TASKS = ("eyes", "frame", "brows", "mouth", "snakes")

_CROP = 96                                              # synthetic crop side, pixels


def _outline_inputs() -> dict:
    """Arguments of :func:`~facepuppet.capture.color.rules.outline_features` of the tracker's types: a blank crop,
    the generic layout placed on it, the feature rectangles."""
    from facepuppet.capture.color.profile import GENERIC_MOUTH_REACH
    from facepuppet.capture.color.rules import BLOB_PARAMS, BOX_NAMES
    from facepuppet.capture.pose import generic_curves

    n = _CROP
    g = generic_curves()[..., :2]
    layout = np.ascontiguousarray((g - g.min(axis=(0, 1))) / np.ptp(g, axis=(0, 1)).max() * (0.6 * n) + 0.2 * n)
    boxes = np.tile(np.array([n // 4, n // 4, 3 * n // 4, 3 * n // 4], np.int64), (len(BOX_NAMES), 1))
    return {"C": np.zeros((n, n), np.float32), "raw": np.zeros((n, n), np.float32),
            "value": np.zeros((n, n), np.uint8), "layout": layout, "mouth_offset": np.zeros(2), "boxes": boxes,
            "blob_params": BLOB_PARAMS, "unit": 0.5 * n, "mouth_reach": GENERIC_MOUTH_REACH,
            "rgb": np.zeros((n, n, 3), np.uint8)}


def _frame_work(part: str) -> None:
    """What the colour tracker compiles for a frame besides the outlines (Eq. 1 and the contrast, the eye
    search, the skin test, the rectangles, the lid model, the filters and the head pose, the glare and veil tests, the
    alignment of the followed crop), or the snakes."""
    from facepuppet.capture.color.config import ColorTrackerConfig, LandmarkConfig
    from facepuppet.capture.color.tracker import ColorTracker

    tracker = ColorTracker(config=ColorTrackerConfig(landmarks=LandmarkConfig(enabled=False)))
    try:
        tracker.warmup(part)
        if part == "frame":
            from facepuppet.capture.color.glare import glare_pixels

            w, h = tracker.crop_size
            glare_pixels(np.zeros((h, w, 3), np.uint8), tracker.feature_boxes[:2], 0, 0, 2, 2, 1.0)
            from facepuppet.capture.color.veil import warmup as veil_warmup

            veil_warmup((w, h))
            from facepuppet.capture.color.align import blur3, ecc_affine

            grey = np.zeros((h // 3, w // 3), np.float32)
            ecc_affine(blur3(grey), grey, np.eye(2, 3), 1, 1e-3)
    finally:
        tracker.close()


def run_task(name: str) -> float:
    """Compile (or load from the cache) the kernels of one of :data:`TASKS`; returns the seconds it took."""
    t0 = time.perf_counter()
    if name in ("eyes", "brows", "mouth"):
        from facepuppet.capture.color.rules import outline_features

        inputs = _outline_inputs()
        outline_features(inputs.pop("C"), **inputs, parts=(name,))
    elif name in ("frame", "snakes"):
        _frame_work(name)
    else:
        raise ValueError(f"unknown precompile task {name!r}; known: {', '.join(TASKS)}")
    return time.perf_counter() - t0


class Precompile:
    """Kernels being compiled by worker processes (:func:`precompile`)."""

    def __init__(self, workers: list[tuple[tuple[str, ...], subprocess.Popen, IO[bytes], IO[bytes]]]):
        self._workers = workers             # (tasks, process, its stdout file, its stderr file)
        self._result: dict[str, float | str] | None = None

    def wait(self) -> dict[str, float | str]:
        """Wait for every task. Returns, per task, the seconds it took in its worker, or why it failed (the
        kernels of a failed task are then compiled on first use, as without this)."""
        if self._result is None:
            out: dict[str, float | str] = {}
            for tasks, proc, stdout, stderr in self._workers:
                proc.wait()
                done = {}
                for f in (stdout, stderr):
                    f.seek(0)
                for line in stdout.read().decode(errors="replace").splitlines():
                    try:
                        done.update(json.loads(line))
                    except ValueError:
                        pass
                told = stderr.read().decode(errors="replace").strip().splitlines()
                why = told[-1] if told else f"worker exited with {proc.returncode}"
                out.update({t: done.get(t, why) for t in tasks})
                stdout.close()
                stderr.close()
            self._result = out
            jobs.discard(self)
        return self._result


def precompile(tasks: tuple[str, ...] = TASKS, workers: int | None = None) -> Precompile:
    """Start compiling the kernels of ``tasks`` into numba's cache in ``workers`` processes (default: one per
    core, at most one per task) and return at once.

    Wait for the returned job before tracking; a :class:`~facepuppet.capture.color.tracker.ColorTracker` made
    in this process waits for it anyway (:func:`wait_pending`), since compiling the same kernels in two
    processes at once only slows both. With fewer than two workers nothing is started: the tracker compiles
    on first use, as fast as one worker would.

    The workers are fresh interpreters running this module (``python -m facepuppet.capture.color.precompile TASK
    ...``), so the caller's script is not imported again in them.
    """
    unknown = [t for t in tasks if t not in TASKS]
    if unknown:
        raise ValueError(f"unknown precompile tasks {unknown}; known: {', '.join(TASKS)}")
    ordered = [t for t in TASKS if t in tasks]
    n = min(len(ordered), workers if workers is not None else (os.cpu_count() or 1))
    if n < 2:
        return Precompile([])
    workers_started = []
    for share in (tuple(ordered[i::n]) for i in range(n)):     # longest first, dealt out in turn
        # Files, not pipes: a worker's warnings cannot fill a pipe nobody reads until wait().
        out, err = tempfile.TemporaryFile(), tempfile.TemporaryFile()
        proc = subprocess.Popen([sys.executable, "-m", __name__, *share], stdout=out, stderr=err,
                                stdin=subprocess.DEVNULL)
        workers_started.append((share, proc, out, err))
    job = Precompile(workers_started)
    jobs.add(job)
    return job


def wait_pending() -> None:
    """Wait for every :func:`precompile` job this process started and has not waited for."""
    jobs.wait_pending()


def _main(argv: list[str]) -> int:
    """Run the tasks named; one JSON line per task on stdout: its seconds, or why it failed."""
    for name in argv:
        try:
            done: float | str = run_task(name)
        except Exception as exc:                # the next task may still compile
            done = f"{type(exc).__name__}: {exc}"
        sys.stdout.write(json.dumps({name: done}) + "\n")
        sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(_main(sys.argv[1:]))
