"""Fixtures of the hardening corpus (see hardening_cases.py)."""

from __future__ import annotations

import subprocess
from dataclasses import replace

import numpy as np
import pytest

from hardening.hardening_cases import World, make_track, write_video


@pytest.fixture(scope="session")
def world(tmp_path_factory) -> World:
    from facepuppet.capture import POINT_NAMES
    from facepuppet.demo.toy import toy_character
    from facepuppet.io.character import save_character
    from facepuppet.io.performer import Performer, save_performer
    from facepuppet.io.track import save_track
    from facepuppet.pipeline.rig import fit_rig, save_rig

    folder = tmp_path_factory.mktemp("world")
    toy = toy_character()
    glb, objdir = folder / "toy.glb", folder / "toy_obj"
    save_character(glb, toy)
    save_character(objdir, toy)
    rng = np.random.default_rng(0)
    p = len(POINT_NAMES)
    neutral = rng.normal(0, 3, (p, 3))
    examples = neutral[None] + rng.normal(0, 0.5, (len(toy.names), p, 3))
    performer = Performer(neutral, examples, tuple(toy.names), tuple(POINT_NAMES), backend="color")
    save_performer(folder / "performer.npz", performer)
    rig, _ = fit_rig(performer, toy)
    save_rig(folder / "rig.npz", rig)
    save_rig(folder / "rig_mp.npz", replace(rig, backend="mediapipe"))
    write_video(folder / "video.mp4", 1)
    write_video(folder / "video2.mp4", 2)
    save_track(folder / "track.npz", make_track(performer, folder / "video.mp4"))
    (folder / "marks.csv").write_text("0,neutral\n5," + toy.names[0] + "\n", encoding="utf-8")
    return World(folder, glb, objdir, folder / "performer.npz", folder / "rig.npz", folder / "rig_mp.npz",
                 folder / "video.mp4", folder / "video2.mp4", folder / "track.npz", folder / "marks.csv")


@pytest.fixture
def small_disk(tmp_path):
    """A 64 KiB tmpfs (a full disk after a few writes); skipped where mounting is not allowed."""
    folder = tmp_path / "small"
    folder.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(folder)], capture_output=True)
    if r.returncode != 0:
        pytest.skip("cannot mount a tmpfs here (needs root)")
    try:
        yield folder
    finally:
        subprocess.run(["umount", str(folder)], capture_output=True)


@pytest.fixture
def read_only(tmp_path):
    """A read-only bind mount of an empty folder; skipped where mounting is not allowed."""
    src, folder = tmp_path / "ro_src", tmp_path / "ro"
    src.mkdir()
    folder.mkdir()
    r = subprocess.run(["mount", "--bind", str(src), str(folder)], capture_output=True)
    if r.returncode != 0:
        pytest.skip("cannot bind-mount here (needs root)")
    subprocess.run(["mount", "-o", "remount,ro,bind", str(folder)], capture_output=True)
    try:
        yield folder
    finally:
        subprocess.run(["umount", str(folder)], capture_output=True)
