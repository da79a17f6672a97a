"""facepuppet live: the paced source, the session's stops, and its outputs equal to animate's."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from facepuppet.cli import main
from facepuppet.errors import FacepuppetError
from facepuppet.live.source import LiveSource

ROOT = Path(__file__).resolve().parents[2]


class FakeSource:
    """A MediaSource stand-in: ``n`` tiny frames (frame k filled with k), at ``fps``."""

    def __init__(self, n, fps=200.0, camera=False, path="fake.mp4"):
        self.n, self.fps, self.is_camera, self.path = n, fps, camera, path
        self.frame_size = (4, 4)

    def __iter__(self):
        return (np.full((4, 4, 3), k % 256, np.uint8) for k in range(self.n))


def test_fast_pace_hands_on_every_frame_in_order():
    live = LiveSource(FakeSource(25), pace="fast")
    frames = list(live)
    assert [f.index for f in frames] == list(range(25)) and live.dropped == 0
    assert [f.time for f in frames] == pytest.approx([k / 200.0 for k in range(25)])


def test_fast_pace_stops_at_max_frames():
    assert [f.index for f in LiveSource(FakeSource(25), pace="fast", max_frames=7)] == list(range(7))


def test_realtime_pace_drops_what_a_slow_stream_cannot_take():
    live = LiveSource(FakeSource(40, fps=200.0), pace="realtime")
    got = []
    for f in live:
        got.append(f.index)
        time.sleep(3 / 200.0)                 # the stream takes three frame periods per frame
    assert got == sorted(got) and len(set(got)) == len(got)
    assert live.read == 40 and live.dropped == 40 - len(got)
    # about a third reach the stream (how many depends on how late the two threads' sleeps run on a busy
    # machine: each late sleep makes the stream take fewer), far fewer than all
    assert 2 <= len(got) <= 30
    assert got[-1] >= 37                      # the last frame read is not lost behind older ones


def test_realtime_pace_keeps_up_with_a_fast_stream():
    # a frame period of 40 ms: a consumer that does nothing takes each frame long before the next is due, even
    # on a busy machine whose threads wake a few milliseconds late
    live = LiveSource(FakeSource(15, fps=25.0), pace="realtime")
    t0 = time.perf_counter()
    got = [f.index for f in live]
    assert got == list(range(15)) and live.dropped == 0
    assert time.perf_counter() - t0 >= 0.5    # played at the file's own rate (15 frames at 25 fps)


def test_stop_from_another_thread_ends_the_iteration():
    live = LiveSource(FakeSource(10_000, fps=100.0), pace="realtime")
    threading.Timer(0.2, live.stop).start()
    t0 = time.perf_counter()
    n = sum(1 for _ in live)
    assert time.perf_counter() - t0 < 2.0 and 5 <= n < 100


def test_a_camera_that_stops_is_an_error():
    live = LiveSource(FakeSource(3, camera=True, path="camera:0"), pace="realtime")
    assert len(list(live)) >= 1
    assert live.error == "camera:0: the camera stopped delivering frames"


def test_bad_pace_and_max_frames_are_refused():
    with pytest.raises(ValueError, match="--pace"):
        LiveSource(FakeSource(1), pace="slow")
    with pytest.raises(ValueError, match="--max-frames"):
        LiveSource(FakeSource(1), max_frames=0)


def _live_args(demo, *extra):
    f = demo.files
    return ["live", str(f["performance.mp4"]), "--rig", str(f["rig.npz"]), "--profile",
            str(f["performer-profile.npz"]), "--no-status", *extra]


def test_live_fast_records_exactly_what_animate_writes(demo, tmp_path, capsys):
    f = demo.files
    assert main(["animate", str(f["performance.mp4"]), "--rig", str(f["rig.npz"]), "--profile",
                 str(f["performer-profile.npz"]), "-o", str(tmp_path / "a.glb"), "--csv", str(tmp_path / "a.csv"),
                 "--no-progress"]) == 0
    assert main(_live_args(demo, "--pace", "fast", "--record", str(tmp_path / "l.glb"), "--csv",
                           str(tmp_path / "l.csv"), "--stats", str(tmp_path / "s.json"))) == 0
    assert (tmp_path / "l.csv").read_bytes() == (tmp_path / "a.csv").read_bytes()
    assert (tmp_path / "l.glb").read_bytes() == (tmp_path / "a.glb").read_bytes()
    stats = json.loads((tmp_path / "s.json").read_text())
    n = sum(1 for _ in open(tmp_path / "a.csv")) - 1
    assert stats["frames"] == n and stats["dropped"] == 0
    assert 0 < stats["latency_ms"]["p50"] <= stats["latency_ms"]["p95"] <= stats["latency_ms"]["p99"] \
        <= stats["latency_ms"]["max"]
    out = capsys.readouterr().out
    assert f"live: {n} frames" in out


def test_live_refuses_bad_addresses_and_rigs_in_one_line(demo, tmp_path, capsys):
    for extra, message in ((["--vmc", "nowhere:port"], "--vmc"), (["--livelink", "70000"], "--livelink"),
                           (["--viewer", "a:b:c"], "--viewer")):
        assert main(_live_args(demo, *extra, "--csv", str(tmp_path / "x.csv"))) == 1
        err = capsys.readouterr().err.strip()
        assert message in err and len(err.splitlines()) == 1
    assert main(["live", "camera:97", "--rig", str(demo.files["rig.npz"]), "--no-status"]) == 1
    err = capsys.readouterr().err.strip()
    assert "camera:97" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "x.csv").exists()


def test_live_viewer_port_in_use_is_one_line(demo, tmp_path, capsys):
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        assert main(_live_args(demo, "--viewer", str(port), "--max-frames", "3")) == 1
    err = capsys.readouterr().err.strip()
    assert str(port) in err and len(err.splitlines()) == 1


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_ends_the_session_and_finishes_the_recording(demo, tmp_path, sig):
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src") + os.pathsep + os.environ.get("PYTHONPATH", ""))
    cmd = [sys.executable, "-m", "facepuppet", *_live_args(demo, "--record", str(tmp_path / "r.glb"), "--csv",
                                                         str(tmp_path / "r.csv"), "--stats",
                                                         str(tmp_path / "s.json"))]
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    started = threading.Event()
    err_lines: list[str] = []

    def read_stderr():
        for line in proc.stderr:
            err_lines.append(line)
            if line.startswith("live: running"):
                started.set()

    reader = threading.Thread(target=read_stderr, daemon=True)
    reader.start()
    try:
        assert started.wait(120), "".join(err_lines)          # the first frame went through
        time.sleep(0.5)                                          # half a second of the take (it lasts five)
        proc.send_signal(sig)
        out, _ = proc.communicate(timeout=60)
    finally:
        proc.kill()
    reader.join(5)
    assert proc.returncode == 0, "".join(err_lines)
    rows = sum(1 for _ in open(tmp_path / "r.csv")) - 1
    stats = json.loads((tmp_path / "s.json").read_text())
    assert 0 < rows < 150 and stats["frames"] == rows      # stopped early, every frame taken is recorded
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.csv", "r.glb", "s.json"]   # no temporary left
    assert "wrote" in out


def test_a_session_stopped_before_its_first_frame_writes_nothing(demo, tmp_path, monkeypatch):
    import facepuppet.live.session as session
    from facepuppet.live.session import LiveConfig, run_live

    class StoppedInWarmup(LiveSource):
        """Ctrl+C while the tracker warms up on the first frame."""

        def __init__(self, *args, **kwargs):
            kwargs["warmup"] = lambda rgb: self.stop()
            super().__init__(*args, **kwargs)

    monkeypatch.setattr(session, "LiveSource", StoppedInWarmup)
    result = run_live(demo.files["performance.mp4"], demo.files["rig.npz"],
                      config=LiveConfig(status=False, keys=False), record=tmp_path / "r.glb", csv=tmp_path / "r.csv")
    assert result.frames == 0 and list(tmp_path.iterdir()) == []


def test_missing_rig_is_one_line(tmp_path, capsys):
    assert main(["live", "camera:0", "--rig", str(tmp_path / "none.npz")]) == 1
    err = capsys.readouterr().err.strip()
    assert "none.npz" in err and len(err.splitlines()) == 1


def test_an_error_in_the_stream_leaves_no_recording(demo, tmp_path):
    from facepuppet.live.session import LiveConfig, run_live

    class Broken:
        def send(self, frame):
            raise FacepuppetError("receiver crashed")

        def close(self):
            pass

    with pytest.raises(FacepuppetError, match="receiver crashed"):
        run_live(demo.files["performance.mp4"], demo.files["rig.npz"], config=LiveConfig(pace="fast", status=False),
                 record=tmp_path / "r.glb", senders=[Broken()])
    assert list(tmp_path.iterdir()) == []


def test_warmup_runs_on_the_first_frame_before_the_clock_starts():
    seen = []

    def warmup(rgb):
        seen.append(int(rgb[0, 0, 0]))
        time.sleep(0.5)                          # as long as 5 frames at 10 fps

    # 100 ms a frame: a loaded machine's scheduling (tens of ms) drops none; a clock started before the warm-up
    # would have the first 5 frames due at once, and the reader keeps only the newest.
    live = LiveSource(FakeSource(20, fps=10.0), pace="realtime", warmup=warmup)
    got = [f.index for f in live]
    assert seen == [0] and got == list(range(20)) and live.dropped == 0
