"""What a tracker hands on for one frame, and the interface every tracker backend implements.

Conventions (DESIGN.md): curves in image pixels, x right, y down; head pose as a head-to-camera rotation and
the head origin in camera coordinates (OpenCV camera: x right, y down, z forward, centimetres); feature points
in head coordinates (:mod:`facepuppet.capture.pose`: x to the performer's left, y up, z out of the face, cm).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

__all__ = ["FrameFeatures", "Tracker"]


@dataclass(frozen=True)
class FrameFeatures:
    """The features tracked in one frame.

    Attributes
    ----------
    valid : bool
        A face was tracked in this frame. When False every array below is NaN.
    curves : (C, 4, 2) float
        Cubic Bezier control points of each feature curve, in :data:`~facepuppet.capture.curves.CURVE_NAMES`
        order, image pixels.
    rotation : (3, 3) float
        Head-to-camera rotation: ``x_cam = rotation @ x_head + translation``.
    translation : (3,) float
        Head origin in camera coordinates, cm.
    points : (P, 3) float
        Feature points in head coordinates (head pose removed), in
        :data:`~facepuppet.capture.curves.POINT_NAMES` order.
    extras : dict of str -> ndarray, optional
        Further per-frame arrays of a backend (for example ``blendshapes`` (52,)); the track file gets one
        ``(F, ...)`` array per key.
    """

    valid: bool
    curves: np.ndarray
    rotation: np.ndarray
    translation: np.ndarray
    points: np.ndarray
    extras: dict | None = None

    @classmethod
    def lost(cls, n_curves: int, n_points: int, extras: dict | None = None) -> FrameFeatures:
        """A frame where no face was tracked: ``valid=False`` and NaN arrays of the right shapes."""
        nan = np.nan
        return cls(
            valid=False,
            curves=np.full((n_curves, 4, 2), nan),
            rotation=np.full((3, 3), nan),
            translation=np.full(3, nan),
            points=np.full((n_points, 3), nan),
            extras=extras,
        )


@runtime_checkable
class Tracker(Protocol):
    """A tracker backend: turns RGB frames, one at a time and in order, into :class:`FrameFeatures`.

    Attributes
    ----------
    name : str
        The backend's name as written to the track file (``"color"``, ``"mediapipe"``).
    """

    name: str

    def track(self, rgb: np.ndarray, timestamp_ms: int) -> FrameFeatures:
        """Track one frame.

        Parameters
        ----------
        rgb : (H, W, 3) uint8
            The frame, RGB order.
        timestamp_ms : int
            Its time in milliseconds, increasing from frame to frame.

        Returns
        -------
        FrameFeatures
            ``FrameFeatures.lost(...)`` when the face is not found; never raises for a face-free frame.
        """
        ...

    def close(self) -> None:
        """Release the backend's resources."""
        ...
