"""Characters as Wavefront OBJ files: a neutral OBJ plus one OBJ per key-model, vertex for vertex.

Only ``v`` and ``f`` lines are read, by this module, in file order: general mesh loaders split vertices at UV
seams or merge duplicates, which breaks the correspondence between the neutral and its key-models. Polygons
are triangulated as fans; ``f`` entries may be ``v``, ``v/vt``, ``v//vn`` or ``v/vt/vn`` and negative
(relative) indices. A key-model's name is its file stem.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from facepuppet._util.atomic import atomic_path
from facepuppet.errors import FacepuppetError
from facepuppet.io.character_type import Character

__all__ = ["read_obj", "read_obj_character", "write_obj", "write_obj_character", "NEUTRAL_NAMES"]

log = logging.getLogger(__name__)

#: File stems taken as the neutral mesh in a folder, in order of preference.
NEUTRAL_NAMES = ("neutral", "Neutral", "NEUTRAL", "base", "Basis")


def read_obj(path: str | os.PathLike, *, faces: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
    """Read the vertices (V, 3) float64, in file order, and the triangles (T, 3) int64 (or None) of an OBJ."""
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            lines = fh.read().decode("utf-8", errors="replace").splitlines()
    except OSError as e:
        raise FacepuppetError(f"{path}: cannot read OBJ ({e.strerror or e})") from e
    vertices: list[list[float]] = []
    tris: list[tuple[int, int, int]] = []
    for number, line in enumerate(lines, 1):
        line = line.lstrip()
        if line.startswith("v ") or line.startswith("v\t"):
            parts = line.split()
            try:
                vertices.append([float(parts[1]), float(parts[2]), float(parts[3])])
            except (IndexError, ValueError) as e:
                raise FacepuppetError(f"{path}:{number}: bad vertex line {line.strip()!r}") from e
        elif faces and (line.startswith("f ") or line.startswith("f\t")):
            try:
                idx = [int(tok.split("/", 1)[0]) for tok in line.split()[1:]]
            except ValueError as e:
                raise FacepuppetError(f"{path}:{number}: bad face line {line.strip()!r}") from e
            if len(idx) < 3:
                raise FacepuppetError(f"{path}:{number}: a face needs 3 or more vertices")
            n = len(vertices)
            idx = [i - 1 if i > 0 else n + i for i in idx]  # 1-based, or relative to the vertices so far
            tris.extend((idx[0], idx[k], idx[k + 1]) for k in range(1, len(idx) - 1))
    if not vertices:
        raise FacepuppetError(f"{path}: no vertices ('v' lines) in the OBJ")
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(tris, dtype=np.int64).reshape(-1, 3) if tris else None
    if f is not None and (f.min() < 0 or f.max() >= len(v)):
        raise FacepuppetError(f"{path}: face indices outside the {len(v)} vertices")
    return v, f


def read_obj_character(source: str | os.PathLike | Sequence[str | os.PathLike], *,
                       neutral: str | os.PathLike | None = None, name: str | None = None) -> Character:
    """Read a character from OBJ files.

    Parameters
    ----------
    source : folder, or sequence of OBJ paths
        A folder: every ``*.obj`` in it; the neutral is ``neutral`` (a file name or stem in the folder) or the
        first of :data:`NEUTRAL_NAMES` present; all other OBJs are key-models, sorted by name. A sequence: the
        key-model OBJs, in order (``neutral`` is then required).
    neutral : str or PathLike, optional
        The neutral OBJ: a path, or a file name / stem inside the folder.
    name : str, optional
        The character's name; defaults to the folder's name or the neutral's stem.
    """
    folder = None
    if isinstance(source, (str, os.PathLike)):
        folder = Path(source)
        if not folder.is_dir():
            raise FacepuppetError(f"{folder}: not a folder of OBJ files")
        objs = sorted(p for p in folder.iterdir() if p.suffix.lower() == ".obj" and p.is_file())
        if not objs:
            raise FacepuppetError(f"{folder}: no .obj files in the folder")
        neutral_path = _pick_neutral(folder, objs, neutral)
        keys = [p for p in objs if p != neutral_path]
    else:
        keys = [Path(p) for p in source]
        if neutral is None:
            raise ValueError("neutral: give the neutral OBJ when listing key-model files")
        neutral_path = Path(neutral)
        keys = [p for p in keys if p.resolve() != neutral_path.resolve()]
    if not keys:
        raise FacepuppetError(f"{folder or neutral_path}: no key-model OBJ besides the neutral")
    base, faces = read_obj(neutral_path)
    targets = np.empty((len(keys), len(base), 3))
    for i, path in enumerate(keys):
        v, _ = read_obj(path, faces=False)
        if len(v) != len(base):
            raise FacepuppetError(f"{path}: {len(v)} vertices, but the neutral {neutral_path.name} has "
                                  f"{len(base)}; key-models must match the neutral vertex for vertex")
        targets[i] = v
    names = tuple(p.stem for p in keys)
    if len(set(names)) != len(names):
        dup = sorted({n for n in names if names.count(n) > 1})
        raise FacepuppetError(f"key-model names repeat: {', '.join(dup)}")
    log.info("read %d key-models of %d vertices from OBJ", len(keys), len(base))
    return Character(neutral=base, targets=targets, names=names, faces=faces,
                     name=name or (folder.name if folder is not None else neutral_path.stem))


def _pick_neutral(folder: Path, objs: list[Path], neutral) -> Path:
    if neutral is not None:
        candidate = Path(neutral)
        for p in (candidate, folder / candidate, folder / f"{candidate}.obj"):
            if p.is_file():
                return p
        raise FacepuppetError(f"{folder}: neutral OBJ {neutral} not found")
    by_stem = {p.stem: p for p in objs}
    for stem in NEUTRAL_NAMES:
        if stem in by_stem:
            return by_stem[stem]
    raise FacepuppetError(f"{folder}: no neutral OBJ (expected one of "
                          f"{', '.join(s + '.obj' for s in NEUTRAL_NAMES)}, or name it with the neutral option)")


def write_obj(path: str | os.PathLike, vertices: np.ndarray, faces: np.ndarray | None = None) -> None:
    """Write vertices (V, 3) and triangles (T, 3) as an OBJ, atomically; floats are written so they read back
    bit for bit."""
    v = np.asarray(vertices, dtype=np.float64)
    lines = ["v " + " ".join(repr(x) for x in row) for row in v.tolist()]
    if faces is not None:
        lines += ["f " + " ".join(str(int(i) + 1) for i in tri) for tri in np.asarray(faces)]
    with atomic_path(path, suffix=".obj") as tmp:
        tmp.write_text("\n".join(lines) + "\n", encoding="utf-8")


def write_obj_character(folder: str | os.PathLike, character: Character) -> None:
    """Write ``neutral.obj`` and one ``<name>.obj`` per key-model into ``folder`` (created if missing)."""
    folder = Path(folder)
    if "neutral" in character.names:
        raise ValueError("a key-model named 'neutral' would overwrite neutral.obj")
    for n in character.names:
        if not n or "/" in n or "\\" in n or n in (".", ".."):
            raise ValueError(f"key-model name {n!r} cannot be a file name")
    folder.mkdir(parents=True, exist_ok=True)
    write_obj(folder / "neutral.obj", character.neutral, character.faces)
    for n, target in zip(character.names, character.targets, strict=True):
        write_obj(folder / f"{n}.obj", target, character.faces)
