"""Side-by-side preview video: the input with its tracked curves on the left, the character on the right.

Frame k of the preview is input frame k (with :func:`facepuppet.export.overlay.draw_overlay`) beside the
character posed with the weights of frame k (rendered on the CPU by :func:`facepuppet.export.render.render_mesh`),
both at the input's height. The file is an MPEG-4 video (``mp4v``), written atomically: a reader never sees a
half-written preview, and a failure leaves none.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterable, Iterator
from pathlib import Path

import numpy as np

from facepuppet._util.atomic import atomic_path
from facepuppet.errors import FacepuppetError

__all__ = ["PreviewWriter", "side_by_side", "open_preview", "write_preview", "check_video"]

_FOURCC = "mp4v"


def side_by_side(left: np.ndarray, right: np.ndarray) -> np.ndarray:
    """Put two RGB images side by side, the right one scaled to the left one's height.

    Parameters
    ----------
    left : (H, W1, 3) uint8
    right : (H2, W2, 3) uint8

    Returns
    -------
    (H, W1 + round(W2 * H / H2), 3) uint8
    """
    import cv2

    h = left.shape[0]
    if right.shape[0] != h:
        w = max(1, int(round(right.shape[1] * h / right.shape[0])))
        right = cv2.resize(right, (w, h), interpolation=cv2.INTER_AREA)
    return np.concatenate([left, right], axis=1)


class PreviewWriter:
    """Writes RGB frames of one fixed size to an MPEG-4 file. Use :func:`open_preview`."""

    def __init__(self, writer, size: tuple[int, int]) -> None:
        self._writer = writer
        self.size = size
        self.n_frames = 0

    def write(self, rgb: np.ndarray) -> None:
        """Append one frame, (H, W, 3) uint8 RGB with (W, H) = ``size``."""
        import cv2

        if rgb.shape[1::-1] != self.size:
            rgb = cv2.resize(rgb, self.size, interpolation=cv2.INTER_AREA)
        self._writer.write(cv2.cvtColor(np.ascontiguousarray(rgb), cv2.COLOR_RGB2BGR))
        self.n_frames += 1


@contextlib.contextmanager
def open_preview(path: str | os.PathLike, fps: float, size: tuple[int, int]) -> Iterator[PreviewWriter]:
    """Open an MPEG-4 video for writing frames of ``size`` = (width, height); it appears at ``path`` only
    when the block ends without error and at least one frame was written."""
    import cv2

    w, h = (int(size[0]) // 2 * 2, int(size[1]) // 2 * 2)     # codecs want even sizes
    try:
        str(path).encode("utf-8")
    except UnicodeEncodeError:
        shown = str(path).encode("utf-8", "backslashreplace").decode("utf-8")
        raise FacepuppetError(f"{shown}: the name is not valid UTF-8 (OpenCV cannot write it)") from None
    with atomic_path(path, suffix=".mp4") as tmp:
        writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*_FOURCC), float(fps), (w, h))
        if not writer.isOpened():
            raise FacepuppetError(f"{path}: cannot open a video writer ({_FOURCC}, {w}x{h})")
        out = PreviewWriter(writer, (w, h))
        try:
            yield out
        finally:
            writer.release()
        if out.n_frames == 0:
            raise FacepuppetError(f"{path}: no frames to write")
        check_video(tmp, out.n_frames, label=path)


def check_video(path: str | os.PathLike, n_frames: int, *, label=None) -> None:
    """Raise FacepuppetError naming ``label`` unless the video at ``path`` opens and holds ``n_frames`` frames.

    OpenCV's writer reports no failure (a full disk, a lost folder): the file is read back after
    ``release()`` instead, before it is renamed onto its name.
    """
    import cv2

    label = path if label is None else label
    size = Path(path).stat().st_size if Path(path).is_file() else 0
    cap = cv2.VideoCapture(str(path)) if size > 0 else None
    try:
        count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) if cap is not None and cap.isOpened() else 0
    finally:
        if cap is not None:
            cap.release()
    if count < n_frames:
        raise FacepuppetError(f"{label}: the video was not written completely ({count} of {n_frames} frames "
                              f"readable, {size} bytes; disk full or not writable?)")


def write_preview(path: str | os.PathLike, frames: Iterable[np.ndarray], fps: float, *,
                  left=None, right=None, n_frames: int | None = None, progress: bool | None = None) -> Path:
    """Write a side-by-side preview.

    Parameters
    ----------
    path : str or PathLike
        The .mp4 to write.
    frames : iterable of (H, W, 3) uint8
        Input frames, RGB.
    fps : float
    left : callable (k, frame) -> (H, W, 3) uint8, optional
        Draws on input frame k (the tracked curves); the frame itself if None.
    right : callable (k) -> (H2, W2, 3) uint8
        Renders the character of frame k.
    n_frames : int, optional
        Stop after this many frames (and size the progress bar).
    progress : bool, optional
        Show a progress bar (default: when stderr is a terminal).

    Returns
    -------
    Path of the written file.
    """
    from tqdm import tqdm

    if right is None:
        raise ValueError("write_preview: right (the character renderer) is required")
    bar = tqdm(total=n_frames, desc="preview", unit="frame", disable=_no_bar(progress), leave=False)
    writer_cm = None
    writer = None
    try:
        for k, frame in enumerate(frames):
            if n_frames is not None and k >= n_frames:
                break
            img = side_by_side(left(k, frame) if left is not None else frame, right(k))
            if writer is None:
                writer_cm = open_preview(path, fps, img.shape[1::-1])
                writer = writer_cm.__enter__()
            writer.write(img)
            bar.update()
    except BaseException as e:
        if writer_cm is not None:
            writer_cm.__exit__(type(e), e, e.__traceback__)
        raise
    finally:
        bar.close()
    if writer_cm is None:
        raise FacepuppetError(f"{path}: no frames to write")
    writer_cm.__exit__(None, None, None)
    return Path(path)


def _no_bar(progress: bool | None) -> bool:
    import sys

    return not sys.stderr.isatty() if progress is None else not progress
