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

__all__ = ["Track", "save_track", "load_track", "track_scalars", "check_fps", "TRACK_KEYS", "TRACK_EXTRAS",
           "PROVENANCE_KEYS", "FPS_RANGE"]

TRACK_KEYS = ("fps", "frame_size", "valid", "curves", "curve_names", "points", "point_names", "rotation",
              "translation", "backend")
#: The backends' further arrays a track file may hold (MediaPipe's blendshape scores and their names).
TRACK_EXTRAS = ("blendshapes", "blendshape_names")
#: Where the track came from (optional; files without them load with ``media = profile_hash = None``).
PROVENANCE_KEYS = ("media_size", "media_frames", "media_hash", "profile_hash", "times")
#: Largest magnitude a track's arrays may hold: pixels (curves, frame_size), centimetres (points,
#: translation), rotation matrix entries (1 plus rounding), flags; beyond it a file is damaged.
_MAX_VALUE = {"curves": 1e7, "frame_size": 1e6, "points": 1e6, "translation": 1e6, "rotation": 1.5,
              "valid": 1e18}
#: Most values a track's scalar and fixed-size members hold (checked in the header, before inflating).
_SIZES = {"fps": 1, "frame_size": 2, "backend": 1, "media_size": 1, "media_frames": 1, "media_hash": 1,
          "profile_hash": 1}
#: Frame rates a track may have, frames per second (lowest, highest).
FPS_RANGE = (0.1, 1000.0)


def check_fps(fps: float, label: str) -> float:
    """``fps`` as a float if finite and within :data:`FPS_RANGE`, else FacepuppetError naming ``label``."""
    try:
        value = float(fps)
    except (TypeError, ValueError):
        raise FacepuppetError(f"{label}: frame rate {fps!r} is not a number") from None
    lo, hi = FPS_RANGE
    if not (np.isfinite(value) and lo <= value <= hi):
        raise FacepuppetError(f"{label}: frame rate {value:g} fps is outside {lo:g} to {hi:g}")
    return value


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
    media : dict or None
        The media file tracked: ``{"size": bytes, "frames": int, "hash": str}``
        (:func:`facepuppet._util.digest.media_record`); None when unknown (a folder, a camera, an older file).
    profile_hash : str or None
        Content hash of the colour tracker's performer profile used, None when none or unknown.
    times : (F,) float or None
        Each frame's time in seconds where a variable-frame-rate video's timestamps gave it; None means
        ``index / fps``.
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
    media: dict | None = None
    profile_hash: str | None = None
    times: np.ndarray | None = None

    def __post_init__(self) -> None:
        f = len(self.valid)
        if self.times is not None:
            t = np.asarray(self.times, dtype=float)
            if t.shape != (f,) or not np.isfinite(t).all() or (f > 1 and not np.all(np.diff(t) > 0)):
                raise ValueError(f"track times must be {f} finite, increasing seconds")
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


def track_scalars(*, fps: float, frame_size, curve_names, point_names, backend: str, media: dict | None = None,
                  profile_hash: str | None = None) -> dict[str, np.ndarray]:
    """The arrays of a track file that are not per frame, as stored (shared with the streaming writer)."""
    arrays = {
        "fps": np.float64(fps),
        "frame_size": np.asarray(frame_size, dtype=np.int64),
        "curve_names": np.asarray(curve_names, dtype=str),
        "point_names": np.asarray(point_names, dtype=str),
        "backend": np.asarray(backend, dtype=str),
    }
    if media is not None:
        arrays.update(media_size=np.int64(media["size"]), media_frames=np.int64(media["frames"]),
                      media_hash=np.asarray(str(media["hash"])))
    if profile_hash is not None:
        arrays["profile_hash"] = np.asarray(str(profile_hash))
    return arrays


def save_track(path: str | os.PathLike, track: Track) -> None:
    """Write ``track`` to ``path`` (.npz, no pickle), atomically."""
    arrays = track_scalars(fps=track.fps, frame_size=track.frame_size, curve_names=track.curve_names,
                           point_names=track.point_names, backend=track.backend, media=track.media,
                           profile_hash=track.profile_hash)
    arrays.update({
        "valid": np.asarray(track.valid, dtype=bool),
        "curves": np.asarray(track.curves, dtype=np.float32),
        "points": np.asarray(track.points, dtype=np.float32),
        "rotation": np.asarray(track.rotation, dtype=np.float32),
        "translation": np.asarray(track.translation, dtype=np.float32),
    })
    if track.times is not None:
        arrays["times"] = np.asarray(track.times, dtype=np.float64)
    for key, value in (track.extras or {}).items():
        if key in arrays or key in PROVENANCE_KEYS:
            raise ValueError(f"track extra {key!r} clashes with a standard key")
        arrays[key] = np.asarray(value)
    with atomic_path(path, suffix=".npz") as tmp:
        np.savez_compressed(tmp, **arrays)


def load_track(path: str | os.PathLike) -> Track:
    """Read a track file; a missing, corrupt or incomplete file raises FacepuppetError naming it."""
    arrays = read_npz(path, "track file", known=TRACK_KEYS + TRACK_EXTRAS + PROVENANCE_KEYS, sizes=_SIZES)
    missing = [k for k in TRACK_KEYS if k not in arrays]
    if missing:
        raise FacepuppetError(f"{path}: not a track file (missing {', '.join(missing)})")
    extras = {k: v for k, v in arrays.items() if k in TRACK_EXTRAS}
    media = None
    if all(k in arrays for k in ("media_size", "media_frames", "media_hash")):
        media = {"size": int(arrays["media_size"]), "frames": int(arrays["media_frames"]),
                 "hash": str(arrays["media_hash"])}
    try:
        fps = check_fps(arrays["fps"], f"{path}")
        if arrays["fps"].size != 1 or arrays["frame_size"].shape != (2,) or arrays["valid"].ndim != 1:
            raise ValueError("fps, frame_size or valid has the wrong shape")
        for key in ("curves", "points", "rotation", "translation", "frame_size", "valid"):
            if arrays[key].dtype.kind not in ("biu" if key == "valid" else "fiu"):
                raise ValueError(f"{key} does not hold {'flags' if key == 'valid' else 'numbers'}")
            finite = arrays[key][np.isfinite(arrays[key])] if arrays[key].dtype.kind == "f" else arrays[key]
            if finite.size and np.abs(finite).max() > _MAX_VALUE[key]:
                raise ValueError(f"{key} holds values beyond ±{_MAX_VALUE[key]:g}")
        if (arrays["frame_size"] < 0).any():
            raise ValueError(f"frame_size must not be negative, got {arrays['frame_size'].tolist()}")
        return Track(
            fps=fps,
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
            media=media,
            profile_hash=str(arrays["profile_hash"]) if "profile_hash" in arrays else None,
            times=arrays["times"].astype(float) if "times" in arrays else None,
        )
    except (ValueError, TypeError, IndexError, KeyError) as e:
        raise FacepuppetError(f"{path}: inconsistent track file ({e})") from e
