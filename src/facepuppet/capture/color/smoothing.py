"""Smoothing the colour tracker's face frame and curves over time (speed-adaptive One-Euro filters).

Still points are smoothed hard and fast ones followed at once (the cut-off frequency rises with the speed), so
small noise is damped without visible lag on fast expressions. The curves are filtered in face units of the
frame they were measured in, the face frame itself (eye midpoint and eye-to-eye vector) in face units too.
"""

from __future__ import annotations

import numpy as np

from facepuppet.capture.color.config import FilterConfig
from facepuppet.capture.color.face import FaceFrame
from facepuppet.capture.color.lids import EYES
from facepuppet.capture.curves import CURVE_NAMES
from facepuppet.filters import OneEuro

__all__ = ["CurveSmoother"]

_LIDS = np.ravel(EYES)                                     # the eyelids' curves
_LIP_CURVES = np.array([i for i, n in enumerate(CURVE_NAMES) if n.startswith("lip_")])   # the lips' curves


class CurveSmoother:
    """The filters of one tracker.

    Parameters
    ----------
    config : FilterConfig
    lids : bool
        Whether the eyelids' middle control points get their own filter (the profile's eyelid model reads them).
    shaped : (N,) int
        The curves the profile's shape models read (their own filter, or none).
    """

    def __init__(self, config: FilterConfig, *, lids: bool, shaped: np.ndarray):
        self.enabled = config.enabled
        self.curve = OneEuro(config.curve)
        self.lid = OneEuro(config.lid)
        self.lip = OneEuro(config.lip)
        self.shape = None if config.shape is None else OneEuro(config.shape)
        self.frame = OneEuro(config.frame)
        self.lids = lids
        self.shaped = shaped
        #: The lip curves of the lip filter (those no shape model reads).
        self.lip_curves = np.setdiff1d(_LIP_CURVES, shaped)
        self.last_ms: int | None = None

    def reset(self) -> None:
        """Restart every filter (the next sample is taken as it is)."""
        self.curve.reset()
        self.lid.reset()
        self.lip.reset()
        if self.shape is not None:
            self.shape.reset()
        self.frame.reset()

    def __call__(self, curves: np.ndarray, measured: FaceFrame, timestamp_ms: int) -> np.ndarray:
        """The curves (C, 4, 2) image pixels measured in face frame ``measured`` at ``timestamp_ms``, smoothed
        (image pixels); the filters restart when time does not move forward."""
        last, self.last_ms = self.last_ms, timestamp_ms
        if not self.enabled:
            return curves
        dt = (timestamp_ms - last) / 1000.0 if last is not None else 0.0
        if not dt > 0:
            self.reset()
        # Image pixels -> face units: the inverse of the frame's similarity [[ax, -ay], [ay, ax]] is its
        # transpose over the squared unit.
        ax, ay = measured.axis.tolist()
        u2 = ax * ax + ay * ay
        units = (curves - measured.origin) @ np.array([[ax / u2, -ay / u2], [ay / u2, ax / u2]])
        fr = self.frame(np.array([measured.origin, measured.axis]), dt, measured.unit)
        smooth = self.curve(units, dt)
        if len(self.lip_curves):
            smooth[self.lip_curves] = self.lip(units[self.lip_curves], dt)
        if self.lids:
            smooth[_LIDS, 1:3] = self.lid(units[_LIDS, 1:3], dt)
        if len(self.shaped):
            shaped = units[self.shaped]
            smooth[self.shaped] = shaped if self.shape is None else self.shape(shaped, dt)
        (ox, oy), (ax, ay) = fr.tolist()
        return smooth @ np.array([[ax, ay], [-ay, ax]]) + np.array([ox, oy])
