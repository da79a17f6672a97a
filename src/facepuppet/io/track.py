"""The track file (DESIGN.md, "Track file"): what `facepuppet track` writes and later stages read.

A track holds, per frame, the Bezier control points of every feature curve in image pixels (x right, y down),
the feature points in head coordinates (head pose removed: the mapping's input), and the head pose in camera
coordinates. Frames where no face was tracked have ``valid = False`` and NaN in every per-frame array but
``valid``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from facepuppet._util.atomic import atomic_path
from facepuppet._util.npz import read_npz
from facepuppet.errors import FacepuppetError

__all__ = ["Track", "save_track", "load_track", "TRACK_KEYS"]

TRACK_KEYS = ("fps", "frame_size", "valid", "curves", "curve_names", "points", "point_names", "rotation",
              "translation", "backend")


@dataclass(frozen=True)
class Track:
    """A tracked performance.

    Attributes
    ----------
    fps : float
    frame_size : (2,) int, width and height in pixels
    valid : (F,) bool
    curves : (F, C, 4, 2) float, NaN where not valid
    curve_names : tuple of C str
    points : (F, P, 3) float, head coordinates, NaN where not valid
    point_names : tuple of P str
    rotation : (F, 3, 3) float, head-to-camera rotation
    translation : (F, 3) float, head origin in camera coordinates
    backend : str
    extras : dict of str -> ndarray, further per-frame arrays a backend adds (for example ``blendshapes``)
    """

    fps: float
    frame_size: np.ndarray
    valid: np.ndarray
    curves: np.ndarray
    curve_names: tuple[str, ...]
    points: np.ndarray
    point_names: tuple[str, ...]
    rotation: np.ndarray
    translation: np.ndarray
    backend: str
    extras: dict | None = None

    def __post_init__(self) -> None:
        f = len(self.valid)
        checks = {
            "curves": (self.curves, (f, len(self.curve_names), 4, 2)),
            "points": (self.points, (f, len(self.point_names), 3)),
            "rotation": (self.rotation, (f, 3, 3)),
            "translation": (self.translation, (f, 3)),
        }
        for name, (arr, shape) in checks.items():
            if np.shape(arr) != shape:
                raise ValueError(f"track {name} must have shape {shape}, got {np.shape(arr)}")

    @property
    def n_frames(self) -> int:
        return len(self.valid)


def save_track(path: str | os.PathLike, track: Track) -> None:
    """Write ``track`` to ``path`` (.npz, no pickle), atomically."""
    arrays = {
        "fps": np.float64(track.fps),
        "frame_size": np.asarray(track.frame_size, dtype=np.int64),
        "valid": np.asarray(track.valid, dtype=bool),
        "curves": np.asarray(track.curves, dtype=np.float32),
        "curve_names": np.asarray(track.curve_names, dtype=str),
        "points": np.asarray(track.points, dtype=np.float32),
        "point_names": np.asarray(track.point_names, dtype=str),
        "rotation": np.asarray(track.rotation, dtype=np.float32),
        "translation": np.asarray(track.translation, dtype=np.float32),
        "backend": np.asarray(track.backend, dtype=str),
    }
    for key, value in (track.extras or {}).items():
        if key in arrays:
            raise ValueError(f"track extra {key!r} clashes with a standard key")
        arrays[key] = np.asarray(value)
    with atomic_path(path, suffix=".npz") as tmp:
        np.savez_compressed(tmp, **arrays)


def load_track(path: str | os.PathLike) -> Track:
    """Read a track file; a missing, corrupt or incomplete file raises FacepuppetError naming it."""
    arrays = read_npz(path, "track file")
    missing = [k for k in TRACK_KEYS if k not in arrays]
    if missing:
        raise FacepuppetError(f"{path}: not a track file (missing {', '.join(missing)})")
    extras = {k: v for k, v in arrays.items() if k not in TRACK_KEYS}
    try:
        return Track(
            fps=float(arrays["fps"]),
            frame_size=arrays["frame_size"].astype(int),
            valid=arrays["valid"].astype(bool),
            curves=arrays["curves"].astype(float),
            curve_names=tuple(str(n) for n in arrays["curve_names"]),
            points=arrays["points"].astype(float),
            point_names=tuple(str(n) for n in arrays["point_names"]),
            rotation=arrays["rotation"].astype(float),
            translation=arrays["translation"].astype(float),
            backend=str(arrays["backend"]),
            extras=extras or None,
        )
    except ValueError as e:
        raise FacepuppetError(f"{path}: inconsistent track file ({e})") from e
