"""Silently wrong: what would animate with exit 0 and a wrong result is refused, naming the file or argument."""

import json
from dataclasses import replace

import numpy as np
import pytest

from hardening.hardening_cases import animate_args, make_track, run_refused


def test_rig_of_another_backend(capsys, world, tmp_path):
    """The track is made with the colour tracker, the rig with MediaPipe."""
    run_refused(capsys, animate_args(world, rig=world.rig_mediapipe) + ["-o", tmp_path / "a.glb"], world,
                folders=[tmp_path], names=["rig_mp.npz", "mediapipe"])


def test_rig_of_another_backend_when_tracking(capsys, world, tmp_path):
    run_refused(capsys, ["animate", world.video, "--rig", world.rig_mediapipe, "-o", tmp_path / "a.glb",
                         "--no-progress"], world, folders=[tmp_path], names=["rig_mp.npz", "--backend"])


def test_track_of_another_video(capsys, world, tmp_path):
    run_refused(capsys, ["animate", world.video2, "--rig", world.rig, "--track", world.track, "-o",
                         tmp_path / "a.glb", "--no-progress"], world, folders=[tmp_path],
                names=["--track", "another video", "video2.mp4"])


def test_older_track_without_provenance_still_loads(world, tmp_path):
    from facepuppet.io.performer import load_performer
    from facepuppet.io.track import load_track, save_track
    from facepuppet.pipeline.animate import animate

    path = tmp_path / "old.npz"
    save_track(path, make_track(load_performer(world.performer), None))
    assert load_track(path).media is None
    anim = animate(world.video2, world.rig, track=path, keep_track=False)    # nothing to compare: no refusal
    assert len(anim.valid) > 0


@pytest.mark.parametrize("gain", ["1e39", "-1", "nan", "inf", "jaw=1e6"])
def test_absurd_gain(capsys, world, tmp_path, gain):
    run_refused(capsys, [*animate_args(world), "-o", tmp_path / "a.glb", "--gain", gain], world,
                folders=[tmp_path], names=["--gain"])


@pytest.mark.parametrize("fps", [1e-40, 0.0, -30.0, float("nan"), float("inf"), 1e9])
def test_track_fps_out_of_range(capsys, world, tmp_path, fps):
    from facepuppet.io.performer import load_performer
    from facepuppet.io.track import save_track

    path = tmp_path / "t.npz"
    save_track(path, replace(make_track(load_performer(world.performer), world.video), fps=fps))
    run_refused(capsys, animate_args(world, track=path) + ["-o", tmp_path / "a.glb"], world, folders=[tmp_path],
                names=["t.npz", "frame rate"])


def _character(tmp_path, change):
    from facepuppet.demo.toy import toy_character
    from facepuppet.io.character import Character
    from facepuppet.io.gltf import write_glb

    toy = toy_character()
    neutral, targets = change(np.array(toy.neutral), np.array(toy.targets))
    path = tmp_path / "bad.glb"
    write_glb(path, Character(neutral, targets, toy.names, None, "bad"))
    return path


@pytest.mark.parametrize("change, what", [
    (lambda n, t: (n[:1], t[:, :1]), "vertices"),
    (lambda n, t: (n, np.repeat(n[None], len(t), axis=0)), "equals the neutral"),
], ids=["one-vertex", "all-neutral"])
def test_degenerate_character(capsys, world, tmp_path, change, what):
    path = _character(tmp_path, change)
    run_refused(capsys, ["rig", "--performer", world.performer, "--character", path, "-o", tmp_path / "r.npz"],
                world, folders=[tmp_path], names=["bad.glb", what])


@pytest.mark.parametrize("which", ["neutral", "key-model"])
def test_character_with_nan_vertices(capsys, world, tmp_path, which):
    """An OBJ folder whose neutral or one key-model has a NaN vertex (glTF writers refuse to write one)."""
    import shutil

    from facepuppet.demo.toy import toy_character

    folder = tmp_path / "nan_obj"
    shutil.copytree(world.objdir, folder)
    name = "neutral" if which == "neutral" else toy_character().names[2]
    obj = folder / f"{name}.obj"
    lines = obj.read_text().splitlines()
    first = next(i for i, x in enumerate(lines) if x.startswith("v "))
    lines[first] = "v nan 0 0"
    obj.write_text("\n".join(lines) + "\n")
    run_refused(capsys, ["rig", "--performer", world.performer, "--character", folder, "-o", tmp_path / "r.npz"],
                world, folders=[tmp_path], names=["nan_obj", "NaN"])


def test_node_scaled_to_zero(capsys, world, tmp_path):
    from facepuppet.demo.toy import toy_character
    from facepuppet.io.gltf import write_glb

    path = tmp_path / "zero.gltf"
    write_glb(path, toy_character())
    doc = json.loads(path.read_text())
    doc["nodes"][0]["scale"] = [0.0, 0.0, 0.0]
    path.write_text(json.dumps(doc))
    run_refused(capsys, ["rig", "--performer", world.performer, "--character", path, "-o", tmp_path / "r.npz"],
                world, folders=[tmp_path], names=["zero.gltf"])


def test_rig_damaged_to_nan(capsys, world, tmp_path):
    import zipfile

    with zipfile.ZipFile(world.rig) as zf:
        members = {n: zf.read(n) for n in zf.namelist()}
    from facepuppet.pipeline.rig import load_rig

    rig = load_rig(world.rig)
    deltas = np.asarray(rig.mapper.target_deltas).copy()
    deltas.flat[0] = np.nan
    import io

    buf = io.BytesIO()
    np.save(buf, deltas)
    members["mapper.target_deltas.npy"] = buf.getvalue()
    bad = tmp_path / "nan_rig.npz"
    with zipfile.ZipFile(bad, "w") as zf:
        for n, data in members.items():
            zf.writestr(n, data)
    run_refused(capsys, animate_args(world, rig=bad) + ["-o", tmp_path / "a.glb"], world, folders=[tmp_path],
                names=["nan_rig.npz", "NaN"])


def test_performer_whose_expressions_do_not_move(capsys, world, tmp_path):
    from facepuppet.io.performer import load_performer, save_performer

    p = load_performer(world.performer)
    still = tmp_path / "still.npz"
    save_performer(still, replace(p, examples=np.repeat(p.neutral[None], len(p.examples), axis=0)))
    line = run_refused(capsys, ["rig", "--performer", still, "--character", world.glb, "-o", tmp_path / "r.npz"],
                       world, folders=[tmp_path], names=["still.npz"])
    assert "source_examples" not in line


def test_negative_mark_time(capsys, world, tmp_path):
    marks = tmp_path / "m.csv"
    marks.write_text("-1s,neutral\n", encoding="utf-8")
    run_refused(capsys, ["calibrate", world.video, "--marks", marks, "-o", tmp_path / "e.npz", "--no-progress"],
                world, folders=[tmp_path], names=["m.csv", "negative"])


@pytest.mark.parametrize("gains", [["2", "3"], ["2,3"], ["jawOpen=2", "jawOpen=3"]])
def test_a_gain_given_twice(capsys, world, tmp_path, gains):
    args = [*animate_args(world), "-o", tmp_path / "a.glb"]
    for g in gains:
        args += ["--gain", g]
    run_refused(capsys, args, world, folders=[tmp_path], names=["--gain"])
