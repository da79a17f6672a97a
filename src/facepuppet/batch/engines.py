"""Where a batch's clips run: worker processes on this machine (``local``) or Ray actors (``ray``,
:mod:`facepuppet.batch.ray_engine`).

Both engines take the same :class:`~facepuppet.batch.worker.ClipTask` list, run
:func:`~facepuppet.batch.worker.run_clip` on each, handing out the clips in the order given (the batch puts the
longest first, so that no worker is left alone with a long clip at the end) to whichever worker is free, and call
back ``on_progress(index, frames)`` as frames pass and ``on_result(ClipResult)`` as clips finish, in the calling
thread. An interrupt (Ctrl-C, SIGTERM turned into one by the batch) ends the workers; a local worker's running
clip leaves no file behind.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import queue as queue_module
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

from facepuppet.batch.ray_engine import RAY_MISSING, RAY_TASK_CPUS, run_ray
from facepuppet.batch.timeline import Timeline
from facepuppet.batch.worker import (
    ClipResult,
    ClipTask,
    guard_worker,
    one_line,
    run_guarded,
    share_cores,
)

__all__ = ["ENGINES", "run_local", "run_ray", "RAY_MISSING", "RAY_TASK_CPUS"]

log = logging.getLogger(__name__)

#: Seconds the engines wait for a result before looking at the progress queue again.
POLL_S = 0.1

OnProgress = Callable[[int, int], None]
OnResult = Callable[[ClipResult], None]

_QUEUE = None        # the progress queue of this worker process (set by _init_local)


def _init_local(progress_queue) -> None:
    global _QUEUE
    _QUEUE = progress_queue
    guard_worker()
    share_cores()


def _local_task(task: ClipTask) -> ClipResult:
    return run_guarded(task, _QUEUE)


def _drain(q, on_progress: OnProgress) -> None:
    while True:
        try:
            index, frames = q.get_nowait()
        except queue_module.Empty:
            return
        on_progress(index, frames)


def run_local(tasks: list[ClipTask], *, workers: int | None, on_progress: OnProgress, on_result: OnResult,
              address: str | None = None) -> None:
    """Run the tasks in ``workers`` processes of this machine (None: ``os.cpu_count()``; spawned, each living
    for the whole batch, with one thread in its native pools: :func:`~facepuppet.batch.worker.share_cores`).

    ``address`` is not used (the Ray engine's). Where the time went is logged at INFO level
    (:mod:`facepuppet.batch.timeline`).
    """
    if not tasks:
        return
    timeline = Timeline("local")
    ctx = multiprocessing.get_context("spawn")
    progress = ctx.Queue()
    before = set(multiprocessing.active_children())
    workers = max(1, min(int(workers or os.cpu_count() or 1), len(tasks)))
    with ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_init_local,
                             initargs=(progress,)) as pool:
        futures = {pool.submit(_local_task, t): t for t in tasks}
        ours = [p for p in multiprocessing.active_children() if p not in before]
        try:
            pending = set(futures)
            while pending:
                done, pending = wait(pending, timeout=POLL_S, return_when=FIRST_COMPLETED)
                _drain(progress, on_progress)
                for f in done:
                    task = futures[f]
                    try:
                        result = f.result()
                    except Exception as e:      # noqa: BLE001 - the worker process died under this clip
                        result = ClipResult(index=task.index, ok=False,
                                            error=f"{task.clip}: worker process ended ({one_line(e)})")
                    timeline.clip(f"pid {result.worker}", result.started, result.seconds)
                    on_result(result)
            timeline.mark("last clip back")
        except BaseException:
            for p in ours:
                if p.is_alive():
                    p.terminate()
            pool.shutdown(wait=True, cancel_futures=True)
            raise
        finally:
            _drain(progress, on_progress)
    timeline.mark("workers ended")
    timeline.log()


#: Engine name -> runner; ``local`` is the default.
ENGINES = {"local": run_local, "ray": run_ray}
