"""Where the pipeline asks the capture stage for a track: which tracker (:class:`TrackerOptions`), made how."""

from __future__ import annotations

import os
from dataclasses import dataclass

from facepuppet.io.track import Track

__all__ = ["TrackerOptions", "get_track", "tracker_kwargs", "make_tracker_for"]


@dataclass(frozen=True, kw_only=True)
class TrackerOptions:
    """Which tracker makes the features.

    Attributes
    ----------
    backend : str
        ``"color"`` (the paper's tracker) or ``"mediapipe"`` (landmark backend, optional extra).
    profile : str or None
        Performer profile of the colour tracker (``facepuppet track --profile``).
    model : str or None
        MediaPipe Face Landmarker ``.task`` file; default ``$FACEPUPPET_FACE_LANDMARKER``.
    progress : bool or None
        Progress bar; None shows it when stderr is a terminal.
    """

    backend: str = "color"
    profile: str | None = None
    model: str | None = None
    progress: bool | None = None


def tracker_kwargs(options: TrackerOptions) -> dict:
    """The constructor options of the chosen backend."""
    if options.backend == "mediapipe":
        return {"model_path": options.model}
    if options.backend == "color" and options.profile is not None:
        return {"profile": options.profile}
    return {}


def make_tracker_for(options: TrackerOptions, media=None):
    """The chosen backend, set up for ``media`` (a still photograph gets MediaPipe's image mode)."""
    from facepuppet.capture.tracking import make_tracker
    from facepuppet.io.frames import is_still

    kwargs = tracker_kwargs(options)
    if options.backend == "mediapipe" and isinstance(media, (str, os.PathLike)) and is_still(media):
        kwargs["running_mode"] = "image"   # one photograph: no video to follow the face through
    return make_tracker(options.backend, **kwargs)


def get_track(media: str | os.PathLike, options: TrackerOptions, *, max_frames: int | None = None) -> Track:
    """Track ``media`` with the chosen backend (see :mod:`facepuppet.capture.tracking`)."""
    from facepuppet.capture.tracking import track_media

    tracker = make_tracker_for(options, media)
    try:
        return track_media(media, tracker, progress=options.progress is not False, max_frames=max_frames)
    finally:
        tracker.close()
