"""The tracking loop and the backend table, with a scripted tracker on generated videos."""

import cv2
import numpy as np
import pytest

from facepuppet.capture import tracking
from facepuppet.capture.curves import CURVE_NAMES, POINT_NAMES
from facepuppet.capture.features import FrameFeatures
from facepuppet.capture.tracking import BACKENDS, make_tracker, track_media
from facepuppet.errors import FacepuppetError
from facepuppet.io.frames import open_media


def write_video(path, n, size=(64, 48), fps=25.0):
    """A video whose frame k is grey level 10 * k (so a tracker can tell the frames apart)."""
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, size)
    for k in range(n):
        w.write(np.full((size[1], size[0], 3), 10 * k, np.uint8))
    w.release()
    return path


class Scripted:
    """Tracks a face in the frames listed in ``faces``; curves hold the frame index, extras a score."""

    name = "scripted"

    def __init__(self, faces):
        self.faces = set(faces)
        self.calls = []
        self.static_extras = {"score_names": np.array(["a", "b"])}

    def track(self, rgb, timestamp_ms):
        k = len(self.calls)
        self.calls.append(timestamp_ms)
        if k not in self.faces:
            return FrameFeatures.lost(len(CURVE_NAMES), len(POINT_NAMES),
                                      extras={"score": np.full(2, np.nan, np.float32)})
        return FrameFeatures(valid=True, curves=np.full((len(CURVE_NAMES), 4, 2), float(k)),
                             rotation=np.eye(3), translation=np.array([0.0, 0.0, 50.0 + k]),
                             points=np.full((len(POINT_NAMES), 3), float(k)),
                             extras={"score": np.array([k, 2 * k], np.float32)})

    def close(self):
        pass


def test_backends_table():
    assert set(BACKENDS) == {"color", "mediapipe"}
    assert tracking.DEFAULT_BACKEND == "color"


def test_unknown_backend_names_the_choices():
    with pytest.raises(ValueError, match="'kinect'.*color, mediapipe"):
        make_tracker("kinect")


def test_backend_module_missing_is_a_clear_error(monkeypatch):
    monkeypatch.setitem(tracking.BACKENDS, "color", ("facepuppet.capture._no_such_module", "X"))
    with pytest.raises(FacepuppetError, match="'color' is not available"):
        make_tracker("color")


def test_make_tracker_passes_options(face_landmarker):
    from facepuppet.capture.landmarks import MediaPipeTracker

    with make_tracker("mediapipe", model_path=face_landmarker, running_mode="image") as t:
        assert isinstance(t, MediaPipeTracker) and t.name == "mediapipe" and t.running_mode == "image"


def test_track_media_stacks_frames_and_marks_lost_ones(tmp_path):
    video = write_video(tmp_path / "v.mp4", 6)
    tracker = Scripted(faces=[1, 2, 4])
    seen = []
    track = track_media(video, tracker, progress=False, on_frame=lambda i, rgb, f: seen.append((i, f.valid)))
    assert track.n_frames == 6 and track.backend == "scripted" and track.fps == pytest.approx(25.0)
    assert tuple(track.frame_size) == (64, 48)
    np.testing.assert_array_equal(track.valid, [False, True, True, False, True, False])
    assert seen == [(i, i in (1, 2, 4)) for i in range(6)]
    assert tracker.calls == [0, 40, 80, 120, 160, 200]  # milliseconds at 25 fps
    for k in (1, 2, 4):
        assert (track.curves[k] == k).all() and (track.points[k] == k).all()
        assert track.translation[k, 2] == 50 + k
    for arr in (track.curves, track.points, track.rotation, track.translation):
        assert np.isnan(arr[~track.valid]).all()
    np.testing.assert_array_equal(track.extras["score"][4], [4, 8])
    assert np.isnan(track.extras["score"][0]).all()
    np.testing.assert_array_equal(track.extras["score_names"], ["a", "b"])
    assert track.curve_names == CURVE_NAMES and track.point_names == POINT_NAMES


def test_max_frames_and_an_open_source(tmp_path):
    video = write_video(tmp_path / "v.mp4", 6)
    with open_media(video) as src:
        track = track_media(src, Scripted(faces=range(6)), progress=False, max_frames=3)
    assert track.n_frames == 3 and track.valid.all()
    with pytest.raises(ValueError, match="max_frames"):
        track_media(video, Scripted(faces=[0]), progress=False, max_frames=0)


def test_face_free_video_is_an_error(tmp_path):
    video = write_video(tmp_path / "blank.mp4", 4)
    with pytest.raises(FacepuppetError, match=r"blank\.mp4: no face found in any of its 4 frame"):
        track_media(video, Scripted(faces=[]), progress=False)


def test_tracker_of_the_wrong_shapes_is_refused(tmp_path):
    class Wrong(Scripted):
        def track(self, rgb, timestamp_ms):
            return FrameFeatures.lost(3, 5)

    with pytest.raises(ValueError, match="'scripted' returned curves"):
        track_media(write_video(tmp_path / "v.mp4", 2), Wrong([]), progress=False)


def test_unreadable_medium_is_named(tmp_path):
    bad = tmp_path / "bad.mp4"
    bad.write_bytes(b"\x00not a video" * 100)
    with pytest.raises(FacepuppetError, match=r"bad\.mp4"):
        track_media(bad, Scripted(faces=[0]), progress=False)


def test_mediapipe_tracks_a_real_clip(assets, face_landmarker):
    clip = assets / "video" / "performer_c.mp4"
    with make_tracker("mediapipe", model_path=face_landmarker) as t:
        track = track_media(clip, t, progress=False, max_frames=12)
    assert track.n_frames == 12 and track.valid.all() and track.backend == "mediapipe"
    assert track.extras["blendshapes"].shape == (12, 52)
    # a steady face: the curves move little between neighbouring frames (well under 2 % of the frame)
    step = np.abs(np.diff(track.curves, axis=0)).max()
    assert step < 0.02 * track.frame_size.max()
