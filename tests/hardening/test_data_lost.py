"""Data lost: an output that is an input (or another output), or not a regular file, is refused before work."""

import os

import pytest

from hardening.hardening_cases import animate_args, run_refused


def test_animate_output_is_its_media(capsys, world):
    run_refused(capsys, [*animate_args(world), "-o", world.video], world, names=["-o", "MEDIA", "video.mp4"])


def test_rig_output_is_the_character(capsys, world):
    run_refused(capsys, ["rig", "--performer", world.performer, "--character", world.glb, "-o", world.glb], world,
                names=["-o", "--character", "toy.glb"])


def test_calibrate_output_is_the_marks(capsys, world):
    run_refused(capsys, ["calibrate", world.video, "--marks", world.marks, "-o", world.marks], world,
                names=["-o", "--marks"])


def test_two_outputs_are_one_file(capsys, world, tmp_path):
    out = tmp_path / "a.glb"
    run_refused(capsys, [*animate_args(world), "-o", out, "--csv", out], world, folders=[tmp_path],
                names=["--csv", "-o", "a.glb"])


def test_two_outputs_are_one_file_through_a_folder_and_back(capsys, world, tmp_path):
    (tmp_path / "sub").mkdir()
    run_refused(capsys, [*animate_args(world), "-o", tmp_path / "a.glb", "--csv", tmp_path / "sub" / ".." / "a.glb"],
                world, folders=[tmp_path], names=["--csv"])


def test_output_is_a_hard_link_of_an_input(capsys, world, tmp_path):
    link = tmp_path / "hard.glb"
    os.link(world.rig, link)
    run_refused(capsys, [*animate_args(world), "-o", link], world, folders=[tmp_path], names=["-o", "--rig"])


def test_output_is_a_symbolic_link_to_an_input(capsys, world, tmp_path):
    link = tmp_path / "sym.glb"
    link.symlink_to(world.track)
    run_refused(capsys, [*animate_args(world), "-o", link], world, folders=[tmp_path], names=["-o", "--track"])


def test_output_is_a_file_of_an_input_folder(capsys, world):
    run_refused(capsys, ["rig", "--performer", world.performer, "--character", world.objdir, "-o",
                         world.objdir / "neutral.obj"], world, names=["-o", "--character"])


@pytest.mark.parametrize("target", ["/dev/null", "/dev/zero"])
def test_output_is_a_device(capsys, world, target):
    line = run_refused(capsys, [*animate_args(world), "-o", target], world, names=["-o", target])
    assert "device" in line
    assert not os.path.isfile(target)


def test_output_is_a_symbolic_link_to_a_device(capsys, world, tmp_path):
    link = tmp_path / "out.glb"
    link.symlink_to("/dev/stdout")
    run_refused(capsys, [*animate_args(world), "-o", link], world, folders=[tmp_path], names=["-o", "out.glb"])
    assert link.is_symlink()


def test_output_is_a_fifo(capsys, world, tmp_path):
    fifo = tmp_path / "out.glb"
    os.mkfifo(fifo)
    line = run_refused(capsys, [*animate_args(world), "-o", fifo], world, folders=[tmp_path], names=["-o"])
    assert "FIFO" in line


def test_output_is_a_folder(capsys, world, tmp_path):
    run_refused(capsys, [*animate_args(world), "-o", tmp_path], world, folders=[tmp_path], names=["-o", "folder"])


def test_output_folder_missing(capsys, world, tmp_path):
    run_refused(capsys, [*animate_args(world), "-o", tmp_path / "nope" / "a.glb"], world, folders=[tmp_path],
                names=["-o", "does not exist"])


def test_demo_into_an_existing_file(capsys, world, tmp_path):
    f = tmp_path / "file"
    f.write_text("keep me")
    run_refused(capsys, ["demo", "-o", f, "--no-progress"], world, folders=[tmp_path], names=["-o", "not a folder"])
