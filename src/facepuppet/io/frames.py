"""Frame sources: one reader over a video file, a still image, a folder of images, or a camera.

Every source yields RGB uint8 frames of shape (H, W, 3) lazily, knows its frame rate and frame size, and is a
context manager. A camera is named ``camera:N`` (device N); tests stand a video file in for it with
``camera:path/to/video.mp4``.

Frame times: a video file's source records the container's timestamp of the frame last read
(``last_time``, seconds, from ``CAP_PROP_POS_MSEC``); :func:`frame_time` uses it where it differs from
``index / fps`` by half a frame or more (variable-frame-rate video), else ``index / fps``.

Decoder threads: FFmpeg decodes a video file on its own threads (one per core by default, decoding frames ahead
of the reader), or on ``decode_threads`` of them (:func:`open_media`; 1: on the reading thread alone, between
two reads); else on ``OPENCV_FFMPEG_THREADS`` of them when that is set. The frames are the same with any count.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from facepuppet.errors import FacepuppetError

__all__ = ["MediaSource", "open_media", "frame_time", "IMAGE_SUFFIXES", "is_still", "container_frame_count"]

IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".ppm", ".pgm", ".bmp", ".tif", ".tiff", ".webp")
_STILL_FPS = 30.0


def is_still(path: str | os.PathLike) -> bool:
    """True if ``path`` names a single image file."""
    return Path(path).suffix.lower() in IMAGE_SUFFIXES


class MediaSource:
    """Frames from one medium. Use :func:`open_media` to make one.

    Attributes
    ----------
    path : str
        What was opened.
    fps : float
        Frames per second (30 for stills and image folders).
    frame_size : (int, int)
        Width and height of the frames in pixels.
    frame_count : int or None
        Number of frames if known in advance (None for a camera).
    is_camera : bool
    decode_threads : int or None
        Threads FFmpeg decodes the video file on (None for cameras, images and backends that do not say).
    """

    def __init__(self, path: str, fps: float, frame_size: tuple[int, int], frame_count: int | None,
                 frames: Iterator[np.ndarray], closer=None, is_camera: bool = False,
                 decode_threads: int | None = None):
        self.path = path
        self.decode_threads = decode_threads
        self.fps = fps
        self.frame_size = frame_size
        self.frame_count = frame_count
        self.is_camera = is_camera
        self._frames = frames
        self._closer = closer
        self.last_time: float | None = None   # container timestamp of the frame last read, seconds

    def __iter__(self) -> Iterator[np.ndarray]:
        return self._frames

    def __enter__(self) -> MediaSource:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        if self._closer is not None:
            self._closer()
            self._closer = None


def _opencv_name(path, label=None) -> str:
    """``path`` as OpenCV takes it; FacepuppetError for a name that is not valid UTF-8 (OpenCV crashes on one)."""
    text = str(path)
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        shown = text.encode("utf-8", "backslashreplace").decode("utf-8")
        raise FacepuppetError(f"{label or shown}: the name is not valid UTF-8; rename the file") from None
    return text


def _read_image(path: Path) -> np.ndarray:
    import cv2

    _opencv_name(path)

    bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if bgr is None:
        raise FacepuppetError(f"{path}: cannot read image (unreadable or not an image)")
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)


def _open_video(path: str, label: str, camera: bool, threads: int | None = None) -> MediaSource:
    import cv2

    # FFmpeg's own messages ("moov atom not found") would follow our one-line error; quiet unless the user chose
    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")
    cap = None
    if threads is not None and not camera:
        # a backend that does not take the thread count opens nothing with it: then opened as without
        cap = cv2.VideoCapture(path, cv2.CAP_ANY, [cv2.CAP_PROP_N_THREADS, max(1, int(threads))])
    if cap is None or not cap.isOpened():
        cap = cv2.VideoCapture(int(path) if path.isdigit() else path)
    if not cap.isOpened():
        raise FacepuppetError(f"{label}: cannot open {'camera' if camera else 'video'}")
    ok, first = cap.read()
    if not ok or first is None:
        cap.release()
        raise FacepuppetError(f"{label}: no frames could be read (empty or corrupt {'camera' if camera else 'video'})")
    fps = cap.get(cv2.CAP_PROP_FPS)
    fps = float(fps) if fps and np.isfinite(fps) and fps > 0 else _STILL_FPS
    count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) if not camera else None
    if count is not None and count <= 0:
        count = None
    h, w = first.shape[:2]

    first_ms = None if camera else cap.get(cv2.CAP_PROP_POS_MSEC)

    def frames() -> Iterator[np.ndarray]:
        source.last_time = _seconds(first_ms)
        yield cv2.cvtColor(first, cv2.COLOR_BGR2RGB)
        while True:
            ok, bgr = cap.read()
            if not ok or bgr is None:
                return
            source.last_time = None if camera else _seconds(cap.get(cv2.CAP_PROP_POS_MSEC))
            yield cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)

    used = None if camera else cap.get(cv2.CAP_PROP_N_THREADS)
    used = int(used) if used and np.isfinite(used) and used > 0 else None
    source = MediaSource(label, fps, (w, h), count, frames(), closer=cap.release, is_camera=camera,
                         decode_threads=used)
    return source


def _seconds(ms) -> float | None:
    return float(ms) / 1000.0 if ms is not None and np.isfinite(ms) and ms >= 0 else None


def frame_time(index: int, fps: float, container: float | None, previous: float | None) -> float:
    """Time of frame ``index`` in seconds: the container's timestamp ``container`` where it differs from
    ``index / fps`` by half a frame or more and keeps time increasing after ``previous``, else ``index / fps``."""
    nominal = index / float(fps)
    if container is None or abs(container - nominal) < 0.5 / float(fps):
        return nominal
    if previous is not None and container <= previous:
        return max(nominal, previous + 1e-6)
    return float(container)


def container_frame_count(path: str | os.PathLike) -> int | None:
    """The frame count a video file's container gives, read without decoding a frame; None when the file cannot
    be opened as a video or its container does not say (images, folders and cameras: None; :func:`open_media`
    counts those)."""
    import cv2

    try:
        name = _opencv_name(path)
    except FacepuppetError:
        return None
    if name.startswith("camera:") or is_still(name) or not os.path.isfile(name):
        return None
    cap = cv2.VideoCapture(name)
    try:
        count = cap.get(cv2.CAP_PROP_FRAME_COUNT) if cap.isOpened() else 0
    finally:
        cap.release()
    return int(count) if count and np.isfinite(count) and count > 0 else None


def open_media(path: str | os.PathLike, *, decode_threads: int | None = None) -> MediaSource:
    """Open a video file, an image, a folder of images, or ``camera:N`` and return its frame source.

    Parameters
    ----------
    path : str or PathLike
    decode_threads : int, optional
        Threads FFmpeg decodes a video file on (at least 1; module notes); None: ``OPENCV_FFMPEG_THREADS`` if
        set, else one per core. Cameras and images take no thread count.

    Raises
    ------
    FacepuppetError
        If the medium is missing, unreadable, empty, or of no known kind; the message names it.
    """
    label = _opencv_name(path)
    if label.startswith("camera:"):
        return _open_video(label[len("camera:"):], label, camera=True)
    p = Path(path)
    if not p.exists():
        raise FacepuppetError(f"{label}: no such file or folder")
    if p.is_dir():
        files = sorted(f for f in p.iterdir() if f.suffix.lower() in IMAGE_SUFFIXES)
        if not files:
            raise FacepuppetError(f"{label}: folder holds no images ({', '.join(IMAGE_SUFFIXES)})")
        first = _read_image(files[0])
        h, w = first.shape[:2]

        def frames() -> Iterator[np.ndarray]:
            yield first
            for f in files[1:]:
                img = _read_image(f)
                if img.shape[:2] != (h, w):
                    raise FacepuppetError(f"{f}: size {img.shape[1]}x{img.shape[0]} differs from {w}x{h} "
                                          f"of the folder's first image")
                yield img

        return MediaSource(label, _STILL_FPS, (w, h), len(files), frames())
    if is_still(p):
        img = _read_image(p)
        h, w = img.shape[:2]
        return MediaSource(label, _STILL_FPS, (w, h), 1, iter([img]))
    return _open_video(label, label, camera=False, threads=decode_threads)
