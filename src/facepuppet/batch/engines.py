"""Where a batch's clips run: worker processes on this machine (``local``) or Ray tasks (``ray``).

Both engines take the same :class:`~facepuppet.batch.worker.ClipTask` list, run
:func:`~facepuppet.batch.worker.run_clip` on each and call back ``on_progress(index, frames)`` as frames pass
and ``on_result(ClipResult)`` as clips finish, in the calling thread. Scheduling is the engine's own
(:class:`concurrent.futures.ProcessPoolExecutor`, Ray's scheduler); an interrupt (Ctrl-C, SIGTERM turned into
one by the batch) ends the workers, whose running clips leave no file behind.
"""

from __future__ import annotations

import logging
import multiprocessing
import queue as queue_module
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

from facepuppet.batch.worker import (
    ClipResult,
    ClipTask,
    cached_rig,
    fair_share,
    guard_worker,
    one_line,
    run_guarded,
    share_cores,
)
from facepuppet.errors import FacepuppetError

__all__ = ["ENGINES", "run_local", "run_ray", "RAY_MISSING", "RAY_TASK_CPUS"]

log = logging.getLogger(__name__)

#: Seconds the engines wait for a result before looking at the progress queue again.
POLL_S = 0.1

#: CPUs a Ray task of one clip reserves (its native thread pools get as many threads, :func:`share_cores`).
RAY_TASK_CPUS = 1

#: What to say when the Ray engine is asked for without Ray installed.
RAY_MISSING = '--engine ray needs Ray: pip install "facepuppet[ray]"'

OnProgress = Callable[[int, int], None]
OnResult = Callable[[ClipResult], None]

_QUEUE = None        # the progress queue of this worker process (set by _init_local)


def _init_local(progress_queue, threads: int) -> None:
    global _QUEUE
    _QUEUE = progress_queue
    guard_worker()
    share_cores(threads)


def _local_task(task: ClipTask) -> ClipResult:
    return run_guarded(task, _QUEUE)


def _drain(q, on_progress: OnProgress) -> None:
    while True:
        try:
            index, frames = q.get_nowait()
        except queue_module.Empty:
            return
        on_progress(index, frames)


def run_local(tasks: list[ClipTask], *, workers: int, on_progress: OnProgress, on_result: OnResult,
              address: str | None = None) -> None:
    """Run the tasks in ``workers`` processes of this machine (spawned; each lives for the whole batch, with
    :func:`~facepuppet.batch.worker.fair_share` threads in its native pools).

    ``address`` is not used (the Ray engine's).
    """
    if not tasks:
        return
    ctx = multiprocessing.get_context("spawn")
    progress = ctx.Queue()
    before = set(multiprocessing.active_children())
    workers = max(1, min(int(workers), len(tasks)))
    with ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_init_local,
                             initargs=(progress, fair_share(workers))) as pool:
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
                    on_result(result)
        except BaseException:
            for p in ours:
                if p.is_alive():
                    p.terminate()
            pool.shutdown(wait=True, cancel_futures=True)
            raise
        finally:
            _drain(progress, on_progress)


def _ray_task(task: ClipTask, progress, rig) -> ClipResult:
    from facepuppet.batch.worker import run_clip

    share_cores(RAY_TASK_CPUS)
    return run_clip(task, progress, rig)


def run_ray(tasks: list[ClipTask], *, workers: int, address: str | None, on_progress: OnProgress,
            on_result: OnResult) -> None:
    """Run the tasks as Ray tasks (:data:`RAY_TASK_CPUS` each), each rig put once into the object store; a Ray
    worker process keeps its tracker across the tasks it runs, as a local worker does.

    Uses the Ray runtime already started in this process if there is one; else connects to ``address`` (an
    existing cluster, e.g. ``ray://head:10001`` or ``auto``) or starts a local one with ``workers`` CPUs, and
    shuts down what it started at the end. Clips and outputs must be on paths every node sees.
    """
    try:
        import ray
        from ray.util.queue import Queue
    except ImportError:
        raise FacepuppetError(RAY_MISSING) from None
    if not tasks:
        return
    started = False
    if not ray.is_initialized():
        if address:
            ray.init(address=address, logging_level=logging.WARNING)
        else:
            ray.init(num_cpus=max(1, int(workers)), include_dashboard=False, logging_level=logging.WARNING)
        started = True
    refs: dict = {}
    try:
        rigs = {}
        for t in tasks:
            if t.rig_sha256 not in rigs:
                rigs[t.rig_sha256] = ray.put(cached_rig(t.rig, t.rig_sha256))
        progress = Queue()
        remote = ray.remote(num_cpus=RAY_TASK_CPUS)(_ray_task)
        refs = {remote.remote(t, progress, rigs[t.rig_sha256]): t for t in tasks}
        pending = list(refs)
        while pending:
            ready, pending = ray.wait(pending, num_returns=len(pending), timeout=POLL_S)
            _drain_ray(progress, on_progress)
            for ref in ready:
                task = refs[ref]
                try:
                    result = ray.get(ref)
                except Exception as e:          # noqa: BLE001 - the task's worker died under this clip
                    result = ClipResult(index=task.index, ok=False,
                                        error=f"{task.clip}: Ray task failed ({one_line(e)})")
                on_result(result)
        _drain_ray(progress, on_progress)
    except BaseException:
        for ref in refs:
            try:
                ray.cancel(ref, force=True)
            except Exception:                   # noqa: BLE001, S110 - already finished
                pass
        raise
    finally:
        if started:
            ray.shutdown()


def _drain_ray(progress, on_progress: OnProgress) -> None:
    n = progress.qsize()
    if n:
        for index, frames in progress.get_nowait_batch(n):
            on_progress(index, frames)


#: Engine name -> runner; ``local`` is the default.
ENGINES = {"local": run_local, "ray": run_ray}
