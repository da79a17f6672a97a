"""The character as the viewer page reads it: one binary asset (``/mesh.bin``) and a JSON description.

``mesh.bin`` layout, little-endian (the byte order of every WebGL platform), 4-byte aligned:

=========================  =================  ===============================================
field                      type               meaning
=========================  =================  ===============================================
magic                      4 bytes            ``b"FPM1"``
V, M, T, flags             4 x uint32         vertices, key-models, triangles; flags bit 0:
                                              vertex colours follow
neutral                    V x 3 float32      the neutral mesh T_B, character units, y up
deltas                     M x V x 3 float32  key-model offsets T_i - T_B (morph targets)
faces                      T x 3 uint32       triangles (T = 0: drawn as points)
colours (if flags bit 0)   V x 4 uint8        RGBA, sRGB
=========================  =================  ===============================================
"""

from __future__ import annotations

import json

import numpy as np

__all__ = ["mesh_asset", "rig_description", "MESH_MAGIC"]

#: First four bytes of ``mesh.bin``.
MESH_MAGIC = b"FPM1"


def mesh_asset(character, *, colors: np.ndarray | None = None) -> bytes:
    """The ``mesh.bin`` bytes of a :class:`facepuppet.io.character.Character` (module notes).

    Parameters
    ----------
    character : Character
    colors : (V, 3) or (V, 4) float in [0, 1] or uint8, optional
        Vertex colours (sRGB).
    """
    neutral = np.asarray(character.neutral, dtype="<f4")
    deltas = np.asarray(character.deltas, dtype="<f4")
    v, m = len(neutral), len(deltas)
    faces = np.zeros((0, 3), dtype="<u4") if character.faces is None else np.asarray(character.faces)
    if faces.size and (faces.min() < 0 or faces.max() >= v):
        raise ValueError(f"character faces index vertices outside 0..{v - 1}")
    parts = [MESH_MAGIC]
    rgba = None
    if colors is not None:
        c = np.asarray(colors)
        if c.ndim != 2 or c.shape[0] != v or c.shape[1] not in (3, 4):
            raise ValueError(f"colors must have shape ({v}, 3) or ({v}, 4), got {c.shape}")
        if c.dtype != np.uint8:
            c = np.clip(np.round(np.asarray(c, dtype=float) * 255), 0, 255).astype(np.uint8)
        rgba = np.concatenate([c, np.full((v, 1), 255, np.uint8)], axis=1) if c.shape[1] == 3 else c
    parts.append(np.array([v, m, len(faces), int(rgba is not None)], dtype="<u4").tobytes())
    parts += [neutral.tobytes(), deltas.tobytes(), faces.astype("<u4").tobytes()]
    if rgba is not None:
        parts.append(np.ascontiguousarray(rgba, dtype=np.uint8).tobytes())
    return b"".join(parts)


def rig_description(character) -> bytes:
    """``rig.json``: the character's name, key-model names (the order of the weights in every frame message)
    and vertex count."""
    return json.dumps({"name": str(character.name), "names": [str(n) for n in character.names],
                       "vertices": int(len(character.neutral))}, separators=(",", ":")).encode("utf-8")
