"""Latency percentiles and frame rate of a live session in bounded memory (``--stats STATS.json``).

Latencies go into a histogram of logarithmically spaced bins (:data:`BINS_PER_DECADE` per decade from
:data:`MIN_LATENCY_S` to :data:`MAX_LATENCY_S`), so memory is fixed however long the session; a percentile
is the geometric centre of the bin holding that rank (relative error at most half a bin,
10**(0.5 / BINS_PER_DECADE) - 1 = 0.058 %), the maximum is exact. Latencies below the first bin count in it,
above the last in the last.
"""

from __future__ import annotations

import json
import math
import os

import numpy as np

from facepuppet._util.atomic import atomic_path

__all__ = ["LatencyStats", "BINS_PER_DECADE", "MIN_LATENCY_S", "MAX_LATENCY_S"]

#: Histogram resolution: bins per factor of ten.
BINS_PER_DECADE = 2000
#: Lowest and highest latency the bins resolve, seconds.
MIN_LATENCY_S = 1e-6
MAX_LATENCY_S = 100.0
_N_BINS = int(round(BINS_PER_DECADE * math.log10(MAX_LATENCY_S / MIN_LATENCY_S)))


class LatencyStats:
    """Frames, dropped frames, latency percentiles and fps of a session.

    ``add(latency_s, time_s)`` once per frame sent (latency from capture to sent, and the wall-clock or
    stream time of the frame), ``drop()`` once per frame dropped; :meth:`summary` gives the figures.
    """

    def __init__(self) -> None:
        self._counts = np.zeros(_N_BINS, dtype=np.int64)
        self.frames = 0
        self.dropped = 0
        self.max = 0.0
        self._first: float | None = None
        self._last: float | None = None

    def add(self, latency_s: float, time_s: float) -> None:
        """Count one frame sent ``latency_s`` seconds after capture, at ``time_s`` seconds (any clock)."""
        latency_s = float(latency_s)
        if not math.isfinite(latency_s):
            raise ValueError(f"latency must be a finite number of seconds, got {latency_s}")
        b = math.floor(BINS_PER_DECADE * math.log10(max(latency_s, MIN_LATENCY_S) / MIN_LATENCY_S))
        self._counts[min(max(b, 0), _N_BINS - 1)] += 1
        self.frames += 1
        self.max = max(self.max, latency_s)
        if self._first is None:
            self._first = float(time_s)
        self._last = float(time_s)

    def drop(self, n: int = 1) -> None:
        """Count ``n`` frames dropped (never sent)."""
        self.dropped += int(n)

    def percentile(self, q: float) -> float:
        """The ``q``-th percentile latency in seconds (nearest rank: the smallest latency with at least q % of
        the frames at or below it), NaN before any frame."""
        if not 0 <= q <= 100:
            raise ValueError(f"q must be in 0..100, got {q}")
        if self.frames == 0:
            return math.nan
        rank = max(1, math.ceil(q / 100 * self.frames))
        b = int(np.searchsorted(np.cumsum(self._counts), rank))
        return min(MIN_LATENCY_S * 10 ** ((b + 0.5) / BINS_PER_DECADE), self.max)

    @property
    def fps(self) -> float:
        """Frames sent per second between the first and the last frame (NaN with fewer than two)."""
        if self.frames < 2 or self._last is None or self._last <= self._first:
            return math.nan
        return (self.frames - 1) / (self._last - self._first)

    def summary(self) -> dict:
        """``{"frames", "dropped", "latency_ms": {"p50", "p95", "p99", "max"}, "fps"}`` (NaN as null)."""
        def ms(x: float):
            return None if math.isnan(x) else round(x * 1e3, 4)

        fps = self.fps
        return {"frames": self.frames, "dropped": self.dropped,
                "latency_ms": {"p50": ms(self.percentile(50)), "p95": ms(self.percentile(95)),
                               "p99": ms(self.percentile(99)), "max": ms(self.max) if self.frames else None},
                "fps": None if math.isnan(fps) else round(fps, 4)}

    def write(self, path: str | os.PathLike) -> None:
        """Write :meth:`summary` as JSON, atomically."""
        with atomic_path(path, suffix=".json") as tmp:
            with open(tmp, "w", encoding="utf-8") as fh:
                json.dump(self.summary(), fh, indent=2)
                fh.write("\n")
