"""Synthetic tracks for the tests of capturing key expressions: known feature points, the standard curves."""

from __future__ import annotations

import numpy as np

from facepuppet.capture.curves import CURVE_NAMES, POINT_NAMES
from facepuppet.io.track import Track

FPS = 30.0
P = len(POINT_NAMES)


def make_track(points: np.ndarray, valid: np.ndarray | None = None, extras: dict | None = None) -> Track:
    """A track at :data:`FPS` with these feature points (NaN where not ``valid``), upright head pose."""
    f = len(points)
    valid = np.ones(f, bool) if valid is None else valid
    points = np.where(valid[:, None, None], points, np.nan)
    return Track(fps=FPS, frame_size=np.array([64, 64]), valid=valid,
                 curves=np.zeros((f, len(CURVE_NAMES), 4, 2)), curve_names=CURVE_NAMES, points=points,
                 point_names=POINT_NAMES, rotation=np.tile(np.eye(3), (f, 1, 1)), translation=np.zeros((f, 3)),
                 backend="test", extras=extras)
