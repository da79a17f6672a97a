"""Crashes and hangs: names OpenCV cannot take, FIFOs, every kind of OSError, damaged GLBs, huge requests."""

import errno
import json
import os
import threading

import pytest

from hardening.hardening_cases import animate_args, assert_one_line, run_refused, run_subprocess, snapshot


def _bad_name(folder, suffix):
    return os.fsdecode(os.path.join(os.fsencode(folder), b"\xff\xfe" + suffix.encode()))


def test_media_name_not_utf8(capsys, world, tmp_path):
    media = _bad_name(tmp_path, ".mp4")
    with open(media, "wb") as f:
        f.write(world.video.read_bytes())
    run_refused(capsys, ["track", media, "-o", tmp_path / "t.npz", "--no-progress"], world, folders=[tmp_path],
                names=["MEDIA", "UTF-8"])


def test_preview_name_not_utf8(capsys, world, tmp_path):
    run_refused(capsys, [*animate_args(world), "--preview", _bad_name(tmp_path, ".mp4")], world,
                folders=[tmp_path], names=["--preview", "UTF-8"])


def test_empty_path(capsys, world, tmp_path):
    run_refused(capsys, [*animate_args(world), "-o", ""], world, folders=[tmp_path], names=["-o", "empty path"])
    run_refused(capsys, ["animate", world.video, "--rig", "", "-o", tmp_path / "a.glb"], world,
                folders=[tmp_path], names=["--rig", "empty path"])


@pytest.mark.parametrize("which", ["media", "marks"])
def test_fifo_input_does_not_block(world, tmp_path, which):
    fifo = tmp_path / ("in.mp4" if which == "media" else "marks.csv")
    os.mkfifo(fifo)
    argv = ["calibrate", fifo if which == "media" else world.video, "--marks",
            fifo if which == "marks" else world.marks, "-o", tmp_path / "e.npz"]
    r = run_subprocess(argv, timeout=60)
    assert r.returncode == 1
    assert_one_line(r.stderr.decode(), "FIFO")
    assert not (tmp_path / "e.npz").exists()


def test_disk_full(capsys, world, small_disk):
    run_refused(capsys, [*animate_args(world), "-o", small_disk / "a.glb", "--csv", small_disk / "a.csv"],
                world, folders=[small_disk], names=["No space left on device"])
    assert list(small_disk.iterdir()) == []


def test_disk_full_during_the_preview(capsys, world, small_disk, tmp_path):
    """OpenCV's writer says nothing when the disk fills: the preview is read back and the run refused."""
    filler = small_disk / "filler"
    filler.write_bytes(bytes(56 * 1024))      # a few kB left: the preview's first frames fill it
    run_refused(capsys, [*animate_args(world), "-o", tmp_path / "a.glb", "--preview", small_disk / "p.mp4"],
                world, folders=[small_disk, tmp_path], names=["p.mp4"])
    assert list(small_disk.iterdir()) == [filler] and list(tmp_path.glob("*.glb")) == []


def test_disk_full_simulated(capsys, world, tmp_path, monkeypatch):
    """Where no tmpfs can be mounted: the write itself raises ENOSPC."""
    import facepuppet.export.gltf_animation as ga

    def full(*a, **k):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(tmp_path / "a.glb"))

    monkeypatch.setattr(ga, "write_animated_glb", full)
    run_refused(capsys, [*animate_args(world), "-o", tmp_path / "a.glb"], world, folders=[tmp_path],
                names=["a.glb", "disk full"])


def test_read_only_folder(capsys, world, read_only):
    run_refused(capsys, ["rig", "--performer", world.performer, "--character", world.glb, "-o",
                         read_only / "r.npz"], world, folders=[read_only], names=["-o", "not writable"])


def test_name_too_long_once_the_temporary_prefix_is_added(capsys, world, tmp_path):
    name = "r" * 245 + ".npz"   # fits the 255-byte limit; the temporary name does not
    run_refused(capsys, ["rig", "--performer", world.performer, "--character", world.glb, "-o", tmp_path / name],
                world, folders=[tmp_path], names=["-o", "too long"])


def test_broken_pipe_on_the_summary_line(world, tmp_path):
    read, write = os.pipe()
    os.close(read)
    try:
        r = run_subprocess(["rig", "--performer", world.performer, "--character", world.glb, "-o",
                            tmp_path / "r.npz"], stdout=write)
    finally:
        os.close(write)
    assert r.returncode == 1
    assert_one_line(r.stderr.decode(), "broken pipe")


def _damaged_glb(tmp_path, change):
    from facepuppet.demo.toy import toy_character
    from facepuppet.io.gltf import write_glb

    path = tmp_path / "c.gltf"
    write_glb(path, toy_character())
    doc = json.loads(path.read_text())
    change(doc)
    path.write_text(json.dumps(doc))
    return path


@pytest.mark.parametrize("change", [
    lambda d: d["meshes"][0]["primitives"][0]["targets"][0].update(POSITION=999),
    lambda d: d["meshes"][0]["primitives"][0]["attributes"].update(POSITION=-1),
    lambda d: d["accessors"][0].update(bufferView=77),
    lambda d: d["bufferViews"][0].update(buffer=5),
    lambda d: d["accessors"][0].update(count=10**12),
    lambda d: d["nodes"][0].update(mesh=42),
], ids=["target", "negative", "view", "buffer", "count", "node"])
def test_glb_index_to_nothing(capsys, world, tmp_path, change):
    path = _damaged_glb(tmp_path, change)
    run_refused(capsys, ["rig", "--performer", world.performer, "--character", path, "-o", tmp_path / "r.npz"],
                world, folders=[tmp_path], names=["c.gltf"])


@pytest.mark.parametrize("seconds", ["1e9", "nan", "inf", "-5"])
def test_demo_seconds_out_of_bounds(capsys, world, tmp_path, seconds):
    run_refused(capsys, ["demo", "-o", tmp_path / "d", "--seconds", seconds, "--no-progress"], world,
                folders=[tmp_path], names=["--seconds"])
    assert not (tmp_path / "d").exists()


def test_memory_error_is_one_line(capsys, world, tmp_path, monkeypatch):
    import facepuppet.pipeline.rig as rig_module

    def no_memory(*a, **k):
        raise MemoryError

    monkeypatch.setattr(rig_module, "fit_rig", no_memory)
    run_refused(capsys, ["rig", "--performer", world.performer, "--character", world.glb, "-o",
                         tmp_path / "r.npz"], world, folders=[tmp_path], names=["out of memory"])


def test_no_hang_on_a_fifo_given_as_a_track_to_the_library(tmp_path):
    """Below the CLI too: the npz reader refuses a FIFO instead of opening it."""
    from facepuppet.errors import FacepuppetError
    from facepuppet.io.track import load_track

    fifo = tmp_path / "t.npz"
    os.mkfifo(fifo)
    done = []

    def read():
        try:
            load_track(fifo)
        except FacepuppetError as e:
            done.append(str(e))

    t = threading.Thread(target=read, daemon=True)
    t.start()
    t.join(10)
    assert done and "not a regular file" in done[0]
    assert snapshot([tmp_path]) == {fifo: "special"}


def test_fifo_inside_an_obj_character_folder(capsys, world, tmp_path):
    import shutil

    folder = tmp_path / "obj"
    shutil.copytree(world.objdir, folder)
    os.mkfifo(folder / "zzz.obj")
    run_refused(capsys, ["rig", "--performer", world.performer, "--character", folder, "-o", tmp_path / "r.npz"],
                world, folders=[tmp_path], names=["--character", "zzz.obj", "FIFO"])
