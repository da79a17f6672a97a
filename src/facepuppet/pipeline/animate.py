"""From a performance video to an animated character: track, map, smooth, scale, write.

:func:`animate` runs the whole chain over a file in one causal pass (:mod:`facepuppet.pipeline.stream`);
:func:`map_track` is its middle (a track and a rig in, weights out) for a track made before.

Per frame: the tracker's feature points (head pose removed) go to the rig's mapper (paper Eq. 13) on frames
with a face; the weights are smoothed by a One-Euro filter, which also holds and then eases lost frames to
neutral (:mod:`facepuppet.pipeline.smoothing`), then scaled and clipped by the expression gain
(:mod:`facepuppet.pipeline.gain`). The outputs are a GLB (the character's key-models as morph targets and one
animation of their weights and of the head rotation), a CSV (Live Link Face layout for ARKit names) and a
side-by-side preview video (:mod:`facepuppet.pipeline.outputs`). They appear together when the take ends
without error, and a failure or an interrupt leaves none of them.
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from facepuppet.capture.features import FrameFeatures
from facepuppet.errors import FacepuppetError
from facepuppet.io.track import Track
from facepuppet.pipeline.gain import GainConfig
from facepuppet.pipeline.outputs import CsvOutput, GlbOutput, PreviewOutput, check_suffix
from facepuppet.pipeline.provenance import check_rig_backend, check_rig_profile, check_track_media
from facepuppet.pipeline.smoothing import SmoothingConfig
from facepuppet.pipeline.stream import (
    FrameMapper,
    SourceFrame,
    StreamFrame,
    head_rotation_in_character,
    run_stream,
    source_frames,
)
from facepuppet.pipeline.tracking import TrackerOptions, make_tracker_for

__all__ = ["AnimateConfig", "Animation", "map_track", "animate", "head_rotation_in_character",
           "check_rig_matches"]

log = logging.getLogger(__name__)

@dataclass(frozen=True, kw_only=True)
class AnimateConfig:
    """Options of :func:`animate`.

    Attributes
    ----------
    tracker : TrackerOptions
        Tracker backend, colour-tracker profile, MediaPipe model.
    smoothing : SmoothingConfig
    gain : GainConfig
    head_rotation : bool
        Animate the head's rotation in the GLB (and write it to the CSV).
    """

    tracker: TrackerOptions = field(default_factory=TrackerOptions)
    smoothing: SmoothingConfig = field(default_factory=SmoothingConfig)
    gain: GainConfig = field(default_factory=GainConfig)
    head_rotation: bool = True


@dataclass(frozen=True)
class Animation:
    """The animation of a performance.

    Attributes
    ----------
    weights : (F, C) float
        Final weights (smoothed, gain applied), one column per channel (``names``); no rows when
        :func:`animate` was told not to keep them.
    raw : (F, C) float
        The mapper's weights before smoothing and gain; NaN on frames without a face (no rows likewise).
    names : tuple of C str
        The rig's channels (``Rig.channel_names``): its M paired key-model names, or for a regional rig the
        R·M ``"<region>/<key-model>"``, region-major.
    fps : float
    track : Track or None
        What the tracker saw (None when :func:`animate` was told not to keep it).
    timings : dict of str -> float
        Seconds spent per step (``track``, ``map``, ``write``: the outputs, ``all``).
    valid_frames : (F,) bool or None
        Frames whose features were mapped; the track's ``valid`` when None.
    regions : tuple of R str
        A regional rig's regions (``Rig.region_names``), empty for a global rig.
    """

    weights: np.ndarray
    raw: np.ndarray
    names: tuple[str, ...]
    fps: float
    track: Track | None
    timings: dict = field(default_factory=dict)
    valid_frames: np.ndarray | None = None
    regions: tuple[str, ...] = ()

    @property
    def valid(self) -> np.ndarray:
        """(F,) bool: frames with a tracked face."""
        if self.track is not None:
            return self.track.valid
        return self.valid_frames


def check_rig_matches(rig, track: Track, rig_label: str = "rig") -> None:
    """Raise FacepuppetError when the rig was made for other feature points than the track holds."""
    ours = tuple(rig.point_names or ())
    if ours and ours != tuple(track.point_names):
        raise FacepuppetError(
            f"{rig_label}: made for other feature points ({len(ours)}, e.g. {ours[0]!r}) than the "
            f"{track.backend} tracker gives ({len(track.point_names)}, e.g. {track.point_names[0]!r}); "
            f"calibrate and rig again with this tracker")


def map_track(rig, track: Track, config: AnimateConfig | None = None, *, rig_label: str = "rig") -> Animation:
    """Weights of every frame of a track: the stream's per-frame mapper (Eq. 13, smoothing, gain) over it.

    Parameters
    ----------
    rig : facepuppet.pipeline.rig.Rig
    track : Track
    config : AnimateConfig, optional
    rig_label : str
        How to name the rig in error messages (its path).
    """
    config = config or AnimateConfig()
    check_rig_matches(rig, track, rig_label)
    t0 = time.perf_counter()
    mapper = FrameMapper(rig, smoothing=config.smoothing, gain=config.gain, rig_label=rig_label)
    recorder = _Recorder(keep_track=False)
    run_stream(track_frames(track, None), None, mapper, [recorder])
    anim = recorder.animation(rig, float(track.fps), track)
    anim.timings["map"] = time.perf_counter() - t0
    return anim


def _load_rig(rig):
    if isinstance(rig, (str, os.PathLike)):
        from facepuppet.pipeline.rig import load_rig

        return load_rig(rig), str(rig)
    return rig, "rig"


def _check_out(path) -> None:
    if path is None:
        return
    folder = Path(path).parent
    if str(folder) and not folder.is_dir():
        raise FileNotFoundError(f"{path}: folder {folder} does not exist")
    if Path(path).is_dir():
        raise IsADirectoryError(f"{path}: is a folder, not a file name")


def animate(media: str | os.PathLike | None, rig, *, glb: str | os.PathLike | None = None,
            csv: str | os.PathLike | None = None, preview: str | os.PathLike | None = None,
            track: Track | str | os.PathLike | None = None, config: AnimateConfig | None = None,
            colors: np.ndarray | None = None, keep_track: bool = True, keep_weights: bool = True,
            max_frames: int | None = None, on_frame: Callable[[int], None] | None = None,
            tracker=None) -> Animation:
    """Animate a character from a performance video, in one causal pass (:mod:`facepuppet.pipeline.stream`).

    Every frame is decoded once, tracked, mapped, smoothed, scaled and handed to every output as it passes;
    the outputs appear together at the end (all or none).

    Parameters
    ----------
    media : str or PathLike or None
        The performance (video, image folder, ``camera:N``); may be None when ``track`` is given and no
        preview is asked for.
    rig : Rig or str or PathLike
        A rig (``facepuppet rig``) or its file.
    glb, csv, preview : str or PathLike, optional
        Outputs: the animated character, the weights as CSV, the side-by-side preview video.
    track : Track or str or PathLike, optional
        Reuse a track (or track file) of ``media`` instead of tracking again.
    config : AnimateConfig, optional
    colors : (V, 3) float, optional
        Vertex colours of the character in the preview (grey by default).
    keep_track : bool
        Keep every frame's features and return them as ``Animation.track`` (memory grows with the take);
        False keeps only the weights.
    keep_weights : bool
        Keep every frame's weights in ``Animation.weights`` / ``raw`` (16 bytes a weight a frame); False
        returns them with no rows (the files have them) and keeps one flag a frame (``Animation.valid``).
    max_frames : int, optional
        Stop after this many frames.
    on_frame : callable, optional
        Called with each frame's index once every output has taken it (progress of a batch).
    tracker : Tracker, optional
        Track with this tracker (of ``config.tracker``'s backend, at the start of a take) instead of a new one
        made from ``config.tracker``; it is left open (a batch worker's, reused across clips).

    Returns
    -------
    Animation
    """
    for out, kind in ((glb, "animated character"), (csv, "weights CSV"), (preview, "preview video")):
        if out is not None:
            check_suffix(out, kind)  # before any work
    config = config or AnimateConfig()
    rig, rig_label = _load_rig(rig)
    for out in (glb, csv, preview):
        _check_out(out)
    if preview is not None and media is None:
        raise ValueError("--preview needs the input media (the frames drawn on the left)")
    if track is None and media is None:
        raise ValueError("give the media to track, or --track")
    track_arg = track
    if track is not None and not isinstance(track, Track):
        from facepuppet.io.track import load_track

        track = load_track(track)
    if track is not None:
        check_rig_matches(rig, track, rig_label)
        check_rig_backend(rig, track.backend, rig_label, what="a track made with")
        check_track_media(track, media, "--track" if not isinstance(track_arg, Track) else "track")
        if not track.valid.any():
            raise FacepuppetError(f"{media or 'track'}: no face was tracked in any frame")
    else:
        check_rig_backend(rig, config.tracker.backend, rig_label)
        if config.tracker.backend == "color":
            check_rig_profile(rig, config.tracker.profile, rig_label)
    mapper = FrameMapper(rig, smoothing=config.smoothing, gain=config.gain, rig_label=rig_label)
    t0 = time.perf_counter()
    with contextlib.ExitStack() as stack:
        source = None
        if media is not None and (track is None or preview is not None):
            from facepuppet.io.frames import open_media

            source = stack.enter_context(open_media(media))
        fps = float(track.fps) if track is not None else float(source.fps)
        if track is not None:
            tracker = None
        elif tracker is None:
            tracker = make_tracker_for(config.tracker, media)
            stack.callback(tracker.close)
        if track is None:
            frames = source_frames(source, max_frames=max_frames)
        else:
            frames = track_frames(track, source, max_frames=max_frames)
        recorder = _Recorder(keep_track, keep_weights)
        outputs: list = [recorder]
        if glb is not None:
            outputs.append(GlbOutput(glb, rig, stack, head_rotation=config.head_rotation, fps=fps))
        if csv is not None:
            outputs.append(CsvOutput(csv, rig, stack, head_rotation=config.head_rotation, fps=fps))
        if preview is not None:
            outputs.append(PreviewOutput(preview, rig, stack, fps=fps, frame_height=int(source.frame_size[1]),
                                         colors=colors, head_rotation=config.head_rotation))
        total = source.frame_count if track is None else track.n_frames
        if max_frames is not None and total is not None:
            total = min(total, max_frames)
        with _progress(total, config.tracker, "animate") as bar:
            def passed(frame: StreamFrame) -> None:
                bar.update(1)
                if on_frame is not None:
                    on_frame(frame.index)

            summary = run_stream(frames, tracker, mapper, outputs, on_frame=passed,
                                 point_names=None if tracker is None else _point_names())
        label = getattr(source, "path", str(media)) if source is not None else "track"
        if summary.frames == 0:
            raise FacepuppetError(f"{label}: no frames to track")
        if summary.with_face == 0:
            raise FacepuppetError(f"{label}: no face found in any of its {summary.frames} frame(s)")
        anim = recorder.animation(rig, fps, track, backend=getattr(tracker, "name", None),
                                  static_extras=getattr(tracker, "static_extras", None),
                                  frame_size=None if source is None else source.frame_size)
    anim.timings.update(summary.timings)
    anim.timings["all"] = time.perf_counter() - t0
    return anim


def track_frames(track: Track, source=None, *, max_frames: int | None = None) -> Iterator[SourceFrame]:
    """The frames of a track as the stream's source (features known), with the pictures of ``source`` if given."""
    pictures = iter(source) if source is not None else None
    n = track.n_frames if max_frames is None else min(track.n_frames, max_frames)
    for k in range(n):
        rgb = next(pictures, None) if pictures is not None else None
        if pictures is not None and rgb is None:
            raise FacepuppetError(f"{source.path}: has fewer frames ({k}) than its track ({track.n_frames})")
        extras = {name: v[k] for name, v in (track.extras or {}).items()
                  if np.ndim(v) and len(v) == track.n_frames} or None
        feats = FrameFeatures(bool(track.valid[k]), track.curves[k], track.rotation[k], track.translation[k],
                              track.points[k], extras)
        t = k / float(track.fps) if track.times is None else float(track.times[k])
        yield SourceFrame(k, t, rgb, time.perf_counter(), feats)


class _Recorder:
    """The output that keeps the take's weights (and, if asked, its features) for the returned Animation."""

    #: Rows per block of the weights kept (blocks of plain float64: 16 bytes a weight, no object per frame).
    BLOCK = 4096

    def __init__(self, keep_track: bool, keep_weights: bool = True) -> None:
        self.keep_track, self.keep_weights = keep_track, keep_weights
        self.raw: list[np.ndarray] = []       # blocks of (BLOCK, M), the last one filled up to _fill
        self.weights: list[np.ndarray] = []
        self._fill = self.BLOCK
        self.features: list[FrameFeatures] = []
        self.valid = bytearray()              # one flag a frame when the weights are not kept

    def write(self, frame: StreamFrame) -> None:
        if self.keep_track:
            self.features.append(frame.features)
        if not self.keep_weights:
            self.valid.append(frame.valid)
            return
        if self._fill == self.BLOCK:
            m = len(frame.weights)
            self.raw.append(np.empty((self.BLOCK, m)))
            self.weights.append(np.empty((self.BLOCK, m)))
            self._fill = 0
        self.raw[-1][self._fill] = frame.raw
        self.weights[-1][self._fill] = frame.weights
        self._fill += 1

    def _rows(self, blocks: list[np.ndarray], m: int) -> np.ndarray:
        if not blocks:
            return np.zeros((0, m))
        return np.concatenate([*blocks[:-1], blocks[-1][:self._fill]]).reshape(-1, m)

    def finish(self) -> None:
        pass

    def animation(self, rig, fps: float, track: Track | None, *, backend: str | None = None,
                  static_extras: dict | None = None, frame_size=None) -> Animation:
        if track is None and self.keep_track and self.features:
            from facepuppet.capture.tracking import features_to_track

            track = features_to_track(self.features, fps=fps, frame_size=frame_size, backend=backend or "",
                                      static_extras=static_extras)
        names = tuple(getattr(rig, "channel_names", rig.names))
        regions = tuple(getattr(rig, "region_names", ()))
        m = len(names)
        if not self.keep_weights:
            return Animation(np.zeros((0, m)), np.zeros((0, m)), names, float(fps), track,
                             valid_frames=np.frombuffer(bytes(self.valid), dtype=np.uint8).astype(bool),
                             regions=regions)
        raw = self._rows(self.raw, m)
        return Animation(self._rows(self.weights, m), raw, names, float(fps), track,
                         valid_frames=np.isfinite(raw).all(axis=1), regions=regions)


def _point_names() -> tuple[str, ...]:
    from facepuppet.capture.curves import POINT_NAMES

    return tuple(POINT_NAMES)


@contextlib.contextmanager
def _progress(total: int | None, options: TrackerOptions, desc: str):
    from tqdm import tqdm

    show = options.progress is not False and sys.stderr.isatty()
    with tqdm(total=total, unit="frame", desc=desc, disable=not show, dynamic_ncols=True, leave=False) as bar:
        yield bar
