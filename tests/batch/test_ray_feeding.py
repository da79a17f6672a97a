"""The Ray engine's driver against a stand-in for Ray (no Ray needed): actors that run their calls in order, as
Ray's do. Each clip gets exactly one result; an actor never holds more than two clips; the last clips go to the
actor that is free; an actor that dies under a clip gives that clip a failed row, and the clip queued behind it
runs on another actor, once. A runtime the engine starts itself runs its workers at niceness 0. A batch connects and
asks for its actors before it hashes its clips, one actor at most per clip to run, and connects to nothing when
its report lists every clip done."""

from __future__ import annotations

import importlib.machinery
import os
import sys
import types

import pytest

from facepuppet.batch import ray_engine
from facepuppet.batch import run as run_module
from facepuppet.batch.jobs import Job
from facepuppet.batch.worker import ClipResult, ClipTask
from facepuppet.pipeline.animate import AnimateConfig


class ActorDied(Exception):
    """What Ray raises for the calls of an actor that died."""


class FakeActor:
    """An actor: its calls in a queue, the first one running; ``dies_on`` the clip index under which it dies."""

    def __init__(self, ray, dies_on):
        self.ray, self.dies_on, self.calls, self.dead = ray, dies_on, [], False
        self.run = types.SimpleNamespace(remote=self.call)
        self.steps_done = types.SimpleNamespace(remote=lambda: None)

    def call(self, task, rig_box):
        assert rig_box == ["rig-ref"]
        gen = FakeGenerator(self, task)
        self.calls.append(gen)
        self.ray.most_queued = max(self.ray.most_queued, len(self.calls))
        return gen


class FakeGenerator:
    """A streaming generator of one call: 3 frame counts of 1, then the clip's result."""

    def __init__(self, actor, task):
        self.actor, self.task, self.items = actor, task, [1, 1, 1]

    def ready(self) -> bool:
        return self.actor.dead or self.actor.calls[0] is self

    def __next__(self):
        if self.actor.dead or self.task.index == self.actor.dies_on:
            self.actor.dead = True
            raise ActorDied("the actor died")
        if self.items:
            return self.items.pop()
        self.actor.calls.pop(0)
        self.actor.ray.ran.append((self.task.index, id(self.actor)))
        return ClipResult(index=self.task.index, ok=True, frames=3, frames_with_face=3, worker=id(self.actor))


class FakeRay:
    """The part of Ray's API the engine uses; the n-th actor started dies under clip ``deaths[n]``."""

    def __init__(self, cpus: int, deaths: dict[int, int]):
        self.cpus, self.deaths = cpus, deaths
        self.actors: list[FakeActor] = []
        self.ran: list[tuple[int, int]] = []
        self.most_queued = 0

    def is_initialized(self):
        return True

    def cluster_resources(self):
        return {"CPU": float(self.cpus)}

    def remote(self, **_options):
        def wrap(_cls):
            def start(*_args):
                actor = FakeActor(self, self.deaths.get(len(self.actors)))
                self.actors.append(actor)
                return actor
            return types.SimpleNamespace(remote=start)
        return wrap

    def put(self, value):
        assert value == "arrays"
        return "rig-ref"

    def wait(self, refs, num_returns=1, timeout=None):
        ready = [r for r in refs if r.ready()][:num_returns]
        assert ready, "the driver waits on clips of which none can run"
        return ready, [r for r in refs if r not in ready]

    def get(self, value):
        return value

    def kill(self, actor):
        actor.dead = True

    def shutdown(self):
        pass


def run(monkeypatch, clips: int, cpus: int, deaths: dict[int, int]):
    ray = FakeRay(cpus, deaths)
    monkeypatch.setitem(sys.modules, "ray", ray)
    monkeypatch.setattr(ray_engine, "rig_arrays", lambda path: "arrays")
    tasks = [ClipTask(index=i, clip=f"c{i}.mp4", rig="rig.npz", rig_sha256="r", outputs={}, config=AnimateConfig())
             for i in range(clips)]
    results, frames = [], {}

    def on_progress(index, n):
        frames[index] = frames.get(index, 0) + n

    ray_engine.run_ray(tasks, workers=None, address=None, on_progress=on_progress, on_result=results.append)
    return ray, results, frames


@pytest.mark.parametrize("clips", [1, 2, 3, 4, 7])
def test_each_clip_runs_once_with_at_most_two_per_actor(monkeypatch, clips):
    ray, results, frames = run(monkeypatch, clips, cpus=2, deaths={})
    assert sorted(r.index for r in results) == list(range(clips))
    assert all(r.ok for r in results)
    assert frames == dict.fromkeys(range(clips), 3)
    assert sorted(i for i, _ in ray.ran) == list(range(clips))
    assert len(ray.actors) == min(2, clips)
    assert ray.most_queued == (2 if clips >= 4 else 1)   # a second clip only while one per actor is left
    if clips >= 2:                                  # the two longest clips (the first two) on different actors
        first = dict(ray.ran)
        assert first[0] != first[1]


def test_an_actor_dying_fails_its_clip_and_its_queued_clip_runs_elsewhere(monkeypatch):
    # actor 0 holds clips 0 and 2 (round by round: 0 and 1 first, then 2 and 3) and dies under clip 0
    ray, results, frames = run(monkeypatch, 6, cpus=2, deaths={0: 0})
    by_index = {r.index: r for r in results}
    assert sorted(by_index) == list(range(6)) and len(results) == 6
    assert not by_index[0].ok and "Ray actor failed" in by_index[0].error and "c0.mp4" in by_index[0].error
    assert all(by_index[i].ok for i in range(1, 6))
    assert sorted(i for i, _ in ray.ran) == [1, 2, 3, 4, 5]     # clip 2, queued on the dead actor, ran once
    assert len(ray.actors) == 3                                 # the dead one replaced
    assert ray.most_queued <= 2


class FakeRayToStart(FakeRay):
    """A Ray not started yet: ``init`` notes the address asked for and the workers' niceness it would read."""

    def __init__(self, cpus: int):
        super().__init__(cpus, {})
        self.started, self.inits = False, []

    def is_initialized(self):
        return self.started

    def init(self, address=None, **_options):
        self.inits.append((address, os.environ.get("RAY_worker_niceness")))
        self.started = True


@pytest.mark.parametrize("address, user, seen", [(None, None, "0"), (None, "7", "7"), ("10.0.0.1:6379", None, None)],
                         ids=["own runtime", "own runtime, user's niceness", "a cluster"])
def test_an_own_runtime_starts_its_workers_at_niceness_0(monkeypatch, address, user, seen):
    ray = FakeRayToStart(2)
    monkeypatch.setitem(sys.modules, "ray", ray)
    monkeypatch.setattr(ray_engine, "rig_arrays", lambda path: "arrays")
    if user is None:
        monkeypatch.delenv("RAY_worker_niceness", raising=False)
    else:
        monkeypatch.setenv("RAY_worker_niceness", user)
    tasks = [ClipTask(index=0, clip="c0.mp4", rig="rig.npz", rig_sha256="r", outputs={}, config=AnimateConfig())]
    results = []
    ray_engine.run_ray(tasks, workers=2, address=address, on_progress=lambda *_: None, on_result=results.append)
    assert [r.ok for r in results] == [True]
    assert ray.inits == [("local" if address is None else address, seen)]
    assert os.environ.get("RAY_worker_niceness") == user         # the process's environment as it was
    assert ray_engine.RAY_WORKER_NICENESS == 0


class FakeRayLogged(FakeRayToStart):
    """A Ray not started yet that notes, in ``events``, its start, each actor asked for, each ended, its end."""

    __spec__ = importlib.machinery.ModuleSpec("ray", None)     # what importlib.util.find_spec reads

    def __init__(self, cpus: int, events: list):
        super().__init__(cpus)
        self.events = events

    def init(self, address=None, **options):
        super().init(address, **options)
        self.events.append("init")

    def remote(self, **options):
        wrapped = super().remote(**options)

        def wrap(cls):
            start = wrapped(cls).remote

            def logged(*args):
                self.events.append("actor")
                return start(*args)
            return types.SimpleNamespace(remote=logged)
        return wrap

    def kill(self, actor):
        super().kill(actor)
        self.events.append("kill")

    def shutdown(self):
        self.events.append("shutdown")


def batch(monkeypatch, tmp_path, clips: int, events: list, *, hashed=None):
    """run_batch on ``clips`` jobs with the Ray engine against :class:`FakeRayLogged`; each clip's hashing noted
    in ``events`` (or done by ``hashed(path)``)."""
    ray = FakeRayLogged(2, events)
    monkeypatch.setitem(sys.modules, "ray", ray)
    monkeypatch.setattr(ray_engine, "rig_arrays", lambda path: "arrays")
    monkeypatch.setattr(run_module, "check_rigs", lambda jobs: {"rig.npz": "r"})

    def sha(path):
        events.append("hash")
        return hashed(path) if hashed else "c" + os.path.basename(path)
    monkeypatch.setattr(run_module, "file_sha256", sha)
    jobs = []
    for k in range(clips):
        (tmp_path / f"c{k}.mp4").write_bytes(b"")
        jobs.append(Job(clip=str(tmp_path / f"c{k}.mp4"), rig="rig.npz", name=f"c{k}", source=f"argument {k + 1}"))
    summary = run_module.run_batch(jobs, tmp_path / "out", run_module.BatchConfig(engine="ray", address="10.0.0.1:6379",
                                                                                  progress=False))
    return ray, summary


def test_the_batch_asks_for_its_actors_before_it_hashes_its_clips(monkeypatch, tmp_path):
    events: list = []
    ray, summary = batch(monkeypatch, tmp_path, 3, events)
    assert [r.status for r in summary.rows] == ["done"] * 3
    assert events[:3] == ["init", "actor", "actor"]              # connected, both actors asked for, then...
    assert events[3:6] == ["hash"] * 3                           # ...the clips hashed
    assert events[-3:] == ["kill", "kill", "shutdown"]           # the actors ended, the connection closed
    assert sorted(i for i, _ in ray.ran) == [0, 1, 2]


def test_one_clip_to_run_keeps_one_actor(monkeypatch, tmp_path):
    events: list = []
    ray, summary = batch(monkeypatch, tmp_path, 1, events)
    assert [r.status for r in summary.rows] == ["done"]
    assert events.count("actor") == 1 and len(ray.actors) == 1


def test_more_actors_than_clips_to_run_end_before_the_clips(monkeypatch, tmp_path):
    events: list = []
    batch(monkeypatch, tmp_path, 2, events)                      # both clips done (no outputs: the fake writes none)
    out = tmp_path / "out"
    (out / "c0.glb").write_bytes(b"glb")                         # c0's output there: only c1 is to run again
    events.clear()
    ray, summary = batch(monkeypatch, tmp_path, 2, events)
    assert [r.status for r in summary.rows] == ["skipped", "done"]
    assert events.count("actor") == 1                            # one clip looks undone: one actor asked for


def done_before(monkeypatch, tmp_path, clips: int) -> list:
    """A batch of ``clips`` run once, their outputs put in place (the fake actors write none); its events cleared."""
    events: list = []
    batch(monkeypatch, tmp_path, clips, events)
    for k in range(clips):
        (tmp_path / "out" / f"c{k}.glb").write_bytes(b"glb")
    events.clear()
    return events


def test_a_rerun_with_every_clip_done_connects_to_no_cluster(monkeypatch, tmp_path):
    events = done_before(monkeypatch, tmp_path, 2)
    ray, summary = batch(monkeypatch, tmp_path, 2, events)
    assert [r.status for r in summary.rows] == ["skipped", "skipped"]
    assert events == ["hash", "hash"] and ray.inits == []


def test_a_clip_changed_since_the_report_still_runs_when_every_clip_looked_done(monkeypatch, tmp_path):
    events = done_before(monkeypatch, tmp_path, 2)
    ray, summary = batch(monkeypatch, tmp_path, 2, events, hashed=lambda path: "changed")
    assert [r.status for r in summary.rows] == ["done", "done"]
    assert events[:2] == ["hash", "hash"] and events[2] == "init"   # the engine opened its own session
    assert events[-1] == "shutdown"


def test_a_stop_while_the_clips_are_hashed_ends_the_actors(monkeypatch, tmp_path):
    events: list = []

    def stopped(path):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        batch(monkeypatch, tmp_path, 2, events, hashed=stopped)
    assert events == ["init", "actor", "actor", "hash", "kill", "kill", "shutdown"]
