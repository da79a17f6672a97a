"""`facepuppet batch` end to end on clips cut from the demo's performance: the same bytes as `animate` per clip,
from the local engine and from Ray; failing clips are rows, the rest go on; a killed batch resumes."""

from __future__ import annotations

import csv
import importlib.util
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from conftest import ROOT, need
from facepuppet.cli import main

#: (first frame, frames) of the clips cut from the demo's performance video.
CUTS = {"c1": (0, 30), "c2": (40, 30), "c3": (80, 30), "c4": (110, 30)}


def cut(src: Path, dst: Path, start: int, count: int, *, black: bool = False) -> Path:
    import cv2

    cap = cv2.VideoCapture(str(src))
    fps = cap.get(cv2.CAP_PROP_FPS)
    size = (int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)))
    out = cv2.VideoWriter(str(dst), cv2.VideoWriter_fourcc(*"mp4v"), fps, size)
    k = 0
    while k < start + count:
        ok, frame = cap.read()
        if not ok:
            break
        if k >= start:
            out.write(np.zeros_like(frame) if black else frame)
        k += 1
    out.release()
    cap.release()
    return dst


@pytest.fixture(scope="module")
def clips(demo, tmp_path_factory):
    """Four good clips, a truncated file and a clip without a face; the rig and profile; `animate`'s outputs."""
    folder = tmp_path_factory.mktemp("clips")
    video = demo.files["performance.mp4"]
    good = {name: cut(video, folder / f"{name}.mp4", *c) for name, c in CUTS.items()}
    bad = folder / "broken.mp4"
    bad.write_bytes(good["c1"].read_bytes()[:3000])
    faceless = cut(video, folder / "faceless.mp4", 0, 10, black=True)
    rig, profile = demo.files["rig.npz"], demo.files["performer-profile.npz"]
    reference = tmp_path_factory.mktemp("animate")
    for name, clip in good.items():
        assert main(["animate", str(clip), "--rig", str(rig), "--profile", str(profile), "--no-progress",
                     "-o", str(reference / f"{name}.glb"), "--csv", str(reference / f"{name}.csv")]) == 0
    return {"good": good, "bad": bad, "faceless": faceless, "rig": rig, "profile": profile,
            "reference": reference}


def batch_args(clips, paths, out, *extra) -> list[str]:
    return ["batch", *map(str, paths), "--rig", str(clips["rig"]), "--profile", str(clips["profile"]),
            "-o", str(out), "--csv", "--no-progress", *extra]


def report(out: Path) -> dict[str, dict]:
    with open(out / "report.csv", newline="") as f:
        return {r["output"]: r for r in csv.DictReader(f)}


def same_as_animate(clips, out: Path, names) -> None:
    for name in names:
        for ext in ("glb", "csv"):
            assert (out / f"{name}.{ext}").read_bytes() == (clips["reference"] / f"{name}.{ext}").read_bytes(), \
                f"{name}.{ext} differs from animate's"


def children(pid: int) -> list[int]:
    """Processes whose parent is ``pid`` (Linux's /proc; empty elsewhere)."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            found.append(int(stat.parent.name))
    return found


def alive(pid: int) -> bool:
    """Whether ``pid`` is a process that has not ended (a zombie counts as ended)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state not in ("Z", "X")


def leftovers(out: Path) -> list[str]:
    return sorted(p.name for p in out.iterdir() if p.name.startswith("."))


def test_local_batch_isolates_failures_matches_animate_and_resumes(clips, tmp_path):
    out = tmp_path / "out"
    good = [clips["good"]["c1"], clips["good"]["c2"], tmp_path / "c3.mp4"]
    shutil.copyfile(clips["good"]["c3"], good[2])
    paths = [good[0], clips["bad"], good[1], clips["faceless"], good[2]]
    assert main(batch_args(clips, paths, out, "--workers", "2")) == 1
    rows = report(out)
    assert list(rows) == ["c1", "broken", "c2", "faceless", "c3"]          # the jobs' order
    assert {n: r["status"] for n, r in rows.items()} == {
        "c1": "done", "broken": "failed", "c2": "done", "faceless": "failed", "c3": "done"}
    assert all(rows[n]["frames"] == "30" and rows[n]["frames_with_face"] == "30" for n in ("c1", "c2", "c3"))
    assert str(clips["bad"]) in rows["broken"]["error"] and "\n" not in rows["broken"]["error"]
    assert "no face" in rows["faceless"]["error"] and rows["faceless"]["frames"] == "10"
    same_as_animate(clips, out, ["c1", "c2", "c3"])
    assert not (out / "broken.glb").exists() and not (out / "faceless.glb").exists()
    assert leftovers(out) == []

    # Rerun after c3's content changed: c1 and c2 are skipped (files untouched), c3 is done again.
    stamps = {n: (out / f"{n}.glb").stat().st_mtime_ns for n in ("c1", "c2")}
    shutil.copyfile(clips["good"]["c4"], good[2])
    assert main(batch_args(clips, paths, out, "--workers", "1")) == 1
    rows = report(out)
    assert {n: r["status"] for n, r in rows.items()} == {
        "c1": "skipped", "broken": "failed", "c2": "skipped", "faceless": "failed", "c3": "done"}
    assert {n: (out / f"{n}.glb").stat().st_mtime_ns for n in ("c1", "c2")} == stamps
    assert (out / "c3.glb").read_bytes() == (clips["reference"] / "c4.glb").read_bytes()


def test_a_list_gives_names_and_rigs(clips, tmp_path):
    lst = tmp_path / "takes.csv"
    c1 = clips["good"]["c1"]
    lst.write_text(f"clip,rig,output\n{c1},{clips['rig']},first\n{c1},,again\n")
    out = tmp_path / "out"
    assert main(["batch", "--list", str(lst), "--rig", str(clips["rig"]), "--profile", str(clips["profile"]),
                 "-o", str(out), "--no-progress"]) == 0
    assert {n: r["status"] for n, r in report(out).items()} == {"first": "done", "again": "done"}
    ref = (clips["reference"] / "c1.glb").read_bytes()
    assert (out / "first.glb").read_bytes() == ref == (out / "again.glb").read_bytes()


def test_bad_arguments_are_one_line(clips, tmp_path, capsys):
    c1 = clips["good"]["c1"]
    assert main(["batch", str(c1), str(c1), "--rig", str(clips["rig"]), "-o", str(tmp_path / "o")]) == 1
    assert "both write c1.glb" in capsys.readouterr().err
    assert main(["batch", str(c1), "--rig", str(tmp_path / "none.npz"), "-o", str(tmp_path / "o")]) == 1
    assert "none.npz: no such file" in capsys.readouterr().err
    not_rig = tmp_path / "notes.npz"
    not_rig.write_text("not a rig")
    assert main(["batch", str(c1), "--rig", str(not_rig), "-o", str(tmp_path / "o")]) == 1
    assert "argument 1: " in (err := capsys.readouterr().err) and "notes.npz: cannot read rig file" in err
    other = tmp_path / "other.npz"
    np.savez(other, format=np.asarray("facepuppet-track"), version=np.asarray(1))
    assert main(["batch", str(c1), "--rig", str(other), "-o", str(tmp_path / "o")]) == 1
    assert "other.npz: not a facepuppet rig file" in capsys.readouterr().err
    assert not (tmp_path / "o").exists() or not (tmp_path / "o" / "report.csv").exists()


def test_ray_missing_is_one_line_naming_the_extra(clips, tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)          # `import ray` fails as without the extra
    assert main(batch_args(clips, [clips["good"]["c1"]], tmp_path / "o", "--engine", "ray")) == 1
    err = capsys.readouterr().err.strip()
    assert err == 'facepuppet batch: error: --engine ray needs Ray: pip install "facepuppet[ray]"'
    assert not (tmp_path / "o").exists()


@pytest.fixture(scope="module")
def ray_runtime():
    need(importlib.util.find_spec("ray") is not None, 'the ray extra is not installed (pip install "facepuppet[ray]")')
    import ray

    ray.init(address="local", num_cpus=2, include_dashboard=False, logging_level="ERROR")
    yield ray
    ray.shutdown()


def test_ray_engine_writes_the_same_bytes(clips, tmp_path, ray_runtime):
    out = tmp_path / "ray"
    paths = [clips["good"]["c1"], clips["bad"], clips["good"]["c2"]]
    assert main(batch_args(clips, paths, out, "--engine", "ray")) == 1
    rows = report(out)
    assert {n: r["status"] for n, r in rows.items()} == {"c1": "done", "broken": "failed", "c2": "done"}
    assert "cannot open" in rows["broken"]["error"] or str(clips["bad"]) in rows["broken"]["error"]
    same_as_animate(clips, out, ["c1", "c2"])


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL], ids=["SIGTERM", "SIGKILL"])
def test_killed_batch_reruns_each_clip_once(clips, tmp_path, sig):
    out = tmp_path / "out"
    names = list(clips["good"])
    cmd = [sys.executable, "-m", "facepuppet", *batch_args(clips, clips["good"].values(), out, "--workers", "1")]
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src") + os.pathsep + os.environ.get("PYTHONPATH", "")}
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 120
    first: dict = {}
    while time.monotonic() < deadline and proc.poll() is None:
        if (out / "report.csv").is_file():
            first = report(out)
            if any(r["status"] == "done" for r in first.values()):
                break
        time.sleep(0.05)
    assert proc.poll() is None, "the batch ended before it could be killed"
    workers = children(proc.pid)
    proc.send_signal(sig)
    proc.wait(timeout=60)
    time.sleep(1.0)                 # the worker, told by its parent's death, removes its temporary files
    end = time.monotonic() + 30
    while any(alive(w) for w in workers) and time.monotonic() < end:
        time.sleep(0.2)
    assert not [w for w in workers if alive(w)], "a worker lived on after its batch was killed"
    first = report(out)
    done_first = {n for n, r in first.items() if r["status"] == "done"}
    assert done_first and done_first != set(names)
    assert leftovers(out) == []                 # the clip cut short left no temporary file

    assert main(batch_args(clips, clips["good"].values(), out, "--workers", "1")) == 0
    second = report(out)
    assert {n: r["status"] for n, r in second.items()} == {
        n: "skipped" if n in done_first else "done" for n in names}
    same_as_animate(clips, out, names)
    assert leftovers(out) == []
