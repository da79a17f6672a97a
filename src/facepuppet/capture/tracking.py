"""The tracking loop: frames of a medium through a tracker backend into a :class:`~facepuppet.io.track.Track`.

Backends are named in :data:`BACKENDS` and built lazily by :func:`make_tracker`, so that a backend's heavy
optional dependencies are imported only when it is used.
"""

from __future__ import annotations

import importlib
import logging
import os
import sys
import time
from collections.abc import Callable

import numpy as np

from facepuppet.capture.curves import CURVE_NAMES, POINT_NAMES
from facepuppet.capture.features import FrameFeatures, Tracker
from facepuppet.errors import FacepuppetError
from facepuppet.io.frames import MediaSource, open_media
from facepuppet.io.track import Track

__all__ = ["BACKENDS", "DEFAULT_BACKEND", "make_tracker", "track_media", "features_to_track"]

log = logging.getLogger(__name__)

#: Tracker backends: name -> (module, class). Imported only when asked for.
BACKENDS: dict[str, tuple[str, str]] = {
    "color": ("facepuppet.capture.color.tracker", "ColorTracker"),
    "mediapipe": ("facepuppet.capture.landmarks", "MediaPipeTracker"),
}

#: The backend `facepuppet track` uses unless told otherwise: the paper's colour tracker.
DEFAULT_BACKEND = "color"


def make_tracker(backend: str = DEFAULT_BACKEND, **options) -> Tracker:
    """Build a tracker backend by name.

    Parameters
    ----------
    backend : str
        A key of :data:`BACKENDS` ("color": the paper's colour tracker; "mediapipe": the landmark backend).
    **options
        Passed to the backend's constructor (for example ``profile=`` for "color", ``model_path=`` and
        ``running_mode=`` for "mediapipe").

    Raises
    ------
    ValueError
        For an unknown backend name.
    FacepuppetError
        If the backend is not available (not yet built, or its optional dependency is missing).
    """
    if backend not in BACKENDS:
        raise ValueError(f"unknown tracker backend {backend!r}; choose from {', '.join(BACKENDS)}")
    module_name, class_name = BACKENDS[backend]
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as e:
        if e.name != module_name:
            raise
        raise FacepuppetError(f"tracker backend {backend!r} is not available in this build "
                              f"({module_name} is missing)") from e
    cls = getattr(module, class_name, None)
    if cls is None:
        raise FacepuppetError(f"tracker backend {backend!r} is not available ({module_name}.{class_name} is missing)")
    return cls(**options)


def _stack_extras(frames_extras: list[dict | None], n: int) -> dict[str, np.ndarray]:
    """Per-frame extras (dicts of arrays) to one (F, ...) array per key, NaN where a frame lacks it."""
    shapes: dict[str, tuple[tuple[int, ...], np.dtype]] = {}
    for ex in frames_extras:
        for k, v in (ex or {}).items():
            v = np.asarray(v)
            shapes.setdefault(k, (v.shape, np.result_type(v.dtype, np.float32)))
    out = {}
    for k, (shape, dtype) in shapes.items():
        arr = np.full((n, *shape), np.nan, dtype=dtype)
        for i, ex in enumerate(frames_extras):
            if ex and k in ex:
                arr[i] = ex[k]
        out[k] = arr
    return out


def _want_bar(progress: bool) -> bool:
    return bool(progress) and sys.stderr.isatty()


def track_media(media: str | os.PathLike | MediaSource, tracker: Tracker, *, progress: bool = True,
                max_frames: int | None = None,
                on_frame: Callable[[int, np.ndarray, FrameFeatures], None] | None = None) -> Track:
    """Track every frame of a medium.

    Parameters
    ----------
    media : str, PathLike or MediaSource
        A video file, image, folder of images or ``camera:N`` (see :func:`~facepuppet.io.frames.open_media`),
        or an already opened source (which is then not closed here).
    tracker : Tracker
        The backend; not closed here.
    progress : bool
        Show a tqdm bar with frames per second (only on a terminal).
    max_frames : int, optional
        Stop after this many frames.
    on_frame : callable(index, rgb, features), optional
        Called after each frame (for previews and live output).

    Returns
    -------
    Track
        ``backend`` is ``tracker.name``; per-frame extras of the tracker become ``(F, ...)`` arrays and its
        ``static_extras`` (if any) are added as they are.

    Raises
    ------
    FacepuppetError
        If the medium cannot be read, holds no frame, or no frame has a face.
    """
    from tqdm import tqdm

    if max_frames is not None and max_frames < 1:
        raise ValueError(f"max_frames must be at least 1, got {max_frames}")
    own = not isinstance(media, MediaSource)
    source = open_media(media) if own else media
    n_c, n_p = len(CURVE_NAMES), len(POINT_NAMES)
    try:
        total = source.frame_count
        if max_frames is not None:
            total = min(total, max_frames) if total is not None else max_frames
        feats: list[FrameFeatures] = []
        bar = tqdm(total=total, unit="frame", desc=f"track ({tracker.name})", disable=not _want_bar(progress),
                   dynamic_ncols=True, leave=False)
        t_track = 0.0
        with bar:
            for i, rgb in enumerate(source):
                if max_frames is not None and i >= max_frames:
                    break
                t0 = time.perf_counter()
                f = tracker.track(rgb, int(round(i * 1000.0 / source.fps)))
                t_track += time.perf_counter() - t0
                if f.curves.shape != (n_c, 4, 2) or f.points.shape != (n_p, 3):
                    raise ValueError(f"tracker {tracker.name!r} returned curves {f.curves.shape} and points "
                                     f"{f.points.shape}; expected ({n_c}, 4, 2) and ({n_p}, 3)")
                feats.append(f)
                if on_frame is not None:
                    on_frame(i, rgb, f)
                bar.update(1)
                if t_track > 0:
                    bar.set_postfix_str(f"{len(feats) / t_track:.0f} fps tracking", refresh=False)
    finally:
        if own:
            source.close()
    label = getattr(source, "path", str(media))
    if not feats:
        raise FacepuppetError(f"{label}: no frames to track")
    track = features_to_track(feats, fps=source.fps, frame_size=source.frame_size, backend=tracker.name,
                              static_extras=getattr(tracker, "static_extras", None))
    if not track.valid.any():
        raise FacepuppetError(f"{label}: no face found in any of its {len(feats)} frame(s)")
    log.info("%s: tracked %d of %d frames (%.0f fps tracking)", label, track.valid.sum(), len(feats),
             len(feats) / max(t_track, 1e-9))
    return track


def features_to_track(feats: list[FrameFeatures], *, fps: float, frame_size, backend: str,
                      static_extras: dict | None = None) -> Track:
    """A :class:`~facepuppet.io.track.Track` of per-frame features, in order.

    Per-frame extras become ``(F, ...)`` arrays (NaN where a frame lacks one); ``static_extras`` are added as
    they are; every array of a frame without a face is NaN (the track file's contract).
    """
    valid = np.array([f.valid for f in feats], dtype=bool)
    extras = _stack_extras([f.extras for f in feats], len(feats))
    for k, v in (static_extras or {}).items():
        extras[k] = np.asarray(v)
    arrays = {k: np.stack([np.asarray(getattr(f, k), dtype=float) for f in feats])
              for k in ("curves", "points", "rotation", "translation")}
    for a in arrays.values():
        a[~valid] = np.nan  # a frame without a face holds no numbers (track file contract)
    return Track(fps=float(fps), frame_size=np.asarray(frame_size, dtype=int), valid=valid,
                 curve_names=CURVE_NAMES, point_names=POINT_NAMES, backend=backend, extras=extras or None,
                 **arrays)
