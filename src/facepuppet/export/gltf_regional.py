"""A regional animation as a GLB: the key-models split by region into morph targets (R·M of them).

The regional blend T = T_B + sum_k sum_i M_k (.) w_ik (T_i - T_B) is linear in the key-models, so a glTF
player plays it with the morph targets M_k (.) (T_i - T_B), region-major (target k·M + i, named
``"<region>/<key-model>"``), and the weights w_ik of each frame flattened the same way. A region that a
key-model does not move (its masked target is zero) keeps its target, so every frame has R·M weights.
"""

from __future__ import annotations

import os

import numpy as np

from facepuppet.export.gltf_animation import write_animated_glb
from facepuppet.io.character import Character

__all__ = ["split_character", "write_regional_glb"]


def split_character(character: Character, masks: np.ndarray, region_names) -> Character:
    """The character with its key-models split by region: R·M key-models T_B + M_k (.) (T_i - T_B).

    Parameters
    ----------
    character : Character
        M key-models.
    masks : (R, V) float
        Region masks (a partition of unity over the vertices).
    region_names : sequence of R str

    Returns
    -------
    Character
        Key-model k·M + i named ``f"{region_names[k]}/{character.names[i]}"``.
    """
    base = np.asarray(character.neutral, dtype=np.float64)
    deltas = np.asarray(character.targets, dtype=np.float64) - base[None]
    m = np.asarray(masks, dtype=np.float64)
    regions = [str(r) for r in region_names]
    if m.ndim != 2 or m.shape[1] != len(base) or len(regions) != len(m) or not np.isfinite(m).all():
        raise ValueError(f"masks must be a finite (R, {len(base)}) array with one name per region, got shape "
                         f"{m.shape} and {len(regions)} names")
    targets = base[None] + (m[:, None, :, None] * deltas[None]).reshape(-1, *base.shape)
    names = tuple(f"{r}/{n}" for r in regions for n in character.names)
    return Character(base, targets, names, character.faces, character.name)


def write_regional_glb(path: str | os.PathLike, character: Character, masks: np.ndarray, region_names,
                       weights: np.ndarray, fps: float, **options) -> None:
    """Write a regional animation as a GLB, atomically (the module docstring; validator-clean).

    Parameters
    ----------
    path : str or PathLike
    character : Character
        M key-models.
    masks : (R, V) float
    region_names : sequence of R str
    weights : (F, R, M) float
        w_ik per frame (e.g. ``ExpressionMapper.weights`` of a regional mapper); a frame with NaN is neutral.
    fps : float
    **options
        ``head_rotation``, ``pivot``, ``normals``, ``name``, ``times`` of
        :func:`~facepuppet.export.gltf_animation.write_animated_glb`.
    """
    w = np.asarray(weights, dtype=np.float64)
    r, m = len(np.asarray(masks)), len(character.names)
    if w.ndim != 3 or w.shape[1:] != (r, m):
        raise ValueError(f"weights must have shape (F, {r}, {m}), got {w.shape}")
    write_animated_glb(path, split_character(character, masks, region_names), w.reshape(len(w), r * m), fps,
                       **options)
