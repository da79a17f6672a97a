"""Signals: SIGINT, SIGTERM and SIGHUP stop every command cleanly (exit 128 + N, one line, nothing left)."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from hardening.hardening_cases import ROOT, assert_one_line, make_track, snapshot, write_video

#: Seconds to wait for a command to reach its frame loop, and for it to end after the signal.
REACH, END = 60.0, 30.0


def _start(argv) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    return subprocess.Popen([sys.executable, "-m", "facepuppet", *map(str, argv)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, env=env)


def _wait_for(proc, condition, timeout=REACH) -> None:
    t0 = time.monotonic()
    while not condition():
        if proc.poll() is not None:
            pytest.fail(f"ended before the signal: {proc.stderr.read().decode()}")
        if time.monotonic() - t0 > timeout:
            proc.kill()
            pytest.fail("never reached the point to interrupt")
        time.sleep(0.05)


def _grown(folder: Path, pattern: str) -> bool:
    """A file matching ``pattern`` holds data: the command's frame loop is running."""
    for p in folder.glob(pattern):
        try:
            if p.stat().st_size > 0:
                return True
        except OSError:
            pass
    return False


def _children(pid: int) -> list[int]:
    out = []
    for f in Path(f"/proc/{pid}/task").glob("*/children"):
        try:
            out += [int(x) for x in f.read_text().split()]
        except OSError:
            pass
    return out


@pytest.fixture(scope="module")
def long_take(world, tmp_path_factory):
    """A 1500-frame video and its track: animate with --preview runs long enough to be interrupted."""
    from facepuppet.io.performer import load_performer
    from facepuppet.io.track import save_track

    folder = tmp_path_factory.mktemp("long")
    video = folder / "long.mp4"
    write_video(video, 3, n=1500)
    track = folder / "long.npz"
    save_track(track, make_track(load_performer(world.performer), video, n=1500))
    return video, track


@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143), (signal.SIGHUP, 129)])
def test_animate_interrupted_during_the_preview(world, long_take, tmp_path, sig, code):
    video, track = long_take
    inputs = snapshot([world.folder, video.parent])
    proc = _start(["animate", video, "--rig", world.rig, "--track", track, "-o", tmp_path / "a.glb", "--csv",
                   tmp_path / "a.csv", "--preview", tmp_path / "p.mp4", "--no-progress"])
    _wait_for(proc, lambda: any(tmp_path.glob(".p.mp4.*")))
    time.sleep(0.5)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=END)
    assert proc.returncode == code, err.decode()
    assert_one_line(err.decode(), "interrupted")
    assert list(tmp_path.iterdir()) == []
    assert snapshot([world.folder, video.parent]) == inputs


@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_track_interrupted(world, long_take, tmp_path, sig, code):
    video, _ = long_take
    proc = _start(["track", video, "-o", tmp_path / "t.npz", "--preview", tmp_path / "o.mp4", "--no-progress"])
    _wait_for(proc, lambda: _grown(tmp_path, ".o.mp4.*"), timeout=180)   # frames pass (kernels compiled)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=END)
    assert proc.returncode == code, err.decode()
    assert "SystemError" not in err.decode()
    assert_one_line(err.decode(), "interrupted")
    assert list(tmp_path.iterdir()) == []


def test_sigint_inside_the_colour_trackers_kernels(assets, tmp_path):
    """Repeated SIGINTs while the colour tracker's numba kernels run: never a SystemError, always exit 130."""
    video = assets / "video" / "performer_a.mp4"
    for delay in (0.3,):
        proc = _start(["track", video, "-o", tmp_path / "t.npz", "--preview", tmp_path / "o.mp4", "--no-progress"])
        _wait_for(proc, lambda: _grown(tmp_path, ".o.mp4.*"), timeout=180)
        time.sleep(delay)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=4 * END)   # a frame of a real face under a loaded machine
        text = err.decode()
        assert proc.returncode == 130, text
        assert "SystemError" not in text and "Traceback" not in text
        assert list(tmp_path.iterdir()) == []


def test_demo_interrupted_leaves_nothing(tmp_path):
    out = tmp_path / "demo"
    proc = _start(["demo", "-o", out, "--seconds", "5", "--no-progress", "--no-preview"])
    _wait_for(proc, lambda: out.is_dir(), timeout=120)
    seen: set[int] = set()
    t0 = time.monotonic()
    while time.monotonic() - t0 < 1.0:
        seen.update(_children(proc.pid))
        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=END)
    assert proc.returncode == 143, err.decode()
    assert_one_line(err.decode(), "interrupted")
    assert not out.exists()
    alive = [pid for pid in seen if Path(f"/proc/{pid}").exists()
             and "precompile" in Path(f"/proc/{pid}/cmdline").read_bytes().decode(errors="replace")]
    assert alive == []
