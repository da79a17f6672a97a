"""Key-model names to ARKit's 52 blendshapes, shared by the VMC and Live Link Face senders.

A key-model drives the ARKit blendshapes :func:`facepuppet.export.csv.arkit_columns` gives it, exactly as the
Live Link Face CSV does: ``eyeBlink_L``, ``eyeBlinkLeft`` and ``EyeBlinkLeft`` drive ``EyeBlinkLeft``; a
symmetric ``mouthSmile`` drives both sides; halves of a shape ARKit has as one (ICT's ``browInnerUp_L`` and
``browInnerUp_R``) are averaged into it.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from facepuppet.arkit import LLF_NAMES
from facepuppet.export.csv import arkit_columns

__all__ = ["ArkitMap", "arkit_map"]


class ArkitMap:
    """The linear map from a rig's weights (M,) to ARKit's 52 blendshapes in Live Link Face order.

    Attributes
    ----------
    matrix : (52, M) float
        ``matrix @ weights`` is the 52 blendshape values (averaging halves).
    driven : (52,) bool
        Blendshapes some key-model drives.
    unmapped : tuple of str
        Key-model names that are not ARKit's.
    """

    def __init__(self, names: Sequence[str]) -> None:
        names = [str(n) for n in names]
        matrix = np.zeros((len(LLF_NAMES), len(names)))
        for j, name in enumerate(names):
            for c in arkit_columns(name):
                matrix[c, j] = 1.0
        count = matrix.sum(axis=1)
        self.matrix = matrix / np.maximum(count, 1.0)[:, None]
        self.driven = count > 0
        self.unmapped = tuple(n for j, n in enumerate(names) if not matrix[:, j].any())

    def __call__(self, weights: np.ndarray) -> np.ndarray:
        """(52,) blendshape values of weights (M,), non-finite weights taken as 0."""
        w = np.asarray(weights, dtype=np.float64)
        return self.matrix @ np.where(np.isfinite(w), w, 0.0)


def arkit_map(names: Sequence[str]) -> ArkitMap:
    """The :class:`ArkitMap` of key-model ``names``."""
    return ArkitMap(names)
