"""A character: its neutral mesh and key-models (the paper's target base T_B and target examples T_i).

Readers and writers for the file formats live in :mod:`facepuppet.io.gltf` and :mod:`facepuppet.io.obj`;
:func:`load_character` picks one by the path.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from facepuppet.errors import FacepuppetError

__all__ = ["Character", "load_character", "save_character"]


@dataclass(frozen=True)
class Character:
    """A character's neutral mesh and named key-models, vertex for vertex.

    Attributes
    ----------
    neutral : (V, 3) float
        Neutral mesh T_B, in the character's own units, y up.
    targets : (M, V, 3) float
        Key-models T_i as absolute vertex positions (not offsets).
    names : tuple of M str
        Key-model names (glTF ``extras.targetNames`` or OBJ file stems).
    faces : (T, 3) int or None
        Triangles, indices into the vertices.
    name : str
        The character's name.
    """

    neutral: np.ndarray
    targets: np.ndarray
    names: tuple[str, ...]
    faces: np.ndarray | None = None
    name: str = "character"

    def __post_init__(self) -> None:
        n, t = np.shape(self.neutral), np.shape(self.targets)
        if len(n) != 2 or n[1] != 3:
            raise ValueError(f"neutral must have shape (V, 3), got {n}")
        if len(t) != 3 or t[1:] != n:
            raise ValueError(f"targets must have shape (M, {n[0]}, 3), got {t}")
        if len(self.names) != t[0]:
            raise ValueError(f"names must hold {t[0]} key-model names, got {len(self.names)}")
        if len(set(self.names)) != len(self.names):
            dup = sorted({x for x in self.names if list(self.names).count(x) > 1})
            raise ValueError(f"key-model names must be unique; repeated: {', '.join(dup)}")

    @property
    def deltas(self) -> np.ndarray:
        """(M, V, 3) key-model offsets T_i - T_B (glTF morph targets)."""
        return self.targets - self.neutral[None]


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
    path = Path(path)
    suffix = path.suffix.lower()
    if path.is_dir():
        if mesh is not None:
            raise ValueError("mesh: only for glTF characters, not for a folder of OBJ files")
        from facepuppet.io.obj import read_obj_character

        return read_obj_character(path, neutral=neutral)
    if not path.exists():
        raise FacepuppetError(f"{path}: no such file or folder")
    if neutral is not None:
        raise ValueError("neutral: only for a folder of OBJ files")
    if suffix in (".glb", ".gltf"):
        from facepuppet.io.gltf import read_gltf

        return read_gltf(path, mesh=mesh)
    if suffix == ".obj":
        raise FacepuppetError(f"{path}: one OBJ holds no key-models; give the folder with the neutral OBJ and "
                              f"one OBJ per key-model")
    raise FacepuppetError(f"{path}: unknown character format (expected .glb, .gltf or a folder of OBJ files)")


def save_character(path: str | os.PathLike, character: Character, *, normals: bool = False) -> None:
    """Write ``character`` as .glb / .gltf (by the suffix), or as a folder of OBJ files (any other path)."""
    path = Path(path)
    if path.suffix.lower() in (".glb", ".gltf"):
        from facepuppet.io.gltf import write_glb

        write_glb(path, character, normals=normals)
    else:
        from facepuppet.io.obj import write_obj_character

        write_obj_character(path, character)
