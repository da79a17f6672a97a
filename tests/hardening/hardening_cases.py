"""The hardening corpus's helpers and world: small valid files of every kind, made without tracking.

``world`` holds a character (GLB and OBJ folder), a key expressions file, rigs made with two backends, two
short videos, a track of the first (recording the video it came from) and a marks file. :func:`run_refused`
runs one command line in-process and asserts the corpus's contract: exit code non-zero, exactly one line on
stderr that names the file or argument, no traceback, every input unchanged byte for byte, and no file left
behind (no output, no temporary file) in any folder it could write to.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from facepuppet.cli import main

ROOT = Path(__file__).resolve().parents[2]
N_FRAMES = 12
#: Seconds any one command may take in a subprocess before the test fails (a hang is a failure).
TIMEOUT = 60


@dataclass(frozen=True)
class World:
    folder: Path
    glb: Path
    objdir: Path
    performer: Path
    rig: Path
    rig_mediapipe: Path
    video: Path
    video2: Path
    track: Path
    marks: Path

    def files(self) -> list[Path]:
        return sorted(p for p in self.folder.rglob("*") if p.is_file())


def write_video(path: Path, seed: int, n: int = N_FRAMES) -> None:
    import cv2

    rng = np.random.default_rng(seed)
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, (64, 64))
    for _ in range(n):
        w.write(rng.integers(0, 255, (64, 64, 3), dtype=np.uint8))
    w.release()


def make_track(performer, media: Path | None, n: int = N_FRAMES, *, fps: float = 30.0, backend: str = "color"):
    from facepuppet._util.digest import media_record
    from facepuppet.capture import CURVE_NAMES
    from facepuppet.io.track import Track

    rng = np.random.default_rng(5)
    k = np.arange(n) % len(performer.examples)
    points = performer.neutral[None] + 0.5 * (performer.examples[k] - performer.neutral[None])
    points = points + rng.normal(0, 1e-3, points.shape)
    return Track(fps=fps, frame_size=np.array([64, 64]), valid=np.ones(n, bool),
                 curves=np.zeros((n, len(CURVE_NAMES), 4, 2)), curve_names=tuple(CURVE_NAMES), points=points,
                 point_names=tuple(performer.point_names), rotation=np.tile(np.eye(3), (n, 1, 1)),
                 translation=np.tile([0.0, 0.0, 50.0], (n, 1)), backend=backend,
                 media=None if media is None else media_record(media, n))


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def snapshot(folders) -> dict[Path, str]:
    """Every file under ``folders`` with its content hash (symbolic links and special files by their kind)."""
    out = {}
    for folder in folders:
        for p in Path(folder).rglob("*"):
            if p.is_symlink():
                out[p] = "link:" + os.readlink(p)
            elif p.is_file():
                out[p] = digest(p)
            elif not p.is_dir():
                out[p] = "special"
    return out


def assert_one_line(err: str, *names: str) -> str:
    assert "Traceback" not in err, err
    lines = [x for x in err.splitlines() if x.strip()]
    assert len(lines) == 1, err
    line = lines[0]
    assert "error" in line or "interrupted" in line, line
    for name in names:
        assert name in line, f"{name!r} not named in {line!r}"
    return line


def run_refused(capsys, argv, world: World, *, folders=(), names=(), code=None) -> str:
    """Run ``facepuppet ARGV`` in-process; assert the corpus's contract (module notes); return the line."""
    watched = [world.folder, *folders]
    before = snapshot(watched)
    capsys.readouterr()
    rc = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert rc != 0, (out, err)
    if code is not None:
        assert rc == code
    line = assert_one_line(err, *names)
    assert snapshot(watched) == before, "a file was changed, added or removed"
    return line


def run_subprocess(argv, *, timeout: float = TIMEOUT, **kwargs) -> subprocess.CompletedProcess:
    """Run ``python -m facepuppet ARGV`` with the worktree's sources (bounded in time; ``env`` replaces the
    environment, the sources' ``PYTHONPATH`` added)."""
    env = dict(kwargs.pop("env", None) or os.environ, PYTHONPATH=str(ROOT / "src"))
    kwargs.setdefault("stdout", subprocess.PIPE)
    return subprocess.run([sys.executable, "-m", "facepuppet", *map(str, argv)], stderr=subprocess.PIPE,
                          timeout=timeout, env=env, **kwargs)



def animate_args(world, track=None, rig=None):
    """``animate`` of the world's video with its track: no tracking, fast."""
    return ["animate", world.video, "--rig", rig or world.rig, "--track", track or world.track, "--no-progress"]
