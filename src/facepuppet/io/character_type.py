"""A character: its neutral mesh and key-models (the paper's target base T_B and target examples T_i).

The type alone, so that the readers (:mod:`facepuppet.io.gltf`, :mod:`facepuppet.io.obj`) and the dispatcher
above them (:mod:`facepuppet.io.character`) all import it from below.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Character"]


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
    source : bytes or None
        The whole glTF scene it was read from, as one self-contained GLB (:mod:`facepuppet.io.scene`), so that
        an animation can be written into it; None for characters made in memory or read from OBJ files.
    """

    neutral: np.ndarray
    targets: np.ndarray
    names: tuple[str, ...]
    faces: np.ndarray | None = None
    name: str = "character"
    source: bytes | None = field(default=None, repr=False, compare=False)

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

