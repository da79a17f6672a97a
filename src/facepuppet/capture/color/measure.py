"""What one measurement of the colour tracker in a face frame gives (:meth:`ColorTracker.measure`), and where
the layout sits on the crop (:class:`Placement`, shared by the tracker and its acquisition).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from facepuppet.capture.color.face import FaceFrame

__all__ = ["Measurement", "Placement"]


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
    held_back : bool
        Whether the eyes pulled the frame past the largest size it may take (``largest`` of
        :meth:`~.tracker.ColorTracker.measure`), where it was kept.
    """

    curves: np.ndarray | None
    frame: FaceFrame
    eyes_found: bool
    score: float
    correction: np.ndarray
    seen: tuple[np.ndarray, np.ndarray, np.ndarray] | None
    held_back: bool = False


@dataclass
class Placement:
    """Where the layout sits on the face crop; changed by acquisition and by each measurement.

    Attributes
    ----------
    anchors_px : (3, 2) float64
        The anchors the face frame is aligned on (:data:`~facepuppet.capture.color.profile.ANCHOR_NAMES`), crop
        pixels.
    anchor_mid : (2,) float64
        Midpoint of the eye anchors.
    calibrated : bool
        Whether the anchors were calibrated on the landmark backend's eyes (or need not be).
    shift : (2,) float64
        Crop pixels the eyes' correction moves the rectangles that follow the eyes.
    mouth_offset : (2,) float64
        Crop pixels the mouth sits off the layout (set by the landmark backend at acquisition).
    scale : float
        Size of the face the eyes' correction found, as a share of the crop's face unit.
    light : (3, 3) float64 or None
        Colour transform evening out the light (set at acquisition), or None.
    skinless_ok : bool
        Accept crops whose cheeks do not look like skin (while settling a frame the landmark backend placed).
    skin_doubted : bool
        Take the crops' cheeks for no skin, whatever they look like (while trying a cascade window whose middle looked
        like skin in no light: in the light made to give it a skin's colour, its cheeks' skin is no evidence).
    """

    anchors_px: np.ndarray
    anchor_mid: np.ndarray
    calibrated: bool
    shift: np.ndarray = field(default_factory=lambda: np.zeros(2))
    mouth_offset: np.ndarray = field(default_factory=lambda: np.zeros(2))
    scale: float = 1.0
    light: np.ndarray | None = None
    skinless_ok: bool = False
    skin_doubted: bool = False

    @property
    def light_gain(self) -> float:
        """How much the light transform stretches the crop's levels (the mean of its channel gains), at least 1:
        the crop's noise grows by as much (a dim frame brightened shows its sensor noise and its coding steps
        larger)."""
        if self.light is None:
            return 1.0
        return max(float(np.mean(np.diag(np.asarray(self.light)[:, :3]))), 1.0)

    def set_anchors(self, anchors_px: np.ndarray) -> None:
        """New anchors (3, 2), crop pixels, and their eyes' midpoint."""
        self.anchors_px = np.asarray(anchors_px, dtype=float)
        self.anchor_mid = self.anchors_px[:2].mean(axis=0)
