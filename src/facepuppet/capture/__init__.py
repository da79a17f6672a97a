"""Capture (paper §3): colour transform, blobs, Bezier snakes, head pose, feature points; landmark backend.

Trackers turn RGB frames into :class:`FrameFeatures`; :func:`make_tracker` builds one by name (``color``, the
paper's tracker, or ``mediapipe``) and :func:`track_media` runs it over a video, image or folder.
"""

from facepuppet.capture.curves import CURVE_NAMES, POINT_NAMES
from facepuppet.capture.features import FrameFeatures, Tracker
from facepuppet.capture.tracking import make_tracker, track_media

__all__ = ["CURVE_NAMES", "POINT_NAMES", "FrameFeatures", "Tracker", "make_tracker", "track_media"]
