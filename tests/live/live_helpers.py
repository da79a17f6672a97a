"""Small characters and frames for the live tests."""

from __future__ import annotations

import importlib.util
import os
import time

import numpy as np
import pytest

from facepuppet.io.character import Character
from facepuppet.live import LiveFrame


def grid_character(n: int = 12, names=("jawOpen", "mouthSmile_L", "eyeBlink_L")) -> Character:
    """A square (n x n vertices) bent like a mask, y up, facing +z, with one key-model per name."""
    u, v = np.meshgrid(np.linspace(-1, 1, n), np.linspace(-1, 1, n))
    neutral = np.stack([u.ravel(), v.ravel(), 0.4 * (1 - u.ravel() ** 2)], axis=1)
    targets = []
    for k in range(len(names)):
        d = np.zeros_like(neutral)
        d[:, 1] = -0.3 * np.exp(-((neutral[:, 0] - 0.5 * (k - 1)) ** 2 + (neutral[:, 1] + 0.5) ** 2) * 4)
        targets.append(neutral + d)
    quads = [(i * n + j, i * n + j + 1, (i + 1) * n + j + 1, (i + 1) * n + j)
             for i in range(n - 1) for j in range(n - 1)]
    faces = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
    return Character(neutral=neutral, targets=np.array(targets), names=tuple(names), faces=faces, name="grid")


def live_frame(names, weights, *, index=0, fps=30.0, head=None, image=None, curves=None) -> LiveFrame:
    return LiveFrame(index=index, time=index / fps, timestamp=time.perf_counter(),
                     weights=np.asarray(weights, dtype=float), names=tuple(names), head_rotation=head,
                     image=image, curves=curves)


def require(module: str, why: str) -> None:
    """Skip the calling test module unless ``module`` can be imported; with ``CI=true`` fail instead."""
    if importlib.util.find_spec(module) is None:
        if os.environ.get("CI", "").lower() in ("1", "true", "yes"):
            pytest.fail(f"CI must run this test, but {why}", pytrace=False)
        pytest.skip(why, allow_module_level=True)
