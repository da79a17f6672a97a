"""Adaptive smoothing of per-frame blend weights: the One-Euro filter, with a hold-then-ease for lost frames.

The One-Euro filter (Casiez, Roussel and Vogel, CHI 2012) is a first-order low-pass filter whose cut-off
frequency rises with the speed of the signal: slow movements (where jitter shows) are smoothed hard, fast
movements (where lag shows) pass almost untouched.

Notes
-----
For a sample x_t at time t, with T = t - t_prev::

    alpha(fc)  = 1 / (1 + tau / T),   tau = 1 / (2 pi fc)
    dx_t       = alpha(d_cutoff) (x_t - y_prev) / T + (1 - alpha(d_cutoff)) dx_prev
    fc         = min_cutoff + beta |dx_t|
    y_t        = alpha(fc) x_t + (1 - alpha(fc)) y_prev

Each channel (key-model weight) has its own cut-off (the filter is :class:`~facepuppet.filters.OneEuro`
with one-component groups). Defaults (:class:`SmoothingConfig`), chosen for blend
weights in [0, 1] at 24-60 frames per second: ``min_cutoff = 1.5`` Hz removes tracking jitter of a still face
(white noise variance falls about six-fold at 30 fps); ``beta = 2.0`` opens the filter to about 10 Hz during a
fast expression change (a jaw opening in 0.2 s moves the weight at about 5 per second), so the delay there
is one or two frames, below what the eye notices; ``d_cutoff = 1.0`` Hz smooths the speed estimate.

Lost frames: the last output is held for ``hold`` seconds (a blink of the tracker should not make the
character twitch), then eased to the neutral value (weights 0) with a smoothstep over ``ease`` seconds.
When the face returns the filter carries on from wherever the output stands, so nothing jumps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from facepuppet.filters import OneEuro, OneEuroConfig

__all__ = ["SmoothingConfig", "OneEuroFilter", "smooth", "parse_smoothing"]


@dataclass(frozen=True, kw_only=True)
class SmoothingConfig:
    """Options of the One-Euro filter and of the lost-frame behaviour.

    Attributes
    ----------
    enabled : bool
        False passes valid frames through unchanged (lost frames still hold, then ease).
    min_cutoff : float
        Cut-off frequency in Hz of a still signal; lower removes more jitter.
    beta : float
        Growth of the cut-off with the signal's speed (Hz per unit per second); higher means less lag.
    d_cutoff : float
        Cut-off frequency in Hz of the speed estimate.
    hold : float
        Seconds a lost face keeps its last output.
    ease : float
        Seconds over which the output then eases to neutral.
    """

    enabled: bool = True
    min_cutoff: float = 1.5
    beta: float = 2.0
    d_cutoff: float = 1.0
    hold: float = 0.25
    ease: float = 0.3

    def __post_init__(self) -> None:
        for name in ("min_cutoff", "d_cutoff"):
            if not getattr(self, name) > 0:
                raise ValueError(f"smoothing {name} must be > 0, got {getattr(self, name)}")
        for name in ("beta", "hold", "ease"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"smoothing {name} must be >= 0, got {getattr(self, name)}")
        for name in ("min_cutoff", "d_cutoff", "beta", "hold", "ease"):   # inf * 0 would make the weights NaN
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"smoothing {name} must be a finite number, got {getattr(self, name)}")


def parse_smoothing(text: str) -> SmoothingConfig:
    """Parse the CLI's ``--smoothing`` value: ``on``, ``off`` or ``key=value,...`` (keys of SmoothingConfig).

    Example
    -------
    >>> parse_smoothing("min_cutoff=1.0,beta=0.5").beta
    0.5
    """
    text = text.strip()
    if text.lower() in ("on", "yes", "true", "default", ""):
        return SmoothingConfig()
    if text.lower() in ("off", "no", "false", "none"):
        return SmoothingConfig(enabled=False)
    fields = {f for f in SmoothingConfig.__dataclass_fields__ if f != "enabled"}
    values: dict[str, float] = {}
    for part in text.split(","):
        key, sep, value = part.partition("=")
        key = key.strip()
        if not sep or key not in fields:
            raise ValueError(f"--smoothing: expected on, off or key=value with keys {', '.join(sorted(fields))}; "
                             f"got {part!r}")
        try:
            values[key] = float(value)
        except ValueError:
            raise ValueError(f"--smoothing: {key} must be a number, got {value!r}") from None
    return replace(SmoothingConfig(), **values)


class OneEuroFilter:
    """A streaming One-Euro filter over a vector of channels, with hold-then-ease on lost frames.

    Parameters
    ----------
    n_channels : int
        Number of channels M (key-models).
    config : SmoothingConfig, optional
    neutral : (M,) float, optional
        The value lost frames ease to; zeros (the neutral face) by default.

    Example
    -------
    >>> f = OneEuroFilter(2)
    >>> f.update(np.array([0.5, 0.0]), t=0.0)
    array([0.5, 0. ])
    """

    def __init__(self, n_channels: int, config: SmoothingConfig | None = None,
                 neutral: np.ndarray | None = None) -> None:
        self.config = config or SmoothingConfig()
        self.neutral = np.zeros(n_channels) if neutral is None else np.asarray(neutral, dtype=float).copy()
        if self.neutral.shape != (n_channels,):
            raise ValueError(f"neutral must have shape ({n_channels},), got {self.neutral.shape}")
        self.n_channels = n_channels
        self.reset()

    def reset(self) -> None:
        """Forget the past: the next valid sample passes unchanged."""
        cfg = self.config
        self._euro = OneEuro(OneEuroConfig(min_cutoff=cfg.min_cutoff, beta=cfg.beta, d_cutoff=cfg.d_cutoff))
        self._y: np.ndarray | None = None       # last output
        self._t: float | None = None            # time of the last output
        self._lost_since: float | None = None   # time of the first lost frame of the current gap
        self._held: np.ndarray | None = None    # output when the gap began

    def update(self, x: np.ndarray | None, t: float) -> np.ndarray:
        """Filter one sample.

        Parameters
        ----------
        x : (M,) float or None
            The sample; None (or any NaN) marks a lost frame.
        t : float
            Its time in seconds, increasing.

        Returns
        -------
        (M,) float
            The filtered value (a new array).
        """
        lost = x is None
        if not lost:
            x = np.asarray(x, dtype=float)
            if x.shape != (self.n_channels,):
                raise ValueError(f"sample must have shape ({self.n_channels},), got {x.shape}")
            lost = not np.isfinite(x).all()
        if lost:
            return self._lost(t)
        self._lost_since = self._held = None
        if self._y is None or self._t is None or not self.config.enabled:
            self._y, self._t = x.copy(), t
            self._euro.restart(x[:, None])
            return x.copy()
        dt = t - self._t
        self._y = self._euro(x[:, None], dt if dt > 0 else 1e-3)[:, 0]
        self._t = t
        return self._y.copy()

    def _lost(self, t: float) -> np.ndarray:
        cfg = self.config
        if self._y is None:
            return self.neutral.copy()
        if self._lost_since is None:
            self._lost_since, self._held = t, self._y.copy()
        gap = t - self._lost_since
        if gap <= cfg.hold:
            s = 0.0
        elif cfg.ease <= 0:
            s = 1.0
        else:
            u = min(1.0, (gap - cfg.hold) / cfg.ease)
            s = u * u * (3.0 - 2.0 * u)      # smoothstep
        self._y = (1.0 - s) * self._held + s * self.neutral
        self._euro.restart(self._y[:, None])
        self._t = t
        return self._y.copy()


def smooth(weights: np.ndarray, fps: float, valid: np.ndarray | None = None,
           config: SmoothingConfig | None = None, neutral: np.ndarray | None = None) -> np.ndarray:
    """Filter a whole sequence of weights (batch form of :class:`OneEuroFilter`).

    Parameters
    ----------
    weights : (F, M) float
        Weights per frame; rows of lost frames may hold anything (NaN is fine).
    fps : float
        Frame rate; frame k is at time k / fps.
    valid : (F,) bool, optional
        Frames with a tracked face; by default the rows without NaN.
    config : SmoothingConfig, optional
    neutral : (M,) float, optional
        What lost frames ease to (zeros by default).

    Returns
    -------
    (F, M) float
    """
    w = np.asarray(weights, dtype=float)
    if w.ndim != 2:
        raise ValueError(f"weights must have shape (F, M), got {w.shape}")
    if not fps > 0:
        raise ValueError(f"fps must be > 0, got {fps}")
    ok = np.isfinite(w).all(axis=1) if valid is None else np.asarray(valid, dtype=bool)
    if ok.shape != (len(w),):
        raise ValueError(f"valid must have shape ({len(w)},), got {ok.shape}")
    f = OneEuroFilter(w.shape[1], config, neutral)
    out = np.empty_like(w)
    for k in range(len(w)):
        out[k] = f.update(w[k] if ok[k] else None, k / fps)
    return out
