"""Which tracker the pipeline builds for a medium (pipeline.tracking)."""

import cv2
import numpy as np
import pytest

from facepuppet.errors import FacepuppetError
from facepuppet.pipeline.tracking import TrackerOptions, get_track, tracker_kwargs


class _Recorder:
    """A tracker factory that records its options and returns a tracker that never finds a face."""

    def __init__(self):
        self.kwargs = None

    def __call__(self, backend, **kwargs):
        from facepuppet.capture.color.tracker import ColorTracker

        self.kwargs = kwargs
        return ColorTracker()


def _run(monkeypatch, media, backend):
    import facepuppet.capture.tracking as tracking

    rec = _Recorder()
    monkeypatch.setattr(tracking, "make_tracker", rec)
    with pytest.raises(FacepuppetError, match="no face found"):     # grey frames: the tracker finds none
        get_track(media, TrackerOptions(backend=backend, model="m.task", progress=False))
    return rec.kwargs


def test_a_photograph_is_tracked_in_image_mode_a_video_in_video_mode(tmp_path, monkeypatch):
    still = tmp_path / "face.png"
    cv2.imwrite(str(still), np.full((48, 64, 3), 128, np.uint8))
    clip = tmp_path / "clip.mp4"
    out = cv2.VideoWriter(str(clip), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, (64, 48))
    for _ in range(3):
        out.write(np.full((48, 64, 3), 128, np.uint8))
    out.release()
    assert _run(monkeypatch, still, "mediapipe") == {"model_path": "m.task", "running_mode": "image"}
    assert _run(monkeypatch, clip, "mediapipe") == {"model_path": "m.task"}
    assert _run(monkeypatch, still, "color") == {}
    assert tracker_kwargs(TrackerOptions(backend="color", profile="p.npz")) == {"profile": "p.npz"}
