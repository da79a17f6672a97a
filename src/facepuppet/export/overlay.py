"""What was tracked, drawn on the frames: the feature curves and the head's axes."""

from __future__ import annotations

import os

import numpy as np

from facepuppet._util.atomic import atomic_path
from facepuppet.capture.curves import bezier_points
from facepuppet.capture.features import FrameFeatures
from facepuppet.capture.pose import default_camera
from facepuppet.errors import FacepuppetError
from facepuppet.io.frames import MediaSource, open_media
from facepuppet.io.track import Track

__all__ = ["draw_overlay", "OverlayWriter", "write_overlay_video", "AXIS_COLOURS", "CURVE_COLOUR"]

#: RGB colours of the head's x (performer's left), y (up) and z (out of the face) axes.
AXIS_COLOURS = ((230, 40, 40), (40, 200, 40), (60, 90, 255))
#: RGB colour of the feature curves.
CURVE_COLOUR = (255, 230, 0)
#: Drawn length of the head axes, cm.
_AXIS_LENGTH = 5.0


def draw_overlay(rgb: np.ndarray, features: FrameFeatures, *, focal: float | None = None) -> np.ndarray:
    """Draw the curves and the head axes of one frame on a copy of it.

    Parameters
    ----------
    rgb : (H, W, 3) uint8
    features : FrameFeatures
        A lost frame (``valid=False``) gets a small "no face" mark instead.
    focal : float, optional
        Focal length of the camera the pose was solved with (default as in
        :func:`~facepuppet.capture.pose.default_camera`).

    Returns
    -------
    (H, W, 3) uint8
    """
    import cv2

    out = np.ascontiguousarray(rgb, dtype=np.uint8).copy()
    h, w = out.shape[:2]
    thick = max(1, round(max(h, w) / 400))
    if not features.valid:
        cv2.putText(out, "no face", (8, 24), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (255, 60, 60), thick, cv2.LINE_AA)
        return out
    curves = np.asarray(features.curves, dtype=float)
    ok = np.isfinite(curves).all(axis=(1, 2))
    if ok.any():
        polys = np.round(bezier_points(curves[ok], 24)).astype(np.int32)
        cv2.polylines(out, list(polys), False, CURVE_COLOUR, thick, cv2.LINE_AA)
    R, t = np.asarray(features.rotation, dtype=float), np.asarray(features.translation, dtype=float)
    if np.isfinite(R).all() and np.isfinite(t).all() and t[2] > 0:
        K = default_camera((w, h), focal)
        ends = np.vstack([np.zeros(3), _AXIS_LENGTH * np.eye(3)]) @ R.T + t
        if (ends[:, 2] > 0).all():
            uv = ends @ K.T
            uv = uv[:, :2] / uv[:, 2:3]
            if np.isfinite(uv).all() and np.abs(uv).max() < 1e5:
                o = tuple(np.round(uv[0]).astype(int))
                for k in range(3):
                    cv2.arrowedLine(out, o, tuple(np.round(uv[k + 1]).astype(int)), AXIS_COLOURS[k], thick + 1,
                                    cv2.LINE_AA, tipLength=0.15)
    return out


def _frame_features(track: Track, i: int) -> FrameFeatures:
    return FrameFeatures(valid=bool(track.valid[i]), curves=track.curves[i], rotation=track.rotation[i],
                         translation=track.translation[i], points=track.points[i])


class OverlayWriter:
    """An MP4 of overlaid frames written one frame at a time, appearing at ``path`` only when closed cleanly.

    Use as a context manager; an exception inside the block leaves no file behind.

    Parameters
    ----------
    path : str or PathLike
    frame_size : (int, int)
        Width and height.
    fps : float
    focal : float, optional
        See :func:`draw_overlay`.
    """

    def __init__(self, path: str | os.PathLike, frame_size: tuple[int, int], fps: float, *,
                 focal: float | None = None):
        self.path = path
        self.frame_size = (int(frame_size[0]), int(frame_size[1]))
        self.fps = float(fps)
        self.focal = focal
        self.n_frames = 0
        self._atomic = None
        self._writer = None

    def __enter__(self) -> OverlayWriter:
        import cv2

        self._atomic = atomic_path(self.path, suffix=".mp4")
        tmp = self._atomic.__enter__()
        self._tmp = tmp
        self._writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"mp4v"), self.fps, self.frame_size)
        if not self._writer.isOpened():
            self.__exit__(FacepuppetError, None, None)
            raise FacepuppetError(f"{self.path}: cannot write an MP4 video here")
        return self

    def write(self, rgb: np.ndarray, features: FrameFeatures) -> None:
        """Draw ``features`` on ``rgb`` (H, W, 3) uint8 and append it."""
        import cv2

        if (rgb.shape[1], rgb.shape[0]) != self.frame_size:
            raise FacepuppetError(f"{self.path}: frame of {rgb.shape[1]}x{rgb.shape[0]} in a video of "
                                  f"{self.frame_size[0]}x{self.frame_size[1]}")
        self._writer.write(cv2.cvtColor(draw_overlay(rgb, features, focal=self.focal), cv2.COLOR_RGB2BGR))
        self.n_frames += 1

    def __exit__(self, exc_type, exc, tb) -> None:
        if self._writer is not None:
            self._writer.release()
            self._writer = None
        if self._atomic is not None:
            atomic, self._atomic = self._atomic, None
            if exc_type is None:
                try:
                    if self.n_frames == 0:
                        raise FacepuppetError(f"{self.path}: no frames to write")
                    from facepuppet.export.preview import check_video

                    check_video(self._tmp, self.n_frames, label=self.path)   # a full disk is told here
                except FacepuppetError as e:
                    atomic.__exit__(type(e), e, None)
                    raise
            atomic.__exit__(exc_type, exc, tb)


def write_overlay_video(path: str | os.PathLike, media: str | os.PathLike | MediaSource, track: Track, *,
                        focal: float | None = None) -> None:
    """Write an MP4 of ``media``'s frames with ``track`` drawn on them, atomically.

    Frames beyond the track's length are not written. Raises FacepuppetError if the video cannot be written
    or the medium's frame size differs from the track's.
    """
    own = not isinstance(media, MediaSource)
    source = open_media(media) if own else media
    try:
        w, h = source.frame_size
        if (w, h) != tuple(int(v) for v in track.frame_size):
            raise FacepuppetError(f"{source.path}: frame size {w}x{h} differs from the track's "
                                  f"{track.frame_size[0]}x{track.frame_size[1]}")
        with OverlayWriter(path, (w, h), track.fps, focal=focal) as out:
            for i, rgb in enumerate(source):
                if i >= track.n_frames:
                    break
                out.write(rgb, _frame_features(track, i))
    finally:
        if own:
            source.close()
