"""Which frames make a key expression: the steadiest run of frames near a chosen one, averaged."""

from __future__ import annotations

import os

import numpy as np

from facepuppet.errors import FacepuppetError
from facepuppet.io.track import Track
from facepuppet.pipeline.examples.config import ExamplesConfig

__all__ = ["steadiest_window", "average_near", "lowest_window", "need_faces"]


def steadiest_window(points: np.ndarray, valid: np.ndarray, centre: int, radius: int,
                     window: int) -> tuple[int, int] | None:
    """The run of ``window`` valid frames near ``centre`` where the feature points move least.

    Parameters
    ----------
    points : (F, P, D) float
    valid : (F,) bool
    centre : int
        The marked frame.
    radius : int
        Frames either side of ``centre`` the window may reach.
    window : int
        Frames in the window (fewer if the video is shorter).

    Returns
    -------
    (start, stop) or None
        The window ``[start, stop)``: least summed squared frame-to-frame motion, ties to the one nearest
        ``centre``; None if no run of valid frames of that length lies within reach.
    """
    n = len(valid)
    window = max(1, min(window, n))
    lo, hi = max(0, centre - radius), min(n, centre + radius + 1)
    best, best_key = None, None
    step = np.zeros(n)
    if n > 1:
        d = np.diff(points, axis=0)
        step[1:] = np.einsum("fpd,fpd->f", d, d)
    for start in range(lo, hi - window + 1):
        stop = start + window
        if not valid[start:stop].all():
            continue
        motion = float(step[start + 1:stop].sum())
        key = (motion, abs((start + stop - 1) / 2 - centre))
        if best_key is None or key < best_key:
            best, best_key = (start, stop), key
    return best


def average_near(track: Track, name: str, centre: int, config: ExamplesConfig,
                 ) -> tuple[np.ndarray, tuple[int, int]]:
    """The feature points (P, D) of the steadiest window within ``config.search`` seconds of frame ``centre``,
    averaged, and the window ``[start, stop)``.

    With too few valid frames for a full window, every valid frame within reach is averaged.

    Raises
    ------
    FacepuppetError
        If no frame within reach has a face (``name`` says which key expression it was for).
    """
    radius = int(round(config.search * track.fps))
    usable = track.valid & np.isfinite(track.points).all(axis=(1, 2))    # a face whose head pose was solved
    span = steadiest_window(track.points, usable, centre, radius, config.window)
    if span is None:
        lo, hi = max(0, centre - radius), min(track.n_frames, centre + radius + 1)
        idx = np.flatnonzero(usable[lo:hi]) + lo
        if len(idx) == 0:
            raise FacepuppetError(f"{name} (frame {centre}): no face was tracked within {config.search:g} s "
                                  f"of it")
        span = (int(idx[0]), int(idx[-1]) + 1)
        return track.points[idx].mean(axis=0), span
    return track.points[span[0]:span[1]].mean(axis=0), span


def lowest_window(cost: np.ndarray, usable: np.ndarray, window: int) -> tuple[int, int] | None:
    """The run of ``window`` usable frames anywhere in the clip whose mean ``cost`` is lowest.

    Parameters
    ----------
    cost : (F,) float
        Each frame's cost (non-finite where the frame cannot be used).
    usable : (F,) bool
    window : int
        Frames in the run (fewer if the clip is shorter).

    Returns
    -------
    (start, stop) or None
        The run ``[start, stop)`` (the earliest of equal ones); None if no run of usable frames is that long.
    """
    n = len(usable)
    window = max(1, min(window, n))
    good = usable & np.isfinite(cost)
    c = np.where(good, cost, 0.0)
    sums = np.convolve(c, np.ones(window), mode="valid")                     # (n - window + 1,)
    full = np.convolve(good.astype(float), np.ones(window), mode="valid") == window
    if not full.any():
        return None
    start = int(np.argmin(np.where(full, sums, np.inf)))
    return start, start + window


def need_faces(track: Track, media: str | os.PathLike) -> None:
    """Raise FacepuppetError naming ``media`` when no frame of ``track`` has a face."""
    if not np.any(track.valid):
        raise FacepuppetError(f"{media}: no face was tracked in any frame")
