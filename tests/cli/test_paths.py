"""check_paths: every output against every input and each other, as files; special files refused."""

import os

import pytest

from facepuppet.cli._paths import TEMP_NAME_EXTRA, check_paths
from facepuppet.errors import FacepuppetError


@pytest.fixture
def files(tmp_path):
    a = tmp_path / "a.mp4"
    a.write_bytes(b"video")
    return tmp_path, a


def test_distinct_files_pass(files):
    folder, a = files
    check_paths({"MEDIA": str(a)}, {"-o": str(folder / "out.glb"), "--csv": str(folder / "out.csv")})


@pytest.mark.parametrize("make", [
    lambda f, a: str(a),                                          # same name
    lambda f, a: str(f / "." / "a.mp4"),                          # same resolved path
    lambda f, a: (os.link(a, f / "h.glb"), str(f / "h.glb"))[1],  # hard link
    lambda f, a: ((f / "s.glb").symlink_to(a), str(f / "s.glb"))[1],   # symbolic link
], ids=["name", "resolved", "hard-link", "symlink"])
def test_output_that_is_the_input(files, make):
    folder, a = files
    with pytest.raises(FacepuppetError, match="-o .*the same file as the input MEDIA"):
        check_paths({"MEDIA": str(a)}, {"-o": make(folder, a)})


def test_two_outputs_one_file_not_yet_existing(files):
    folder, a = files
    with pytest.raises(FacepuppetError, match="--csv .* same file as -o"):
        check_paths({"MEDIA": str(a)}, {"-o": str(folder / "x.glb"), "--csv": str(folder / "x.glb")})


def test_special_files(files):
    folder, a = files
    fifo = folder / "f"
    os.mkfifo(fifo)
    with pytest.raises(FacepuppetError, match="MEDIA .*FIFO"):
        check_paths({"MEDIA": str(fifo)}, {})
    with pytest.raises(FacepuppetError, match="-o .*FIFO"):
        check_paths({}, {"-o": str(fifo)})
    with pytest.raises(FacepuppetError, match="-o /dev/null: is a character device"):
        check_paths({}, {"-o": "/dev/null"})
    with pytest.raises(FacepuppetError, match="--rig /dev/zero: is a character device"):
        check_paths({"--rig": "/dev/zero"}, {})
    link = folder / "l"
    link.symlink_to("/dev/stderr")
    with pytest.raises(FacepuppetError, match="symbolic link to /dev/stderr"):
        check_paths({}, {"-o": str(link)})


def test_names(files):
    folder, a = files
    with pytest.raises(FacepuppetError, match="-o: empty path"):
        check_paths({}, {"-o": ""})
    bad = os.fsdecode(os.fsencode(str(folder)) + b"/\xff.mp4")
    with pytest.raises(FacepuppetError, match=r"MEDIA .*\\udcff.mp4: the name is not valid UTF-8"):
        check_paths({"MEDIA": bad}, {})
    longest = "x" * (255 - TEMP_NAME_EXTRA)
    check_paths({}, {"-o": str(folder / longest)})
    with pytest.raises(FacepuppetError, match="too long"):
        check_paths({}, {"-o": str(folder / (longest + "x"))})


def test_cameras_and_unset_options_are_skipped(files):
    folder, a = files
    check_paths({"MEDIA": "camera:0", "--track": None}, {"-o": str(folder / "x.glb"), "--csv": None})


def test_folder_output(files):
    folder, a = files
    check_paths({}, {"-o": str(folder / "new")}, folder_outputs=["-o"])
    check_paths({}, {"-o": str(folder)}, folder_outputs=["-o"])
    with pytest.raises(FacepuppetError, match="not a folder"):
        check_paths({}, {"-o": str(a)}, folder_outputs=["-o"])


def test_output_inside_an_input_folder(files):
    folder, a = files
    with pytest.raises(FacepuppetError, match="in folder"):
        check_paths({"--character": str(folder)}, {"-o": str(a)})


def test_every_command_declares_its_files():
    """A new subcommand must say which arguments it reads and writes, or the checks would pass it by."""
    import argparse

    from facepuppet.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for name, p in sub.choices.items():
        inputs, outputs = p.get_default("inputs"), p.get_default("outputs")
        assert inputs is not None and outputs is not None, name
        dests = {a.dest for a in p._actions}
        for dest, _label in (*inputs, *outputs):
            assert dest in dests, (name, dest)
        file_like = {a.dest for a in p._actions if a.metavar and any(
            x in str(a.metavar) for x in (".npz", ".glb", ".csv", ".mp4", ".json", "MEDIA", "SOURCE", "TASK"))}
        declared = {d for d, _ in (*inputs, *outputs)}
        assert file_like <= declared, (name, file_like - declared)
