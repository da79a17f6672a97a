"""The landmark backend: MediaPipe Face Landmarker as a :class:`~facepuppet.capture.features.Tracker`.

mediapipe is an optional extra (``pip install facepuppet[mediapipe]``): it is imported when a tracker is made,
not when this package is.
"""

from facepuppet.capture.landmarks.mediapipe import (
    BLENDSHAPE_NAMES,
    MODEL_ENV,
    MP_CURVES,
    MP_POSE_LANDMARKS,
    MediaPipeConfig,
    MediaPipeTracker,
    curves_from_landmarks,
    resolve_model_path,
)

__all__ = ["BLENDSHAPE_NAMES", "MODEL_ENV", "MP_CURVES", "MP_POSE_LANDMARKS", "MediaPipeConfig", "MediaPipeTracker",
           "curves_from_landmarks", "resolve_model_path"]
