"""Speed-adaptive low-pass filtering of tracked values (the One-Euro filter of Casiez et al., 2012).

Each value is smoothed by an exponential filter whose cut-off frequency rises with the value's own (filtered)
speed: ``fc = min_cutoff + beta * |speed|``. Still values are smoothed hard (small noise removed); moving
values are followed closely (little lag). Values come in *groups* of components (for a 2D point, its x and y):
the velocity of each component is low-pass filtered (cut-off ``d_cutoff``) and the group's speed is the
length of that filtered velocity, in the units of the values divided by ``scale``. Filtering the velocity
before taking its length, as the original filter does, lets the to-and-fro of noise cancel out, so a still
but noisy point keeps a low cut-off (filtering the length instead, noise alone would open the filter:
on the shared clips' dim, warm and noisy copies that doubled the jitter).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from facepuppet._util.jit import KERNEL

__all__ = ["OneEuroConfig", "OneEuro"]


@dataclass(frozen=True)
class OneEuroConfig:
    """Options of the One-Euro filter.

    Attributes
    ----------
    min_cutoff : float
        Cut-off frequency (Hz) of a still value.
    beta : float
        Rise of the cut-off frequency (Hz) per unit of speed (scaled units per second).
    d_cutoff : float
        Cut-off frequency (Hz) of the speed estimate.
    """

    min_cutoff: float = 1.0
    beta: float = 5.0
    d_cutoff: float = 1.0


class OneEuro:
    """One-Euro filter over an array of values whose last axis groups the components of one point.

    Parameters
    ----------
    config : OneEuroConfig
    """

    def __init__(self, config: OneEuroConfig = OneEuroConfig()):
        self.config = config
        self.reset()

    def reset(self) -> None:
        """Forget the past: the next value passes unchanged."""
        self._x: np.ndarray | None = None
        self._dx: np.ndarray | None = None

    def restart(self, x: np.ndarray) -> None:
        """Carry on from ``x`` (the last output), standing still: the next value is filtered towards it."""
        self._x = np.array(x, dtype=float)
        self._dx = np.zeros(self._x.shape)

    def __call__(self, x: np.ndarray, dt: float, scale: float = 1.0) -> np.ndarray:
        """Filter one sample.

        Parameters
        ----------
        x : (..., D) float
            The values (the same shape at every call).
        dt : float
            Seconds since the previous sample (> 0).
        scale : float
            Speeds are measured in units of ``x / scale``.

        Returns
        -------
        (..., D) float
            The filtered values.
        """
        x = np.asarray(x, dtype=float)
        if self._x is None or self._x.shape != x.shape or not dt > 0:
            self._x, self._dx = x.copy(), np.zeros(x.shape)
            return x.copy()
        cfg = self.config
        flat, self._dx = _kernel()(x.reshape(-1, x.shape[-1]), self._x.reshape(-1, x.shape[-1]),
                               self._dx.reshape(-1, x.shape[-1]),
                               float(dt), float(scale), float(cfg.min_cutoff), float(cfg.beta), float(cfg.d_cutoff))
        self._x = flat.reshape(x.shape)
        self._dx = self._dx.reshape(x.shape)
        return self._x.copy()


#: The compiled :func:`_step`, made on first use (importing this module leaves numba unloaded).
_COMPILED: dict = {}


def _kernel():
    """:func:`_step` compiled with numba (loaded from numba's on-disk cache after the first process)."""
    kernel = _COMPILED.get("step")
    if kernel is None:
        import numba as nb

        kernel = _COMPILED["step"] = nb.njit(**KERNEL)(_step)
    return kernel


def _step(x: np.ndarray, last: np.ndarray, velocity_last: np.ndarray, dt: float, scale: float, min_cutoff: float,
          beta: float, d_cutoff: float):
    """One step for (N, D) points: the filtered points and their filtered velocities (see :class:`OneEuro`)."""
    n, d = x.shape
    out = np.empty((n, d))
    velocity = np.empty((n, d))
    a_d = 1.0 / (1.0 + 1.0 / (2.0 * np.pi * d_cutoff * dt))
    for i in range(n):
        s = 0.0
        for k in range(d):
            velocity[i, k] = velocity_last[i, k] + a_d * ((x[i, k] - last[i, k]) / (dt * scale) - velocity_last[i, k])
            s += velocity[i, k] ** 2
        a = 1.0 / (1.0 + 1.0 / (2.0 * np.pi * (min_cutoff + beta * np.sqrt(s)) * dt))
        for k in range(d):
            out[i, k] = last[i, k] + a * (x[i, k] - last[i, k])
    return out, velocity
