"""Compiling the colour tracker's kernels ahead of use: after precompile, tracking compiles nothing."""

import json
import os
import subprocess
import sys
import textwrap

import pytest

from facepuppet.capture.color.precompile import TASKS, precompile, run_task

#: Tracks frames of the digital performer with the generic profile (snakes and every rule) and with a profile
#: carrying an eyelid model and shape models, then prints every kernel that had to be compiled or that was
#: loaded for more than one set of argument types.
_TRACK = textwrap.dedent("""
    import importlib, json, pkgutil
    import numba
    import numpy as np
    import facepuppet
    from facepuppet.capture.color.config import ColorTrackerConfig, LandmarkConfig
    from facepuppet.capture.color.tracker import ColorTracker
    from facepuppet.capture.color.lids import PATCH_SIZE
    from facepuppet.capture.color.profile import Profile
    from facepuppet.capture.color.shape_models import FAMILIES, PATCH_SIZE as SHAPE_PATCH
    from facepuppet.demo.performer import render_performer
    from facepuppet.demo.script import calibration_script

    frames, _ = render_performer(calibration_script(hold=0.3, transition=0.1), size=(256, 256))
    n_in = SHAPE_PATCH[0] * SHAPE_PATCH[1] * 3
    shapes = {f: {"coef": np.zeros((8 * len(i), n_in)), "intercept": np.linspace(0.1, 0.9, 8 * len(i))}
              for f, i in FAMILIES.items()}
    lids = {"coef": np.zeros((2, PATCH_SIZE[0] * PATCH_SIZE[1])), "intercept": np.zeros(2)}
    options = ColorTrackerConfig(landmarks=LandmarkConfig(enabled=False))
    for profile in (None, Profile(shapes=shapes, lids=lids)):
        tracker = ColorTracker(profile, config=options)
        assert sum(tracker.track(f, 33 * k).valid for k, f in enumerate(frames[:30])) > 20
    compiled, several = [], []
    for m in pkgutil.walk_packages(facepuppet.__path__, "facepuppet."):
        if m.name.endswith("__main__"):
            continue
        for name, obj in vars(importlib.import_module(m.name)).items():
            if isinstance(obj, numba.core.registry.CPUDispatcher) and obj.__module__ == m.name:
                if sum(obj.stats.cache_misses.values()):
                    compiled.append(f"{m.name}.{name}")
                if len(obj.signatures) > 1:
                    several.append(f"{m.name}.{name}")
    print(json.dumps({"compiled": compiled, "several": several}))
""")


def _run(code: str, cache: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "NUMBA_CACHE_DIR": cache}
    env.pop("FACEPUPPET_FACE_LANDMARKER", None)
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=900)


def test_after_precompile_the_tracker_compiles_nothing(tmp_path):
    """Two workers compile every task into an empty cache; a fresh process then tracks with the generic
    profile and with one that has an eyelid model and shape models, loading each kernel it calls (for one set
    of argument types) and compiling none."""
    cache = str(tmp_path / "numba-cache")
    done = _run("from facepuppet.capture.color.precompile import precompile\n"
                "import json; print(json.dumps(precompile(workers=2).wait()))", cache)
    assert done.returncode == 0, done.stderr[-2000:]
    took = json.loads(done.stdout.strip().splitlines()[-1])
    assert set(took) == set(TASKS)
    assert all(isinstance(v, float) for v in took.values()), took
    tracked = _run(_TRACK, cache)
    assert tracked.returncode == 0, tracked.stderr[-2000:]
    got = json.loads(tracked.stdout.strip().splitlines()[-1])
    assert got == {"compiled": [], "several": []}


def test_precompile_checks_its_tasks_and_runs_nothing_on_one_worker():
    with pytest.raises(ValueError, match=r"unknown precompile tasks \['nose'\]"):
        precompile(tasks=("eyes", "nose"))
    with pytest.raises(ValueError, match="unknown precompile task 'nose'"):
        run_task("nose")
    assert precompile(workers=1).wait() == {}


def test_a_worker_that_fails_is_reported_not_raised(monkeypatch):
    """A worker that cannot run (here: no interpreter) leaves its tasks to the caller, with the reason."""
    import facepuppet.capture.color.precompile as pc

    monkeypatch.setattr(pc.sys, "executable", "false")
    job = pc.precompile(tasks=("eyes", "frame"), workers=2)
    assert job.wait() == {"eyes": "worker exited with 1", "frame": "worker exited with 1"}
    pc.wait_pending()                                   # nothing left pending
    from facepuppet.capture.color import jobs

    assert jobs.pending() == ()
