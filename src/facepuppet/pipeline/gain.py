"""Expression gain: attenuate or exaggerate the animation, globally or per key-model.

Notes
-----
The weights of frame k become ``clip(g * w_k, low, high * max(1, g))`` channel by channel, with g the gain of
that key-model. Clipping (defaults ``low = 0``, ``high = 1``) keeps the character within the span its
designer modelled: a negative weight of a key-model is the opposite of that expression and looks wrong on
most characters, and a weight above 1 over-drives it. A gain above 1 raises the upper bound in proportion,
so ``--gain jawOpen=1.5`` can open the jaw up to 1.5 times its key-model; a gain below 1 keeps the bound 1.
Set ``low``/``high`` to None to switch either bound off.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

__all__ = ["GainConfig", "parse_gain", "gain_vector", "apply_gain", "MAX_GAIN"]


#: Largest expression gain accepted: beyond it every weight is clipped at once (a typing slip, not a choice).
MAX_GAIN = 100.0


@dataclass(frozen=True, kw_only=True)
class GainConfig:
    """Expression gain.

    Attributes
    ----------
    gain : float
        Gain of every key-model not named in ``per_key``.
    per_key : dict of str -> float
        Gain of named key-models.
    low, high : float or None
        Clipping bounds (see the module notes); None switches a bound off.
    """

    gain: float = 1.0
    per_key: dict[str, float] = field(default_factory=dict)
    low: float | None = 0.0
    high: float | None = 1.0

    def __post_init__(self) -> None:
        for name, g in [("gain", self.gain), *self.per_key.items()]:
            if not np.isfinite(g):
                raise ValueError(f"--gain {name}: must be a finite number, got {g}")
            if not 0.0 <= g <= MAX_GAIN:
                raise ValueError(f"--gain {name}: must be between 0 and {MAX_GAIN:g}, got {g:g}")


def parse_gain(specs: Iterable[str] | None) -> GainConfig:
    """Build a GainConfig from CLI values such as ``["1.2"]``, ``["jawOpen=1.5", "eyeBlink_L=0.8"]``.

    A bare number sets the global gain; ``NAME=VALUE`` the gain of one key-model. Comma-separated lists are
    accepted too (``"1.1,jawOpen=1.5"``).
    """
    gain, per_key = 1.0, {}
    for spec in specs or ():
        for part in str(spec).split(","):
            part = part.strip()
            if not part:
                continue
            name, sep, value = part.rpartition("=")
            try:
                g = float(value)
            except ValueError:
                raise ValueError(f"--gain: expected NUMBER or NAME=NUMBER, got {part!r}") from None
            if sep:
                if not name.strip():
                    raise ValueError(f"--gain: empty key-model name in {part!r}")
                per_key[name.strip()] = g
            else:
                gain = g
    return GainConfig(gain=gain, per_key=per_key)


def gain_vector(config: GainConfig, names: Sequence[str]) -> np.ndarray:
    """The gain of each key-model, (M,) float; a name in ``per_key`` that the rig lacks is an error."""
    unknown = sorted(set(config.per_key) - set(names))
    if unknown:
        raise ValueError(f"--gain: no key-model named {', '.join(unknown)} (the rig has {', '.join(names)})")
    return np.array([config.per_key.get(n, config.gain) for n in names], dtype=float)


def apply_gain(weights: np.ndarray, config: GainConfig, names: Sequence[str]) -> np.ndarray:
    """Scale and clip weights.

    Parameters
    ----------
    weights : (..., M) float
    config : GainConfig
    names : sequence of M str
        Key-model names, in the order of the weights' last axis.

    Returns
    -------
    (..., M) float, a new array; NaN stays NaN.
    """
    w = np.asarray(weights, dtype=float)
    if w.shape[-1:] != (len(names),):
        raise ValueError(f"weights must have {len(names)} channels (one per key-model), got shape {w.shape}")
    g = gain_vector(config, names)
    out = w * g
    if config.low is not None:
        out = np.where(out < config.low, config.low, out)
    if config.high is not None:
        hi = config.high * np.maximum(1.0, g)
        out = np.where(out > hi, hi, out)
    return out
