"""A take's per-frame rows read chunk by chunk: what the animation writers stream from.

The GLB and CSV writers need every frame of a take, but only one frame at a time: each key, each CSV row is a
function of its own frame (and, for quaternions, of the one before). :class:`TakeRows` hands them the take as
chunks of rows, as often as a writer needs a pass (a GLB makes one pass per accessor), read from wherever the
rows are: whole arrays in memory (:meth:`TakeRows.from_arrays`) or a spool on disk (the stream's outputs,
:mod:`facepuppet.pipeline.outputs`). A writer's memory is then that of one chunk, flat in the take's length,
and its bytes do not depend on the chunk size.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

__all__ = ["TakeChunk", "TakeRows", "CHUNK_ROWS", "as_take"]

#: Frames per chunk when the rows are read (about 0.2 MB of float64 for 25 weights a frame).
CHUNK_ROWS = 1024


@dataclass(frozen=True)
class TakeChunk:
    """Consecutive frames of a take.

    Attributes
    ----------
    times : (n,) float64
        Each frame's time, seconds.
    weights : (n, M) float64
    rotation : (n, 3, 3) float64 or None
        Head rotations (None when the take has none).
    valid : (n,) bool or None
        False where no face was tracked (None: every frame counts as tracked).
    """

    times: np.ndarray
    weights: np.ndarray
    rotation: np.ndarray | None = None
    valid: np.ndarray | None = None


@dataclass(frozen=True)
class TakeRows:
    """The frames of a take as chunks (see the module notes).

    Attributes
    ----------
    frames : int
        F, the number of frames over all chunks.
    width : int
        M, weights per frame.
    read : callable () -> iterator of TakeChunk
        A new pass over the take, first frame to last; every pass gives the same rows.
    has_rotation : bool
        Chunks carry head rotations.
    """

    frames: int
    width: int
    read: Callable[[], Iterator[TakeChunk]]
    has_rotation: bool = False

    @classmethod
    def from_arrays(cls, weights: np.ndarray, times: np.ndarray, *, rotation: np.ndarray | None = None,
                    valid: np.ndarray | None = None, chunk_rows: int | None = None) -> TakeRows:
        """Rows of whole arrays: weights (F, M), times (F,), rotation (F, 3, 3), valid (F,), in chunks of
        ``chunk_rows`` frames (:data:`CHUNK_ROWS` if None; shapes are the caller's to check)."""
        weights = np.asarray(weights, dtype=np.float64)
        times = np.asarray(times, dtype=np.float64)
        step = max(1, int(CHUNK_ROWS if chunk_rows is None else chunk_rows))

        def read() -> Iterator[TakeChunk]:
            for a in range(0, len(weights), step):
                b = a + step
                yield TakeChunk(times[a:b], weights[a:b], None if rotation is None else rotation[a:b],
                                None if valid is None else valid[a:b])

        return cls(len(weights), weights.shape[1], read, rotation is not None)

    def mapped(self, fn: Callable[[TakeChunk], TakeChunk], width: int | None = None) -> TakeRows:
        """The same take with every chunk passed through ``fn`` (which keeps the chunk's frame count)."""
        source = self.read

        def read() -> Iterator[TakeChunk]:
            for chunk in source():
                yield fn(chunk)

        return TakeRows(self.frames, self.width if width is None else int(width), read, self.has_rotation)

    def times_checked(self, label: str = "times") -> Iterator[TakeChunk]:
        """A pass whose times are checked finite and increasing across chunks (ValueError naming ``label``)."""
        last = -np.inf
        for chunk in self.read():
            t = chunk.times
            if len(t) and (not np.isfinite(t).all() or t[0] <= last or (len(t) > 1 and not (np.diff(t) > 0).all())):
                raise ValueError(f"{label} must be {self.frames} finite, increasing seconds")
            if len(t):
                last = t[-1]
            yield chunk


def as_take(weights, width: int, fps: float, *, times=None, head_rotation=None) -> TakeRows:
    """A writer's ``weights`` argument as :class:`TakeRows`, checked: a TakeRows of ``width`` columns and at
    least one frame (its times and rotations are its own), or arrays — weights (F, ``width``), F >= 1, times
    (F,) finite and increasing seconds (``f / fps`` if None), head_rotation (F, 3, 3) or None. ``fps`` must be
    a positive number. ValueError names what is wrong."""
    if isinstance(weights, TakeRows):
        if head_rotation is not None or times is not None:
            raise ValueError("times and head rotations of a TakeRows are its own")
        if weights.width != width or weights.frames == 0:
            raise ValueError(f"weights must have shape (F, {width}) with F >= 1, got "
                             f"({weights.frames}, {weights.width})")
    else:
        weights = np.asarray(weights, dtype=np.float64)
        if weights.ndim != 2 or weights.shape[1] != width or len(weights) == 0:
            raise ValueError(f"weights must have shape (F, {width}) with F >= 1, got {weights.shape}")
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be a positive number, got {fps}")
    if isinstance(weights, TakeRows):
        return weights
    f = len(weights)
    times = np.arange(f) / fps if times is None else np.asarray(times, dtype=np.float64)
    if times.shape != (f,) or not np.isfinite(times).all() or (f > 1 and not (np.diff(times) > 0).all()):
        raise ValueError(f"times must be {f} finite, increasing seconds, got shape {times.shape}")
    if head_rotation is not None:
        head_rotation = np.asarray(head_rotation, dtype=np.float64)
        if head_rotation.shape != (f, 3, 3):
            raise ValueError(f"head_rotation must have shape ({f}, 3, 3), got {head_rotation.shape}")
    return TakeRows.from_arrays(weights, times, rotation=head_rotation)
