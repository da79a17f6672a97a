"""The causal per-frame stream: frame -> features -> weights -> every output, one frame at a time.

This is the online system of the paper in one loop. For frame k, read at time t_k = k / fps of the take:

1. the tracker (§3) turns the RGB frame into :class:`~facepuppet.capture.features.FrameFeatures`;
2. the rig's mapper turns its feature points into the key-models' weights (Eq. 13), on frames with a face;
3. a One-Euro filter smooths them, holding and then easing lost frames to neutral
   (:class:`~facepuppet.pipeline.smoothing.OneEuroFilter`);
4. the expression gain scales and clips them (:func:`~facepuppet.pipeline.gain.apply_gain`);
5. every output (GLB, CSV, preview video, live senders) takes the frame as it passes.

Nothing waits for a later frame, so ``facepuppet animate`` (a file, every frame) and ``facepuppet live`` (a
camera, newest frame first) are the same stream with other sources and outputs. The stream itself keeps no
per-frame history: memory is flat in the length of the take; outputs that need the whole take (a GLB) keep only
their own rows.

Neutral re-zero
---------------
:meth:`FrameMapper.rezero` takes the current face as the performer's neutral for the session: the rig's source
base (and with it every source example) is shifted by ``d = p_now - S_B``, so later frames are mapped as
``weights(p - d)``. The face of that moment then maps to the neutral character exactly.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from facepuppet._util.interrupt import between_frames
from facepuppet._util.interrupt import check as interrupt_check
from facepuppet.capture.features import FrameFeatures
from facepuppet.errors import FacepuppetError
from facepuppet.pipeline.gain import GainConfig, rig_gain
from facepuppet.pipeline.smoothing import OneEuroFilter, SmoothingConfig

__all__ = ["CAMERA_TO_CHARACTER", "head_rotation_in_character", "SourceFrame", "StreamFrame", "FrameMapper",
           "Output", "StreamSummary", "run_stream", "source_frames"]

log = logging.getLogger(__name__)

#: OpenCV camera axes (x right, y down, z forward) to the character's (glTF: y up, facing +z).
CAMERA_TO_CHARACTER = np.diag([1.0, -1.0, -1.0])


def head_rotation_in_character(rotation: np.ndarray) -> np.ndarray:
    """Head rotations (..., 3, 3) from the track's camera frame to the character's frame.

    The track's rotation R maps head to OpenCV camera coordinates; the character (y up, facing +z, its own
    left at +x, like the head frame) turns by ``diag(1, -1, -1) @ R``, which is the identity for a frontal,
    upright head. The performer turning to their left turns the character to its own left.
    """
    return np.einsum("ij,...jk->...ik", CAMERA_TO_CHARACTER, np.asarray(rotation, dtype=float))


@dataclass(frozen=True)
class SourceFrame:
    """One frame as the source hands it to the stream.

    Attributes
    ----------
    index : int
        Frame number in the source, from 0 (gaps where frames were dropped).
    time : float
        Its time in the take, seconds (``index / fps`` for a file).
    rgb : (H, W, 3) uint8 or None
        The picture, RGB; None when features come from a track file and no picture is needed.
    captured : float
        ``time.perf_counter()`` when the frame was read: where the latency is measured from.
    features : FrameFeatures or None
        Features already known (from a track file); None lets the stream's tracker make them.
    """

    index: int
    time: float
    rgb: np.ndarray | None
    captured: float
    features: FrameFeatures | None = None


@dataclass(frozen=True)
class StreamFrame:
    """One frame after the whole chain.

    Attributes
    ----------
    index, time, rgb, captured
        As in :class:`SourceFrame`.
    features : FrameFeatures
        What the tracker saw.
    raw : (C,) float
        The mapper's weights before smoothing and gain; NaN when no face was tracked.
    weights : (C,) float
        Final weights (smoothed, gain applied), one per channel of the rig: its M paired key-models, or the
        R·M (region, key-model) pairs of a regional rig (``Rig.channel_names``).
    rotation : (3, 3) float
        Head rotation in the character's frame; a lost frame keeps the last tracked one (the rest pose before
        the first).
    """

    index: int
    time: float
    rgb: np.ndarray | None
    captured: float
    features: FrameFeatures
    raw: np.ndarray
    weights: np.ndarray
    rotation: np.ndarray

    @property
    def valid(self) -> bool:
        """A face was tracked and mapped in this frame."""
        return bool(np.isfinite(self.raw).all())


class FrameMapper:
    """Feature points of one frame -> final weights: Eq. 13, One-Euro smoothing, gain (see the module notes).

    Parameters
    ----------
    rig : facepuppet.pipeline.rig.Rig
        Its ``mapper`` maps (P, D) points to (M,) weights (names: the rig's ``names``), or a regional one to
        (R, M), flattened to R·M channels region-major (names: the rig's ``channel_names``).
    smoothing : SmoothingConfig, optional
    gain : GainConfig, optional
    rig_label : str
        How errors name the rig (its path).
    """

    def __init__(self, rig, *, smoothing: SmoothingConfig | None = None, gain: GainConfig | None = None,
                 rig_label: str = "rig") -> None:
        self.rig = rig
        self.names = tuple(getattr(rig, "channel_names", rig.names))
        self.rig_label = rig_label
        gain = gain or GainConfig()
        self._gain = rig_gain(gain, rig)
        self._low = gain.low
        self._high = None if gain.high is None else gain.high * np.maximum(1.0, self._gain)
        self._filter = OneEuroFilter(len(self.names), smoothing)
        self._offset: np.ndarray | None = None
        self._rotation = np.eye(3)
        self._rezero_next = False

    def request_rezero(self) -> None:
        """Take the next frame with a face as the session's neutral (thread-safe: sets a flag)."""
        self._rezero_next = True

    def rezero(self, features: FrameFeatures) -> bool:
        """Take this frame's face as the performer's neutral; False (and no change) if it has no face."""
        points = np.asarray(features.points, dtype=float)
        if not features.valid or not np.isfinite(points).all():
            return False
        base = np.asarray(self.rig.mapper.source_base, dtype=float)
        if base.shape != points.shape:
            raise FacepuppetError(f"{self.rig_label}: its source base has shape {base.shape}, the tracker gives "
                                  f"points of shape {points.shape}")
        self._offset = points - base
        return True

    def clear_rezero(self) -> None:
        """Back to the rig's own neutral."""
        self._offset = None

    def step(self, features: FrameFeatures, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Map one frame: (raw (C,), weights (C,), rotation (3, 3)) at time ``t`` seconds, C channels."""
        points = np.asarray(features.points, dtype=float)
        ok = bool(features.valid) and bool(np.isfinite(points).all())
        if ok and self._rezero_next:
            self._rezero_next = not self.rezero(features)
        if ok:
            if self._offset is not None:
                points = points - self._offset
            try:
                raw = np.asarray(self.rig.mapper.weights(points), dtype=float).reshape(-1)
            except ValueError as e:
                raise FacepuppetError(f"{self.rig_label}: does not fit the track's feature points ({e})") from e
        else:
            raw = np.full(len(self.names), np.nan)
        if features.valid:
            rotation = head_rotation_in_character(features.rotation)
            if np.isfinite(rotation).all():
                self._rotation = rotation
        smoothed = self._filter.update(raw if ok else None, t)
        weights = smoothed * self._gain                     # the gain's clip, as apply_gain does it
        if self._low is not None:
            weights = np.where(weights < self._low, self._low, weights)
        if self._high is not None:
            weights = np.where(weights > self._high, self._high, weights)
        return raw, weights, self._rotation.copy()


class Output(Protocol):
    """Something that takes every frame of the stream: a file writer or a live sender."""

    def write(self, frame: StreamFrame) -> None:
        """Take one frame; must not keep the frame's picture beyond the call."""
        ...

    def finish(self) -> None:
        """Called once after the last frame (before files are committed); not called when the stream fails."""
        ...


@dataclass
class StreamSummary:
    """What one run of the stream did.

    Attributes
    ----------
    frames : int
        Frames that went through the chain.
    with_face : int
        Of those, frames with a tracked face.
    first_time, last_time : float
        Times of the first and last frame in the take, seconds.
    latency_ms : list of float
        Per-frame latency from capture to the last output, milliseconds (only if ``keep_latency``).
    seconds : float
        Wall time of the whole run.
    timings : dict of str -> float
        Seconds spent tracking (``track``), mapping (``map``) and in the outputs (``write``).
    """

    frames: int = 0
    with_face: int = 0
    first_time: float = 0.0
    last_time: float = 0.0
    seconds: float = 0.0
    latency_ms: list = field(default_factory=list)
    timings: dict = field(default_factory=lambda: {"track": 0.0, "map": 0.0, "write": 0.0})


def source_frames(source, *, max_frames: int | None = None) -> Iterator[SourceFrame]:
    """Every frame of an opened :class:`~facepuppet.io.frames.MediaSource`, in order, at its time: the
    container's timestamp where a variable-frame-rate video has one (:func:`~facepuppet.io.frames.frame_time`),
    else ``index / fps``."""
    from facepuppet.io.frames import frame_time

    fps = float(source.fps)
    previous = None
    for i, rgb in enumerate(source):
        if max_frames is not None and i >= max_frames:
            return
        t = frame_time(i, fps, getattr(source, "last_time", None), previous)
        previous = t
        yield SourceFrame(i, t, rgb, time.perf_counter())


def run_stream(frames: Iterable[SourceFrame], tracker, mapper: FrameMapper, outputs: Sequence[Output], *,
               on_frame: Callable[[StreamFrame], None] | None = None, keep_latency: bool = False,
               point_names: Sequence[str] | None = None) -> StreamSummary:
    """Run frames through tracker, mapper and outputs, one at a time (see the module notes).

    Parameters
    ----------
    frames : iterable of SourceFrame
        The source; frames that carry ``features`` skip the tracker (which may then be None).
    tracker : Tracker or None
        ``tracker.track(rgb, timestamp_ms)`` -> FrameFeatures.
    mapper : FrameMapper
    outputs : sequence of Output
        Each gets every frame, in the order given; ``finish()`` is called on each at the end.
    on_frame : callable(StreamFrame), optional
        Called after the outputs (progress, status line).
    keep_latency : bool
        Record every frame's latency in the summary (a live session's statistics keep their own).
    point_names : sequence of str, optional
        The tracker's feature point names; checked once against the rig's.

    Returns
    -------
    StreamSummary
    """
    rig_points = tuple(getattr(mapper.rig, "point_names", None) or ())
    if rig_points and point_names is not None and tuple(point_names) != rig_points:
        raise FacepuppetError(
            f"{mapper.rig_label}: made for other feature points ({len(rig_points)}, e.g. {rig_points[0]!r}) "
            f"than the {getattr(tracker, 'name', 'track')} tracker gives ({len(point_names)}); capture the key "
            f"expressions and rig again with this tracker")
    summary = StreamSummary()
    spent = summary.timings
    start = time.perf_counter()
    with between_frames():
        summary = _run_frames(frames, tracker, mapper, outputs, on_frame, keep_latency, summary)
    t0 = time.perf_counter()
    for out in outputs:
        out.finish()
    spent["write"] += time.perf_counter() - t0
    summary.seconds = time.perf_counter() - start
    return summary


def _run_frames(frames, tracker, mapper, outputs, on_frame, keep_latency, summary) -> StreamSummary:
    spent = summary.timings
    for src in frames:
        interrupt_check()
        t0 = time.perf_counter()
        if src.features is not None:
            features = src.features
        else:
            features = tracker.track(src.rgb, int(round(src.time * 1000.0)))
        t1 = time.perf_counter()
        raw, weights, rotation = mapper.step(features, src.time)
        frame = StreamFrame(src.index, src.time, src.rgb, src.captured, features, raw, weights, rotation)
        t2 = time.perf_counter()
        for out in outputs:
            out.write(frame)
        t3 = time.perf_counter()
        spent["track"] += t1 - t0
        spent["map"] += t2 - t1
        spent["write"] += t3 - t2
        if keep_latency:
            summary.latency_ms.append((time.perf_counter() - src.captured) * 1000.0)
        if summary.frames == 0:
            summary.first_time = src.time
        summary.frames += 1
        summary.with_face += frame.valid
        summary.last_time = src.time
        if on_frame is not None:
            on_frame(frame)
    return summary
