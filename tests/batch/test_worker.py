"""A batch worker's reuse across clips: a reset colour tracker sees a new take as a new tracker does, a worker's
clips written with its kept tracker are `animate`'s bytes; the threads each worker's native pools get."""

from __future__ import annotations

import itertools
import os

import numpy as np
import pytest

from facepuppet.batch import worker
from facepuppet.batch.worker import BLAS_THREAD_VARIABLES, ClipTask, reused_tracker, rig_arrays, run_clip, share_cores
from facepuppet.pipeline.animate import AnimateConfig, animate
from facepuppet.pipeline.tracking import TrackerOptions

#: Frames of each shared clip tracked in the tracker test (the second clip's face is found afresh).
FRAMES = 45


def frames_of(path, n: int, start: int = 0) -> list[np.ndarray]:
    from facepuppet.io.frames import open_media

    with open_media(path) as source:
        return list(itertools.islice(source, start, start + n))


def features(tracker, frames: list[np.ndarray]) -> list:
    return [tracker.track(rgb, int(round(k * 1000 / 30))) for k, rgb in enumerate(frames)]


def same_features(a: list, b: list) -> bool:
    for fa, fb in zip(a, b, strict=True):
        if fa.valid != fb.valid:
            return False
        for name in ("curves", "rotation", "translation", "points"):
            if not np.array_equal(getattr(fa, name), getattr(fb, name), equal_nan=True):
                return False
    return True


def test_a_reset_tracker_tracks_the_next_clip_as_a_new_one(assets):
    from facepuppet.capture.color.tracker import ColorTracker

    first = frames_of(assets / "video" / "performer_a.mp4", FRAMES)
    second = frames_of(assets / "video" / "performer_c.mp4", FRAMES)
    kept = ColorTracker()
    on_first = features(kept, first)
    assert sum(f.valid for f in on_first) > FRAMES // 2            # it followed a face: there is state to forget
    kept.reset()
    reused = features(kept, second)
    fresh = features(ColorTracker(), second)
    assert sum(f.valid for f in fresh) > FRAMES // 2
    assert same_features(reused, fresh)
    kept.reset()                                                    # and back to the first clip
    assert same_features(features(kept, first), on_first)
    later = frames_of(assets / "video" / "performer_a.mp4", FRAMES, start=FRAMES)
    kept.reset()                                                    # the same face where it just was
    assert same_features(features(kept, later), features(ColorTracker(), later))


def test_without_reset_the_last_take_would_show(assets):
    """The test above can fail: a tracker carried on from a take whose face sits where the next take's does
    follows it on (its filters and face frame carried over) instead of finding it afresh, and tracks it
    differently (a carried tracker that loses the last take's face searches anew, as a fresh one does)."""
    from facepuppet.capture.color.tracker import ColorTracker

    first = frames_of(assets / "video" / "performer_a.mp4", FRAMES)
    later = frames_of(assets / "video" / "performer_a.mp4", FRAMES, start=FRAMES)
    carried = ColorTracker()
    features(carried, first)
    assert not same_features(features(carried, later), features(ColorTracker(), later))


@pytest.fixture(scope="module")
def two_clips(demo, tmp_path_factory):
    """Two different clips cut from the demo's performance, its rig and profile."""
    import cv2

    folder = tmp_path_factory.mktemp("clips")
    cap = cv2.VideoCapture(str(demo.files["performance.mp4"]))
    fps, size = cap.get(cv2.CAP_PROP_FPS), (int(cap.get(3)), int(cap.get(4)))
    frames = [f for ok, f in iter(cap.read, (False, None)) if ok][:100]
    cap.release()
    paths = []
    for name, part in (("early", frames[:40]), ("late", frames[60:100][::-1])):
        out = cv2.VideoWriter(str(folder / f"{name}.mp4"), cv2.VideoWriter_fourcc(*"mp4v"), fps, size)
        for f in part:
            out.write(f)
        out.release()
        paths.append(folder / f"{name}.mp4")
    return paths, demo.files["rig.npz"], demo.files["performer-profile.npz"]


def test_a_worker_keeps_its_tracker_and_writes_animates_bytes(two_clips, tmp_path):
    paths, rig, profile = two_clips
    config = AnimateConfig(tracker=TrackerOptions(profile=str(profile), progress=False))
    reference = {}
    for p in paths:
        animate(p, rig, glb=tmp_path / f"ref-{p.stem}.glb", csv=tmp_path / f"ref-{p.stem}.csv", config=config)
        reference[p.stem] = [(tmp_path / f"ref-{p.stem}.{e}").read_bytes() for e in ("glb", "csv")]

    kept = reused_tracker(config.tracker)
    for i, p in enumerate([*paths, paths[0]]):                        # early, late, early again
        outputs = {"glb": str(tmp_path / f"{i}.glb"), "csv": str(tmp_path / f"{i}.csv")}
        task = ClipTask(index=i, clip=str(p), rig=str(rig), rig_sha256="rig", outputs=outputs, config=config)
        result = run_clip(task)
        assert result.ok and result.frames == 40, result.error
        assert [(tmp_path / f"{i}.{e}").read_bytes() for e in ("glb", "csv")] == reference[p.stem]
        assert reused_tracker(config.tracker) is kept                # one tracker for all the worker's clips


def test_other_trackers_are_not_kept():
    assert reused_tracker(TrackerOptions(backend="mediapipe")) is None
    assert "mediapipe" not in worker.REUSED_BACKENDS


def test_share_cores_sizes_opencvs_the_decoders_and_blass_pools(monkeypatch):
    import cv2
    from threadpoolctl import threadpool_info, threadpool_limits

    before = cv2.getNumThreads()
    for name in ("OPENCV_FFMPEG_THREADS", *BLAS_THREAD_VARIABLES):
        monkeypatch.delenv(name, raising=False)
    with threadpool_limits(limits=None):                             # BLAS's count put back at the end
        try:
            share_cores()                                            # a worker's: one thread
            assert cv2.getNumThreads() == 1 and os.environ["OPENCV_FFMPEG_THREADS"] == "1"
            assert all(os.environ[name] == "1" for name in BLAS_THREAD_VARIABLES)
            assert all(pool["num_threads"] == 1 for pool in threadpool_info() if pool["user_api"] == "blas")
            share_cores(0)                                            # at least one
            assert cv2.getNumThreads() == 1
            share_cores(3)
            assert cv2.getNumThreads() == 3 and os.environ["OPENCV_FFMPEG_THREADS"] == "3"
        finally:
            cv2.setNumThreads(before)


def test_a_ray_actors_clip_streams_its_frame_counts_then_animates_result(two_clips, tmp_path, monkeypatch):
    """The Ray actor's method as plain Python (no Ray needed): frame counts adding up to the clip's frames, then
    the result, with `animate`'s bytes; a clip that cannot be read gives a failed result, not an error."""
    import cv2
    from threadpoolctl import threadpool_limits

    from facepuppet.batch.ray_engine import ClipWorker

    paths, rig, profile = two_clips
    config = AnimateConfig(tracker=TrackerOptions(profile=str(profile), progress=False))
    animate(paths[1], rig, glb=tmp_path / "ref.glb", config=config)
    before = cv2.getNumThreads()
    for name in ("OPENCV_FFMPEG_THREADS", *BLAS_THREAD_VARIABLES):   # set by the actor: put back after
        monkeypatch.setenv(name, os.environ.get(name, "1"))
    with threadpool_limits(limits=None):                             # BLAS's count put back at the end
        try:
            actor = ClipWorker(1)
            task = ClipTask(index=7, clip=str(paths[1]), rig=str(tmp_path / "not-read.npz"), rig_sha256="shipped",
                            outputs={"glb": str(tmp_path / "out.glb")}, config=config)
            items = list(actor.run(task, [rig_arrays(str(rig))]))   # the rig's arrays as shipped, not its path
            bad = ClipTask(index=8, clip=str(tmp_path / "none.mp4"), rig=str(rig), rig_sha256="shipped",
                           outputs={"glb": str(tmp_path / "none.glb")}, config=config)
            failed = list(actor.run(bad, [None]))                     # the rig kept: not fetched again
        finally:
            cv2.setNumThreads(before)
    *counts, result = items
    assert all(isinstance(c, int) and c > 0 for c in counts) and sum(counts) == 40
    assert result.ok and result.index == 7 and result.frames == 40, result.error
    assert (tmp_path / "out.glb").read_bytes() == (tmp_path / "ref.glb").read_bytes()
    assert len(failed) == 1 and not failed[0].ok and "none.mp4" in failed[0].error
    assert not (tmp_path / "none.glb").exists()


def test_clips_are_handed_out_longest_first():
    from facepuppet.batch.run import longest_first

    tasks = [ClipTask(index=i, clip=f"{i}.mp4", rig="r", rig_sha256="r", outputs={}, config=AnimateConfig())
             for i in range(5)]
    frames = {0: 354, 1: 1008, 2: 216, 3: 354, 4: 0}
    assert [t.index for t in longest_first(tasks, frames)] == [1, 0, 3, 2, 4]        # ties in job order
