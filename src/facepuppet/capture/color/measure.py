"""What one measurement of the colour tracker in a face frame gives (:meth:`ColorTracker.measure`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from facepuppet.capture.color.face import FaceFrame

__all__ = ["Measurement"]


@dataclass(frozen=True)
class Measurement:
    """One frame measured in one face frame.

    Attributes
    ----------
    curves : (C, 4, 2) float64 or None
        The feature curves in image pixels; None when only the face frame was re-aligned.
    frame : FaceFrame
        The face frame re-aligned on the eyes.
    eyes_found : bool
        Whether the eye search found both eyes (else the frame kept its correction).
    score : float
        Likeness of the crop to a face (correlation with the layout drawn as a face, in [-1, 1]; 1.0 when
        following a face whose cheeks look like skin, where it is not computed).
    correction : (4,) float64
        The eyes' smoothed correction of the face frame, a similarity (a, b, tx, ty) in crop pixels.
    seen : tuple or None
        What the curves were read on: (face crop (H, W, 3) uint8, its crop matrix (2, 3), the layout placed on
        the crop (C, 4, 2)), or None without curves.
    """

    curves: np.ndarray | None
    frame: FaceFrame
    eyes_found: bool
    score: float
    correction: np.ndarray
    seen: tuple[np.ndarray, np.ndarray, np.ndarray] | None
