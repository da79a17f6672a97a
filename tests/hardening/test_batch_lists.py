"""A batch list's clips, rigs and output names are checked as every command's file arguments are."""

from __future__ import annotations

import os

import pytest

from hardening.hardening_cases import run_refused


@pytest.fixture
def batch_dir(tmp_path, world):
    import shutil

    out = tmp_path / "out"
    out.mkdir()
    shutil.copy(world.video, tmp_path / "a.mp4")
    return tmp_path


def _batch(folder, listing: str, *extra, name="list.csv"):
    path = folder / name
    path.write_text(listing, encoding="utf-8")
    return ["batch", "--list", path, "-o", folder / "out", "--no-progress", "--workers", "1", *extra]


def test_list_clip_that_is_a_fifo(capsys, world, batch_dir):
    os.mkfifo(batch_dir / "f.mp4")
    run_refused(capsys, _batch(batch_dir, "clip,output\na.mp4,x\nf.mp4,y\n", "--rig", world.rig), world,
                folders=[batch_dir], names=["list.csv:3", "f.mp4", "FIFO"])


def test_list_rig_that_is_a_fifo(capsys, world, batch_dir):
    os.mkfifo(batch_dir / "r.npz")
    run_refused(capsys, _batch(batch_dir, "clip,rig\na.mp4,r.npz\n"), world, folders=[batch_dir],
                names=["list.csv:2", "r.npz"])


def test_list_output_that_is_its_own_clip(capsys, world, batch_dir):
    import shutil

    shutil.copy(world.video, batch_dir / "out" / "a.mp4")
    run_refused(capsys, _batch(batch_dir, "clip\nout/a.mp4\n", "--rig", world.rig, "--preview"), world,
                folders=[batch_dir], names=["list.csv:2", "a.mp4"])


def test_list_output_hard_link_to_a_clip(capsys, world, batch_dir):
    os.link(batch_dir / "a.mp4", batch_dir / "out" / "x.mp4")
    run_refused(capsys, _batch(batch_dir, "clip,output\na.mp4,x\n", "--rig", world.rig, "--preview"), world,
                folders=[batch_dir], names=["list.csv:2", "x.mp4"])


def test_list_output_that_is_the_list(capsys, world, batch_dir):
    args = _batch(batch_dir / "out", "clip,output\n../a.mp4,l\n", "--rig", world.rig, "--csv", name="l.csv")
    args[args.index("-o") + 1] = batch_dir / "out"
    run_refused(capsys, args, world, folders=[batch_dir], names=["l.csv"])


def test_list_output_that_is_the_report(capsys, world, batch_dir):
    run_refused(capsys, _batch(batch_dir, "clip,output\na.mp4,report\n", "--rig", world.rig, "--csv"), world,
                folders=[batch_dir], names=["report.csv"])


def test_list_output_that_is_the_rig(capsys, world, batch_dir):
    import shutil

    shutil.copy(world.rig, batch_dir / "out" / "r.csv")   # a rig whose name ends in .csv
    run_refused(capsys, _batch(batch_dir, "clip,rig,output\na.mp4,out/r.csv,r\n", "--csv"), world,
                folders=[batch_dir], names=["list.csv:2", "r.csv"])


@pytest.mark.parametrize("name", ["../evil", "sub/x", "..", "/abs/x"])
def test_list_output_outside_the_folder(capsys, world, batch_dir, name):
    run_refused(capsys, _batch(batch_dir, f"clip,output\na.mp4,{name}\n", "--rig", world.rig), world,
                folders=[batch_dir], names=["list.csv:2"])


def test_list_output_that_is_a_folder(capsys, world, batch_dir):
    (batch_dir / "out" / "x.glb").mkdir()
    run_refused(capsys, _batch(batch_dir, "clip,output\na.mp4,x\n", "--rig", world.rig), world,
                folders=[batch_dir], names=["list.csv:2", "x.glb", "folder"])


def test_list_output_that_is_a_link_to_a_device(capsys, world, batch_dir):
    os.symlink("/dev/null", batch_dir / "out" / "x.glb")
    run_refused(capsys, _batch(batch_dir, "clip,output\na.mp4,x\n", "--rig", world.rig), world,
                folders=[batch_dir], names=["list.csv:2", "x.glb"])


def test_list_that_is_not_utf8(capsys, world, batch_dir):
    path = batch_dir / "list.csv"
    path.write_bytes(b"clip\n\xff\xfe.mp4\n")
    run_refused(capsys, ["batch", "--list", path, "-o", batch_dir / "out", "--rig", world.rig, "--no-progress"],
                world, folders=[batch_dir], names=["list.csv"])


def test_list_that_is_a_folder(capsys, world, batch_dir):
    run_refused(capsys, ["batch", "--list", batch_dir, "-o", batch_dir / "out", "--rig", world.rig,
                         "--no-progress"], world, folders=[batch_dir], names=["--list"])


def test_clip_argument_that_is_a_fifo(capsys, world, batch_dir):
    os.mkfifo(batch_dir / "f.mp4")
    run_refused(capsys, ["batch", batch_dir / "f.mp4", "-o", batch_dir / "out", "--rig", world.rig,
                         "--no-progress"], world, folders=[batch_dir], names=["argument 1", "f.mp4"])
