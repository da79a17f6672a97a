"""The colour tracker's eye anchors calibrated on the landmark backend's eyes, and that backend shared.

Where the eye search (:mod:`.eye_anchors`) lands on an eye depends on the performer (lashes, lid shadows, brows
close above), so the generic profile's average anchors may put the layout a little off. When the landmark
backend (MediaPipe) is available, the tracker asks it once, at its first acquisition, where the eyes are, and
moves its anchors so the layout's eye centres land on them (:func:`calibrated_anchors`).

Conventions: crop pixels of one face crop (x right, y down), right eye first (as in the anchors).
"""

from __future__ import annotations

import logging
import os
import threading

import numpy as np

from facepuppet.capture.color.face import similarity_from_points
from facepuppet.errors import FacepuppetError

__all__ = ["calibrated_anchors", "shared_landmarker", "landmark_curves"]

log = logging.getLogger(__name__)

#: Landmark backends (image mode) by model path and options, made on first need and kept for the process:
#: loading the model costs far more than a tracker's whole acquisition. None: not available.
_SHARED: dict = {}
_LOCK = threading.Lock()


def calibrated_anchors(anchors: np.ndarray, found: np.ndarray, unit: float, *,
                       scale_limits: tuple[float, float] = (0.85, 1.15), noise_floor: float = 0.03,
                       max_move: float = 0.25, gain: float = 1.0) -> np.ndarray | None:
    """The anchors moved onto the eye blobs found in a crop whose layout sits on the eyes, or None when the
    evidence is not clear.

    In a face crop placed so that the layout's eye centres lie on the eyes the landmark backend sees, the
    eye blobs' centres ``found`` are where the anchors belong: the tracker's alignment of the blobs on the
    anchors then puts the layout on the eyes. The other anchors follow the similarity taking the old eye
    anchors onto the new ones; its scale is kept within ``scale_limits``.

    Parameters
    ----------
    anchors : (N, 2) float
        The tracker's anchors in crop pixels (the eyes first, right eye first).
    found : (2, 2) float
        The eye blobs' centres in crop pixels, right eye first.
    unit : float
        Crop pixels per face unit.
    noise_floor : float
        Face units: when no eye anchor would move farther, the anchors stay (None).
    max_move : float
        Face units: when an eye anchor would move farther, the blob found is not that eye (None).

    Returns
    -------
    (N, 2) float or None
    """
    anchors = np.asarray(anchors, dtype=float)
    found = np.asarray(found, dtype=float)
    if not np.isfinite(found).all():
        return None
    move = np.hypot(*(found - anchors[:2]).T).max()
    if move < noise_floor * unit or move > max_move * unit:
        return None
    T = similarity_from_points(anchors[:2], found)
    scale = float(np.hypot(*T[:, 0]))
    kept = float(np.clip(scale, *scale_limits))
    mid = found.mean(axis=0)
    T[:, :2] *= kept / scale
    T[:, 2] = mid - T[:, :2] @ anchors[:2].mean(axis=0)
    return anchors + gain * (anchors @ T[:, :2].T + T[:, 2] - anchors)


def shared_landmarker(model_path: str | os.PathLike | None, config=None):
    """The process's landmark backend (a MediaPipeTracker in image mode) for this model and options, or None
    when mediapipe or the model is missing. Made on first call; never closed by its users (at exit)."""
    key = (str(model_path) if model_path is not None else os.environ.get("FACEPUPPET_FACE_LANDMARKER", ""), config)
    with _LOCK:
        if key not in _SHARED:
            try:
                from facepuppet.capture.landmarks import MediaPipeTracker

                _SHARED[key] = MediaPipeTracker(model_path, running_mode="image", config=config)
            except (FacepuppetError, ImportError, OSError) as e:
                log.debug("no landmark backend: %s", e)
                _SHARED[key] = None
        return _SHARED[key]


def landmark_curves(landmarker, rgb: np.ndarray) -> np.ndarray | None:
    """The landmark backend's curves (C, 4, 2) in image pixels on one image, or None without a face."""
    with _LOCK:
        landmarker.reset()                  # shared: the last user's face says nothing about this image
        found = landmarker.track(rgb, 0)
    return found.curves if found.valid else None
