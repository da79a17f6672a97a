"""The Ray engine: a batch's clips on long-lived Ray actors, one per CPU slot, fed clips as they finish.

Each actor (:class:`ClipWorker`) is one Ray worker process that lives for the whole batch, like a local worker:
its imports, the colour tracker's compiled kernels, the tracker itself (reset before each clip) and each rig stay
loaded across its clips. A rig file is read once, by the driver, and its arrays go once into the object store
(``ray.put``; the driver imports none of the mapping's modules); an actor fetches them the first time one of its
clips needs the rig (shared memory on the same node, no copy), builds the rig and keeps it
(:func:`~facepuppet.batch.worker.cached_rig`).

A clip is one call of the actor's generator method :meth:`ClipWorker.run`, a Ray streaming generator: it yields
the frames done since its last yield (an ``int``, at most every :data:`~facepuppet.batch.worker.PROGRESS_EVERY_S`
seconds) and last the clip's :class:`~facepuppet.batch.worker.ClipResult`. The driver waits on all running
generators at once (``ray.wait``), so progress needs no actor of its own. When an actor's result comes in, the
next clip (longest first, as the batch orders them) goes to that actor; an actor that died under a clip gives
that clip a failed row and is replaced.

The batch opens its :class:`RaySession` (Ray connected, the actors asked for) before it hashes its clips, so the
actors' start-up (a worker process, imports, compiled kernels, tracker, for each) runs on the cluster while the
driver reads the clips; the clips go to the actors once the batch knows which to run.
"""

from __future__ import annotations

import contextlib
import logging
import os
import queue as queue_module
import threading
import time

from facepuppet.batch.timeline import Timeline, process_start_time
from facepuppet.batch.worker import (
    ClipResult,
    ClipTask,
    cached_rig,
    one_line,
    rig_arrays,
    rig_of_arrays,
    run_clip,
    share_cores,
    warm_up,
)
from facepuppet.errors import FacepuppetError

__all__ = ["run_ray", "RaySession", "ClipWorker", "RAY_MISSING", "RAY_TASK_CPUS", "RAY_INIT", "RAY_WORKER_NICENESS",
           "POLL_S", "STEPS_WAIT_S", "QUEUED_PER_ACTOR"]

log = logging.getLogger(__name__)

#: CPUs a Ray actor of the batch reserves (its native thread pools get as many threads, :func:`share_cores`).
RAY_TASK_CPUS = 1

#: Seconds the driver waits on the running clips before looking again.
POLL_S = 0.1

#: Clips queued on one actor at a time: the one it works on and the next (:func:`_drive`).
QUEUED_PER_ACTOR = 2

#: Seconds the driver waits at the end for the actors' start-up steps (the timeline's).
STEPS_WAIT_S = 5.0

#: What to say when the Ray engine is asked for without Ray installed.
RAY_MISSING = '--engine ray needs Ray: pip install "facepuppet[ray]"'

#: ``ray.init`` options of the local runtime the batch starts when given no ``address`` (``address="local"``: a
#: new runtime, never a cluster that ``ray start`` left on this machine): no dashboard, Ray's own messages from
#: warnings up (the workers' log lines still reach the driver's stderr).
RAY_INIT = {"include_dashboard": False, "logging_level": logging.WARNING}

#: Niceness of the worker processes of the local runtime the batch starts (Ray's variable ``RAY_worker_niceness``,
#: read by the runtime as it starts; left as it is when set). Ray's own default, 15, puts its workers behind every
#: other process of the machine; the batch's own runtime is this machine's foreground work, as the local engine's
#: worker processes (niceness 0) are. A cluster's nodes keep the niceness their ``ray start`` gave them.
RAY_WORKER_NICENESS = 0


class ClipWorker:
    """What one Ray actor of a batch does (made remote by :func:`run_ray`; plain Python here).

    Parameters
    ----------
    threads : int
        Threads of its native pools (:func:`~facepuppet.batch.worker.share_cores`): its CPUs.
    warm : TrackerOptions, optional
        The batch's tracker options: the actor loads at once what its first clip would
        (:func:`~facepuppet.batch.worker.warm_up`), while the driver sends out the rigs and the other actors start.
    """

    def __init__(self, threads: int = RAY_TASK_CPUS, warm=None) -> None:
        self.steps = [(f"process (nice {os.nice(0)})", process_start_time()), ("init", time.time())]
        self.clips = 0
        share_cores(threads)
        self.warming = None
        if warm is not None:                # on a thread of its own: the first clip's rig is fetched meanwhile
            self.warming = threading.Thread(target=self._warm_up, args=(warm,), name="facepuppet-warm-up",
                                            daemon=True)
            self.warming.start()

    def _warm_up(self, options) -> None:
        try:
            self.steps += warm_up(options)
        except Exception:                   # noqa: BLE001 - the first clip does the same work and says what fails
            log.debug("warm-up failed", exc_info=True)
        self.steps.append(("warmed up", time.time()))

    def steps_done(self) -> tuple[int, list]:
        """This actor's process id and its start-up steps (name, wall-clock time), for the batch's timeline:
        its process's start, ``__init__``'s, the warm-up's steps, its first clip's arrival, rig and start."""
        return os.getpid(), sorted(self.steps, key=lambda step: step[1] or 0.0)

    def run(self, task: ClipTask, rig_box: list):
        """Animate one clip: yield frame counts (``int``, frames since the last yield), then its ClipResult.

        ``rig_box`` holds the object reference of the rig file's arrays (in a list, so that Ray hands it over
        unresolved and it is fetched only by an actor that has not kept the rig yet), or the arrays or the rig
        itself. The first clip waits for the warm-up after fetching its rig. The clip runs on a thread of its
        own, which sends its frame counts and last an end mark through a queue: the generator returns as soon
        as the clip has.
        """
        self.clips += 1
        if self.clips == 1:
            self.steps.append(("first clip arrived", time.time()))
        rig = cached_rig(task.rig, task.rig_sha256, load=lambda: rig_of_arrays(task.rig, _resolve(rig_box[0])))
        if self.clips == 1:
            self.steps.append(("its rig", time.time()))
        if self.warming is not None:
            self.warming.join()
            self.warming = None
        counts: queue_module.SimpleQueue = queue_module.SimpleQueue()
        done: list[ClipResult] = []
        failure: list[BaseException] = []

        def clip() -> None:
            try:
                done.append(run_clip(task, _CountQueue(counts), rig))
            except BaseException as e:      # noqa: BLE001 - handed to the generator, which raises it
                failure.append(e)
            finally:
                counts.put(None)            # the end: the generator stops waiting at once

        worker = threading.Thread(target=clip, name=f"facepuppet-clip-{task.index}", daemon=True)
        worker.start()
        while (frames := counts.get()) is not None:
            yield frames
        worker.join()
        if failure:
            raise failure[0]
        yield done[0]


class _CountQueue:
    """The ``put`` that :func:`run_clip` sends progress through, keeping only the frame count."""

    def __init__(self, counts: queue_module.SimpleQueue) -> None:
        self.counts = counts

    def put(self, item) -> None:
        self.counts.put(int(item[1]))


def _resolve(ref):
    """The object behind a Ray object reference; anything else as it is."""
    try:
        import ray
    except ImportError:
        return ref
    return ray.get(ref) if isinstance(ref, ray.ObjectRef) else ref


@contextlib.contextmanager
def _worker_niceness():
    """``RAY_worker_niceness`` set to :data:`RAY_WORKER_NICENESS` in this process's environment (unless set) while
    the runtime it starts reads it."""
    name = "RAY_worker_niceness"
    if name in os.environ:
        yield
        return
    os.environ[name] = str(RAY_WORKER_NICENESS)
    try:
        yield
    finally:
        os.environ.pop(name, None)


def _slots(ray, workers: int | None, tasks: int) -> int:
    """Actors to start: ``workers`` if given, at most the cluster's CPUs over :data:`RAY_TASK_CPUS` (an actor
    that could not start would keep its clip waiting for ever), and at most one per clip."""
    cpus = int(float(ray.cluster_resources().get("CPU", RAY_TASK_CPUS)) // RAY_TASK_CPUS)
    return max(1, min(int(workers or cpus), cpus, tasks))


class RaySession:
    """Ray connected (or started) and a batch's actors asked for: opened by the batch before it plans its clips,
    so that the actors start (processes, imports, compiled kernels, tracker: seconds) while the driver hashes the
    clips and reads their frame counts, then given the clips to run (:meth:`run`) and closed.

    Uses the Ray runtime already started in this process if there is one; else connects to ``address`` (an
    existing cluster: ``auto``, ``HOST:PORT`` of its head, ``ray://HOST:10001``) or starts a local runtime of
    ``workers`` CPUs (:data:`RAY_INIT`); :meth:`close` ends the actors and shuts down what it started.

    Parameters
    ----------
    workers : int or None
        Actors (None, or more than the cluster has CPUs: one per CPU).
    address : str or None
        The cluster; None starts a local runtime.
    most : int
        At most this many actors: the clips that may need running.
    warm : TrackerOptions or None
        The batch's tracker options, which the actors load at once (:class:`ClipWorker`).
    """

    def __init__(self, *, workers: int | None, address: str | None, most: int, warm=None) -> None:
        self.timeline = Timeline("ray")
        try:
            import ray
        except ImportError:
            raise FacepuppetError(RAY_MISSING) from None
        self.ray, self.address, self.warm = ray, address, warm
        self.timeline.mark("ray imported")
        self.started = False
        self.actors: list = []
        if not ray.is_initialized():
            if address:
                ray.init(address=address, logging_level=RAY_INIT["logging_level"])
                self.timeline.mark(f"connected to the cluster at {address}")
            else:
                with _worker_niceness():
                    ray.init(address="local", num_cpus=max(1, int(workers or os.cpu_count() or 1)), **RAY_INIT)
                self.timeline.mark("own Ray runtime started")
            self.started = True
        try:
            self.remote = ray.remote(num_cpus=RAY_TASK_CPUS)(ClipWorker)
            for _ in range(_slots(ray, workers, most)):
                self.start_actor()
        except BaseException:
            self.close()
            raise
        self.timeline.mark(f"{len(self.actors)} actors asked for")

    def start_actor(self):
        """A new actor (:class:`ClipWorker`), warming up at once; kept in :attr:`actors`."""
        actor = self.remote.remote(RAY_TASK_CPUS, self.warm)
        self.actors.append(actor)
        return actor

    def end_actor(self, actor) -> None:
        """End ``actor`` (gone already or not) and forget it."""
        if actor in self.actors:
            self.actors.remove(actor)
        try:
            self.ray.kill(actor)
        except Exception:                       # noqa: BLE001, S110 - already gone
            pass

    def run(self, tasks: list[ClipTask], on_progress, on_result) -> None:
        """Run the tasks on the actors (module notes), in the order given; each rig put once into the object
        store. Actors beyond one per task end first."""
        for actor in self.actors[len(tasks):]:
            self.end_actor(actor)
        if tasks:
            _drive(self, tasks, on_progress, on_result)

    def close(self) -> None:
        """End the actors, shut down the runtime or connection this session started, log the timeline."""
        for actor in list(self.actors):
            self.end_actor(actor)
        self.timeline.mark("actors ended")
        if self.started:
            self.started = False
            self.ray.shutdown()
            self.timeline.mark("Ray shut down" if self.address else "own Ray runtime shut down")
        self.timeline.log()


def run_ray(tasks: list[ClipTask], *, workers: int | None, address: str | None, on_progress, on_result,
            session: RaySession | None = None) -> None:
    """Run the tasks on Ray actors (module notes), in the order given; each rig put once into the object store.

    ``session`` is a :class:`RaySession` the caller opened (and closes); without one, a session for these tasks
    is opened and closed here (``workers`` and ``address`` as :class:`RaySession` takes them). Clips and outputs
    must be on paths every node sees. Where the time went is logged at INFO level
    (:mod:`facepuppet.batch.timeline`).
    """
    if session is not None:
        session.run(tasks, on_progress, on_result)
        return
    if not tasks:
        try:
            import ray  # noqa: F401 - the engine's dependency, asked for even with nothing to run
        except ImportError:
            raise FacepuppetError(RAY_MISSING) from None
        return
    session = RaySession(workers=workers, address=address, most=len(tasks), warm=tasks[0].config.tracker)
    try:
        session.run(tasks, on_progress, on_result)
    finally:
        session.close()


def _drive(session: RaySession, tasks, on_progress, on_result) -> None:
    """Feed the tasks to the session's actors and hand back their progress and results.

    Each actor holds up to :data:`QUEUED_PER_ACTOR` clips: the one it works on and the next, which Ray runs as
    soon as the first returns (an actor runs its calls in order), so no actor waits for the driver between two
    clips. A second clip is queued only while at least one clip per actor is left to hand out, so the last
    clips still go to whichever actor is free first. One ``ray.wait`` on every queued clip's generator returns as
    soon as one has something (only an actor's first generator yields). When an actor dies, the clip it was on
    gets a failed row and its queued clips go back to the head of the line, for the actor that replaces it.
    """
    ray, timeline = session.ray, session.timeline
    queues: dict = {actor: [] for actor in session.actors}  # actor -> [(generator, task)], the clip it is on first
    rigs: dict = {}
    for t in tasks:
        if t.rig_sha256 not in rigs:
            rigs[t.rig_sha256] = ray.put(rig_arrays(t.rig))
    timeline.mark(f"{len(rigs)} rig(s) in the object store")
    todo = list(reversed(tasks))
    running: dict = {}                          # generator -> actor

    def give(actor, most: int = QUEUED_PER_ACTOR) -> None:
        queue = queues[actor]
        while todo and len(queue) < most and (not queue or len(todo) >= len(queues)):
            task = todo.pop()
            ref = actor.run.remote(task, [rigs[task.rig_sha256]])
            queue.append((ref, task))
            running[ref] = actor

    for most in range(1, QUEUED_PER_ACTOR + 1):  # round by round: the longest clips go to different actors
        for actor in list(queues):
            give(actor, most)
    while running:
        ready, _ = ray.wait(list(running), num_returns=1, timeout=POLL_S)
        for ref in ready:
            actor = running.get(ref)
            if actor is None:                   # a clip of an actor that died and was replaced meanwhile
                continue
            queue = queues[actor]
            task = queue[0][1]
            try:
                item = ray.get(next(ref))
            except StopIteration:
                item = ClipResult(index=task.index, ok=False, error=f"{task.clip}: Ray actor gave no result")
            except Exception as e:              # noqa: BLE001 - the actor died under this clip, or Ray failed it
                item = ClipResult(index=task.index, ok=False, error=f"{task.clip}: Ray actor failed ({one_line(e)})")
                for gone, waiting in reversed(queue[1:]):
                    del running[gone]
                    todo.append(waiting)        # never started: next in line, in their order
                del queue[1:]
                session.end_actor(actor)
                del queues[actor]
                actor = session.start_actor()
                queues[actor] = []              # ``queue`` is the dead actor's: its failed clip left to pop
            if isinstance(item, ClipResult):
                del running[queue.pop(0)[0]]
                give(actor)                     # first: the actor queues its next clip while the report is written
                timeline.clip(f"pid {item.worker}", item.started, item.seconds)
                on_result(item)
            else:
                on_progress(task.index, int(item))
    timeline.mark("last clip back")
    if timeline.wanted():                       # a round trip to every actor, for the log alone
        _startups(ray, session.actors, timeline)


def _startups(ray, actors: list, timeline: Timeline) -> None:
    """Each live actor's start-up steps into the timeline (one call each, all at once; a gone actor is left out)."""
    calls = [actor.steps_done.remote() for actor in actors]
    done, _ = ray.wait(calls, num_returns=len(calls), timeout=STEPS_WAIT_S)
    for ref in done:
        try:
            pid, steps = ray.get(ref)
        except Exception:                       # noqa: BLE001, S112 - the actor is gone
            continue
        timeline.worker(f"pid {pid}", steps)
