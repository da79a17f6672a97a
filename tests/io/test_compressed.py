"""Compressed characters (EXT_meshopt_compression, KHR_draco_mesh_compression) read as the uncompressed one.

The tests compress their own character with the packages' encoders and check the same character and the
same rig come out; what is kept in ``Character.source`` is uncompressed.
"""

from __future__ import annotations

import numpy as np

from compressed_copies import draco_copy, meshopt_copy
from facepuppet.io.character import load_character
from facepuppet.io.performer import Performer
from facepuppet.io.scene import parse_glb
from facepuppet.pipeline.rig import fit_rig
from scene_characters import skinned_character

NAMES = ("jawOpen", "eyeBlinkLeft", "mouthSmileLeft")


def _canonical(faces: np.ndarray) -> np.ndarray:
    """Each triangle rotated to start at its smallest index (the meshopt index codec rotates triangles)."""
    faces = np.asarray(faces)
    shift = np.argmin(faces, axis=1)
    return np.stack([np.roll(f, -k) for f, k in zip(faces, shift, strict=True)])


def _same_rig(tmp_path, rng, compressed: bytes, plain: bytes, atol: float):
    (tmp_path / "plain.glb").write_bytes(plain)
    (tmp_path / "packed.glb").write_bytes(compressed)
    a, b = load_character(tmp_path / "plain.glb"), load_character(tmp_path / "packed.glb")
    assert a.names == b.names
    np.testing.assert_allclose(b.neutral, a.neutral, atol=atol)
    np.testing.assert_allclose(b.targets, a.targets, atol=atol)
    np.testing.assert_array_equal(_canonical(b.faces), _canonical(a.faces))
    doc, _ = parse_glb(b.source)
    assert not set(doc.get("extensionsUsed", [])) & {"EXT_meshopt_compression", "KHR_draco_mesh_compression"}
    base = rng.normal(size=(8, 2))
    performer = Performer(base, base[None] + rng.normal(size=(3, 8, 2)) * 0.1, NAMES)
    rig_a, rig_b = fit_rig(performer, a)[0], fit_rig(performer, b)[0]
    probe = base + rng.normal(size=base.shape) * 0.05
    np.testing.assert_allclose(rig_b.mapper.weights(probe), rig_a.mapper.weights(probe), atol=1e-4)
    return doc


def test_meshopt_character_gives_the_same_rig(tmp_path, rng, caplog):
    plain = skinned_character(rng)["glb"]
    with caplog.at_level("WARNING"):
        _same_rig(tmp_path, rng, meshopt_copy(plain), plain, atol=0.0)  # lossless
    assert "EXT_meshopt_compression; what facepuppet writes from this character is uncompressed" in caplog.text


def test_draco_character_gives_the_same_rig(tmp_path, rng):
    plain = skinned_character(rng)["glb"]
    _same_rig(tmp_path, rng, draco_copy(plain), plain, atol=1e-5)  # 30-bit quantisation
