"""The tracking loop and the backend table."""

import cv2
import numpy as np
import pytest

from facepuppet.capture.curves import CURVE_NAMES, POINT_NAMES
from facepuppet.capture.features import FrameFeatures
from facepuppet.capture.tracking import make_tracker, track_media
from facepuppet.errors import FacepuppetError


def write_video(path, n=6, size=(64, 48)):
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, size)
    for i in range(n):
        w.write(np.full((size[1], size[0], 3), 20 * i, np.uint8))
    w.release()
    return path


class EveryOther:
    name = "dummy"
    static_extras = {"labels": np.array(["a", "b"])}

    def track(self, rgb, timestamp_ms):
        k = timestamp_ms // 33
        if k % 2:
            return FrameFeatures.lost(len(CURVE_NAMES), len(POINT_NAMES), extras={"score": np.full(2, np.nan)})
        return FrameFeatures(True, np.full((12, 4, 2), float(k)), np.eye(3), np.zeros(3), np.ones((48, 3)),
                             extras={"score": np.array([k, 1.0])})

    def close(self):
        pass


class Never(EveryOther):
    def track(self, rgb, timestamp_ms):
        return FrameFeatures.lost(len(CURVE_NAMES), len(POINT_NAMES))


def test_track_media_marks_lost_frames_and_stacks_extras(tmp_path):
    track = track_media(write_video(tmp_path / "v.mp4"), EveryOther(), progress=False)
    assert track.n_frames == 6 and track.backend == "dummy"
    assert list(track.valid) == [True, False] * 3
    assert np.isnan(track.curves[1]).all() and track.curves[2, 0, 0, 0] == 2
    assert track.extras["score"].shape == (6, 2) and np.isnan(track.extras["score"][1]).all()
    assert list(track.extras["labels"]) == ["a", "b"]
    assert tuple(track.frame_size) == (64, 48)


def test_max_frames_and_on_frame(tmp_path):
    seen = []
    track = track_media(write_video(tmp_path / "v.mp4"), EveryOther(), progress=False, max_frames=3,
                        on_frame=lambda i, rgb, f: seen.append((i, rgb.shape, f.valid)))
    assert track.n_frames == 3 and [s[0] for s in seen] == [0, 1, 2]


def test_face_free_video_is_an_error(tmp_path):
    with pytest.raises(FacepuppetError, match="no face"):
        track_media(write_video(tmp_path / "v.mp4"), Never(), progress=False)


def test_unknown_backend():
    with pytest.raises(ValueError, match="unknown tracker backend"):
        make_tracker("sonar")
