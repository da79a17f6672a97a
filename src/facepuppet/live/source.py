"""A live source: frames of a camera (or of a file standing in for one) handed to the stream, newest first.

Two paces:

``realtime``
    A reader thread takes frames from the source as they come: a camera's own rate, or a file played at its
    frame rate (frame k is due ``k / fps`` seconds after the start). The stream is handed the newest frame
    read; a frame the stream could not take before the next one arrived is dropped (counted), never queued, so
    the latency stays that of one frame however slow the pipeline is.
``fast``
    Every frame, in order, as fast as the stream takes them (tests, benchmarks, converting a file).

Either way the iteration ends at the source's end, at ``max_frames``, or when :meth:`LiveSource.stop` is
called (from a signal handler or another thread); a camera that stops delivering frames (or sends none for
:data:`CAMERA_TIMEOUT` seconds) ends it too, with :attr:`LiveSource.error` saying so.
"""

from __future__ import annotations

import itertools
import threading
import time
from collections.abc import Iterator

from facepuppet.errors import FacepuppetError
from facepuppet.pipeline.stream import SourceFrame

__all__ = ["PACES", "LiveSource"]

#: The paces a live source knows.
PACES = ("realtime", "fast")
#: Seconds without a frame after which a camera counts as stopped.
CAMERA_TIMEOUT = 5.0


class LiveSource:
    """Frames of an opened :class:`~facepuppet.io.frames.MediaSource` at a pace (see the module notes).

    Parameters
    ----------
    source : MediaSource
        Opened by the caller, who also closes it.
    pace : {"realtime", "fast"}
    max_frames : int, optional
        Stop after this many frames have been read from the source.
    warmup : callable(rgb), optional
        Called once with the first frame before the clock starts (a throwaway tracker loading its compiled
        kernels), so the time it takes drops no frame; the first frame is then handed on as usual.

    Attributes
    ----------
    read : int
        Frames read from the source.
    dropped : int
        Frames read but never handed on (the stream was busy when a newer one arrived).
    error : str or None
        Why the source ended early (a camera that stopped), else None.
    """

    def __init__(self, source, *, pace: str = "realtime", max_frames: int | None = None, warmup=None) -> None:
        if pace not in PACES:
            raise ValueError(f"--pace: choose from {', '.join(PACES)}, got {pace!r}")
        if max_frames is not None and max_frames < 1:
            raise ValueError(f"--max-frames must be at least 1, got {max_frames}")
        self.source = source
        self.pace = pace
        self.max_frames = max_frames
        self.warmup = warmup
        self.read = 0
        self.dropped = 0
        self.error: str | None = None
        self._stop = threading.Event()
        self._cond = threading.Condition()
        self._newest: SourceFrame | None = None
        self._ended = False

    def stop(self) -> None:
        """End the iteration after the current frame (safe from a signal handler or any thread)."""
        self._stop.set()
        if self.pace == "realtime":
            # no lock here: a signal handler may run while the reader holds it
            self._ended = True

    @property
    def stopped(self) -> bool:
        return self._stop.is_set()

    def __iter__(self) -> Iterator[SourceFrame]:
        return self._fast() if self.pace == "fast" else self._realtime()

    def _frames(self) -> Iterator[tuple[int, float, object]]:
        fps = float(self.source.fps)
        camera = bool(getattr(self.source, "is_camera", False))
        start = None
        for k, rgb in enumerate(self.source):
            if self._stop.is_set() or (self.max_frames is not None and k >= self.max_frames):
                return
            if k == 0 and self.warmup is not None:
                self.warmup(rgb)
            if start is None:
                start = time.perf_counter()
            self.read += 1
            t = time.perf_counter() - start if camera else k / fps
            yield k, t, rgb
        if camera and not self._stop.is_set():
            self.error = f"{self.source.path}: the camera stopped delivering frames"

    def _fast(self) -> Iterator[SourceFrame]:
        for k, t, rgb in self._frames():
            yield SourceFrame(k, t, rgb, time.perf_counter())
            if self._stop.is_set():
                return

    def _realtime(self) -> Iterator[SourceFrame]:
        camera = bool(getattr(self.source, "is_camera", False))
        frames = self._frames()
        first = next(frames, None)                   # here, before the reader starts: the warm-up, if any
        if first is None:
            return
        reader = threading.Thread(target=self._read, args=(first, frames), name="facepuppet-live-reader",
                                  daemon=True)
        reader.start()
        try:
            while True:
                with self._cond:
                    since = time.perf_counter()
                    while self._newest is None and not self._ended:
                        self._cond.wait(0.1)
                        if camera and time.perf_counter() - since > CAMERA_TIMEOUT:
                            self.error = f"{self.source.path}: the camera stopped delivering frames"
                            self._ended = True
                    frame, self._newest = self._newest, None
                    if frame is None:
                        return
                yield frame
                if self._stop.is_set():
                    return
        finally:
            self._stop.set()
            reader.join(timeout=1.0)

    def _read(self, first: tuple, rest: Iterator) -> None:
        camera = bool(getattr(self.source, "is_camera", False))
        fps = float(self.source.fps)
        start = time.perf_counter()                  # the clock starts at the first frame, after the warm-up
        try:
            for k, t, rgb in itertools.chain([first], rest):
                if not camera:                       # a file stands in for a camera: frame k is due at k / fps
                    due = start + k / fps
                    while not self._stop.is_set() and (wait := due - time.perf_counter()) > 0:
                        time.sleep(min(wait, 0.05))
                    if self._stop.is_set():
                        break
                frame = SourceFrame(k, t, rgb, time.perf_counter())
                with self._cond:
                    if self._newest is not None:
                        self.dropped += 1
                    self._newest = frame
                    self._cond.notify()
        except FacepuppetError as e:
            self.error = str(e)
        finally:
            with self._cond:
                self._ended = True
                self._cond.notify()
