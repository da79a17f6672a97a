"""Characters by path: :func:`load_character` and :func:`save_character` pick the glTF or OBJ reader/writer.

The :class:`Character` type is defined in :mod:`facepuppet.io.character_type` and re-exported here; the
readers and writers of the file formats live in :mod:`facepuppet.io.gltf` and :mod:`facepuppet.io.obj`.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from facepuppet.errors import FacepuppetError
from facepuppet.io.character_type import Character
from facepuppet.io.gltf import read_gltf, write_glb
from facepuppet.io.obj import read_obj_character, write_obj_character

__all__ = ["Character", "load_character", "save_character", "check_character"]


def load_character(path: str | os.PathLike, *, neutral: str | os.PathLike | None = None,
                   mesh: str | int | None = None) -> Character:
    """Read a character from a .glb / .gltf file or a folder of OBJ files.

    Parameters
    ----------
    path : str or PathLike
        A .glb or .gltf file (morph targets are the key-models), or a folder with a neutral OBJ and one OBJ
        per key-model.
    neutral : str or PathLike, optional
        OBJ folders only: the neutral OBJ's file name or stem (default ``neutral.obj``).
    mesh : str or int, optional
        glTF only: read this mesh (name or index) instead of every mesh with morph targets.
    """
    return check_character(_read(Path(path), neutral, mesh), path)


def check_character(character: Character, label) -> Character:
    """``character`` if it can be animated; else FacepuppetError naming ``label`` (its file) and what is wrong:
    fewer than 3 vertices, NaN or infinite vertices (which key-model), every key-model equal to the neutral."""
    neutral, targets = np.asarray(character.neutral), np.asarray(character.targets)
    if len(neutral) < 3:
        raise FacepuppetError(f"{label}: the mesh has {len(neutral)} vertices; a face needs at least 3")
    if not np.isfinite(neutral).all():
        raise FacepuppetError(f"{label}: the neutral mesh holds NaN or infinite vertices")
    bad = [n for n, t in zip(character.names, targets, strict=True) if not np.isfinite(t).all()]
    if bad:
        raise FacepuppetError(f"{label}: key-model {bad[0]!r} holds NaN or infinite vertices"
                              + (f" (and {len(bad) - 1} more)" if len(bad) > 1 else ""))
    size = float(np.ptp(neutral, axis=0).max())
    if len(targets) and size > 0 and np.abs(targets - neutral[None]).max() <= 1e-9 * size:
        raise FacepuppetError(f"{label}: every key-model equals the neutral mesh (no morph target moves a "
                              f"vertex; a node scaled to zero?)")
    if size <= 0:
        raise FacepuppetError(f"{label}: every vertex of the neutral mesh is at the same point")
    return character


def _read(path: Path, neutral, mesh) -> Character:
    suffix = path.suffix.lower()
    if path.is_dir():
        if mesh is not None:
            raise ValueError("mesh: only for glTF characters, not for a folder of OBJ files")
        return read_obj_character(path, neutral=neutral)
    if not path.exists():
        raise FacepuppetError(f"{path}: no such file or folder")
    if neutral is not None:
        raise ValueError("neutral: only for a folder of OBJ files")
    if suffix in (".glb", ".gltf", ".vrm"):
        return read_gltf(path, mesh=mesh)
    if suffix == ".obj":
        raise FacepuppetError(f"{path}: one OBJ holds no key-models; give the folder with the neutral OBJ and "
                              f"one OBJ per key-model")
    raise FacepuppetError(f"{path}: unknown character format (expected .glb, .gltf or a folder of OBJ files)")


def save_character(path: str | os.PathLike, character: Character, *, normals: bool = False) -> None:
    """Write ``character`` as .glb / .gltf (by the suffix), or as a folder of OBJ files (any other path)."""
    path = Path(path)
    if path.suffix.lower() in (".glb", ".gltf"):
        write_glb(path, character, normals=normals)
    else:
        write_obj_character(path, character)
