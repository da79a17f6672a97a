"""Batch plans: list files, output names, content hashes, the report and what a rerun skips."""

from __future__ import annotations

from pathlib import Path

import pytest

from facepuppet.batch.jobs import check_unique, file_sha256, jobs_from_clips, options_sha256, read_list
from facepuppet.batch.report import Row, can_skip, read_report, write_report
from facepuppet.pipeline.animate import AnimateConfig
from facepuppet.pipeline.gain import GainConfig
from facepuppet.pipeline.tracking import TrackerOptions


def write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def test_list_with_header_resolves_paths_from_its_folder(tmp_path):
    lst = write(tmp_path / "takes.csv", "output,clip,rig\n\n# a comment\nfirst,a.mp4,r1.npz\n,sub/b.mp4,\n")
    jobs = read_list(lst, rig="/rigs/main.npz")
    assert [(j.clip, j.rig, j.name) for j in jobs] == [
        (str(tmp_path / "a.mp4"), str(tmp_path / "r1.npz"), "first"),
        (str(tmp_path / "sub" / "b.mp4"), "/rigs/main.npz", "b")]
    assert jobs[1].source == f"{lst}:5"


def test_list_without_header_is_positional(tmp_path):
    lst = write(tmp_path / "l.csv", "a.mp4\nb.mp4,other.npz,bee.glb\n")
    jobs = read_list(lst, rig="r.npz")
    assert [(Path(j.clip).name, Path(j.rig).name, j.name) for j in jobs] == [
        ("a.mp4", "r.npz", "a"), ("b.mp4", "other.npz", "bee")]


@pytest.mark.parametrize("text, rig, message", [
    ("clip,rig\na.mp4,r.npz\nb.mp4,r.npz,x\n", None, ":3: 3 cells"),
    ("a.mp4\n", None, ":1: no rig in the row and no --rig"),
    ("clip,take\na.mp4\n", "r.npz", ":1: unknown column 'take'"),
    ("clip,rig,output\na.mp4,r.npz,../up\n", None, ":2: output name '../up'"),
    ("clip,rig\n,r.npz\n", None, ":2: no clip"),
    ("camera:0\n", "r.npz", ":1: camera:0 is a camera"),
    ("# nothing\n", "r.npz", "no clips in the list"),
])
def test_list_errors_name_the_line(tmp_path, text, rig, message):
    lst = write(tmp_path / "l.csv", text)
    with pytest.raises(ValueError, match=message.replace("(", r"\(")) as e:
        read_list(lst, rig=rig)
    assert str(lst) in str(e.value)


def test_same_stem_twice_is_an_error_naming_both():
    jobs = jobs_from_clips(["day1/take.mp4", "day2/take.mov", "other.mp4"], "r.npz")
    with pytest.raises(ValueError, match=r"argument 2 \(day2/take.mov\) and argument 1 \(day1/take.mp4\)"):
        check_unique(jobs)
    check_unique(jobs[1:])


def test_clips_need_a_rig():
    with pytest.raises(ValueError, match="--rig"):
        jobs_from_clips(["a.mp4"], None)


def test_hashes_follow_content_not_names(tmp_path):
    a = write(tmp_path / "a.bin", "same")
    b = write(tmp_path / "b.bin", "same")
    c = write(tmp_path / "c.bin", "other")
    assert file_sha256(a) == file_sha256(b) != file_sha256(c)
    # sha256 of the bytes "same" (known answer)
    assert file_sha256(a) == "0967115f2813a3541eaef77de9d9d5773f1c0c04314b0bbfe4ff3b3b1c55b5d5"
    base = options_sha256(AnimateConfig(), csv=False, preview=False)
    assert base == options_sha256(AnimateConfig(tracker=TrackerOptions(progress=False)), csv=False, preview=False)
    assert base != options_sha256(AnimateConfig(gain=GainConfig(gain=1.2)), csv=False, preview=False)
    assert base != options_sha256(AnimateConfig(), csv=True, preview=False)
    p1, p2 = write(tmp_path / "p1.npz", "x"), write(tmp_path / "p2.npz", "y")
    same1 = options_sha256(AnimateConfig(tracker=TrackerOptions(profile=str(p1))), csv=False, preview=False)
    write(tmp_path / "p3.npz", "x")
    same3 = options_sha256(AnimateConfig(tracker=TrackerOptions(profile=str(tmp_path / "p3.npz"))), csv=False,
                           preview=False)
    other = options_sha256(AnimateConfig(tracker=TrackerOptions(profile=str(p2))), csv=False, preview=False)
    assert same1 == same3 != other


def test_report_round_trip_and_skip_rules(tmp_path):
    out = write(tmp_path / "a.glb", "glb")
    done = Row(clip="a.mp4", output="a", rig="r.npz", status="done", frames=40, frames_with_face=38,
               seconds=1.25, clip_sha256="c", rig_sha256="r", options_sha256="o")
    failed = Row(clip="b.mp4", output="b", rig="r.npz", status="failed", error="b.mp4: cannot open video")
    write_report(tmp_path / "report.csv", [done, failed])
    back = read_report(tmp_path / "report.csv")
    assert back == {"a": done, "b": failed}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.glb", "report.csv"]     # no temporary left
    hashes = dict(clip_sha256="c", rig_sha256="r", options_sha256="o")
    skipped = can_skip(back["a"], outputs=[out], **hashes)
    assert skipped is not None and skipped.status == "skipped" and skipped.frames == 40
    assert can_skip(back["a"], outputs=[out, tmp_path / "a.csv"], **hashes) is None
    assert can_skip(back["a"], outputs=[out], **{**hashes, "rig_sha256": "new"}) is None
    assert can_skip(back["b"], outputs=[out], **hashes) is None
    assert can_skip(None, outputs=[out], **hashes) is None
    write(tmp_path / "report.csv", "\x00\xff not a report")
    assert read_report(tmp_path / "report.csv") == {}
