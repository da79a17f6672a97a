"""The rig keeps the character's whole scene (rig format 2), and the GLB output writes into it; a version-1 rig
still loads and writes the bare mesh."""

from __future__ import annotations

import contextlib
from types import SimpleNamespace

import numpy as np

from facepuppet.io.character import load_character
from facepuppet.io.performer import Performer
from facepuppet.io.scene import parse_glb
from facepuppet.pipeline.outputs import GlbOutput
from facepuppet.pipeline.rig import fit_rig, load_rig, save_rig
from scene_characters import skinned_character

NAMES = ("jawOpen", "eyeBlinkLeft", "mouthSmileLeft")


def _rig(tmp_path, rng):
    made = skinned_character(rng)
    (tmp_path / "c.glb").write_bytes(made["glb"])
    character = load_character(tmp_path / "c.glb")
    base = rng.normal(size=(8, 2))
    performer = Performer(base, base[None] + rng.normal(size=(3, 8, 2)) * 0.1, NAMES)
    rig, _ = fit_rig(performer, character)
    save_rig(tmp_path / "rig.npz", rig)
    return made, rig


def _write_glb(path, rig, frames=5):
    with contextlib.ExitStack() as stack:
        out = GlbOutput(path, rig, stack, fps=30.0)
        for f in range(frames):
            out.write(SimpleNamespace(time=f / 30, valid=True, weights=np.full(len(rig.names), 0.1 * f),
                                      rotation=np.eye(3)))
        out.finish()


def test_rig_keeps_the_scene_and_writes_into_it(tmp_path, rng):
    made, rig = _rig(tmp_path, rng)
    back = load_rig(tmp_path / "rig.npz")
    assert back.character.source == rig.character.source
    _write_glb(tmp_path / "out.glb", back)
    doc_in, _ = parse_glb(made["glb"])
    doc, _ = parse_glb((tmp_path / "out.glb").read_bytes())
    for key in ("nodes", "meshes", "materials", "textures", "images", "samplers", "skins", "cameras", "scenes"):
        assert doc[key] == doc_in[key], key
    assert len(doc["animations"]) == len(doc_in["animations"]) + 1


def test_version_1_rig_writes_the_bare_mesh(tmp_path, rng):
    _, rig = _rig(tmp_path, rng)
    with np.load(tmp_path / "rig.npz", allow_pickle=False) as raw:
        arrays = {k: raw[k] for k in raw.files if k != "character.source"}
    arrays["version"] = np.asarray(1)
    np.savez(tmp_path / "old.npz", **arrays)
    old = load_rig(tmp_path / "old.npz")
    assert old.character.source is None
    _write_glb(tmp_path / "bare.glb", old)
    doc, _ = parse_glb((tmp_path / "bare.glb").read_bytes())
    assert len(doc["meshes"]) == 1 and "materials" not in doc
