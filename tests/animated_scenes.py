"""Small animated characters for the tests that play an exported GLB in another program (three.js, Blender)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from facepuppet.export.gltf_animation import write_animated_glb
from facepuppet.io.character import Character


def make_character(rng, v=30, m=4) -> Character:
    """A random character of ``v`` vertices and ``m`` key-models (float32-exact, as a GLB stores them)."""
    base = rng.normal(size=(v, 3)).astype(np.float32).astype(np.float64)
    targets = (base[None] + rng.normal(size=(m, v, 3)) * 0.05).astype(np.float32).astype(np.float64)
    faces = np.array([[i, i + 1, i + 2] for i in range(v - 2)])
    return Character(base, targets, tuple(f"key{i}" for i in range(m)), faces, "toy")


def morphed(c: Character, w: np.ndarray) -> np.ndarray:
    """Eq. 14: T_B + Σ_i w_i (T_i - T_B), (V, 3)."""
    return c.neutral + np.tensordot(w, c.targets - c.neutral[None], axes=1)


@dataclass
class HeadScene:
    """A character animated with weights and a turning head, written to ``path``."""

    character: Character
    weights: np.ndarray       # (F, M); frame 4 is lost (NaN): neutral
    rotation: Rotation        # F head rotations
    pivot: np.ndarray
    fps: int
    path: Path


def head_scene(tmp_path: Path, rng, frames: int = 12, fps: int = 24) -> HeadScene:
    """Write a 3-key-model character with random weights and head turns (frame 4 lost) to ``tmp_path``."""
    c = make_character(rng, m=3)
    rot = Rotation.from_euler("YXZ", rng.uniform(-0.5, 0.5, size=(frames, 3)))
    weights = rng.uniform(0, 1, size=(frames, 3))
    weights[4] = np.nan
    pivot = np.array([0.5, -1.0, 0.25])
    path = tmp_path / "head.glb"
    write_animated_glb(path, c, weights, fps, head_rotation=rot.as_matrix(), pivot=pivot)
    return HeadScene(c, weights, rot, pivot, fps, path)
