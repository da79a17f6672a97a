"""Expression gain: attenuate or exaggerate the animation, globally, per key-model or per region.

Notes
-----
A name in ``--gain NAME=VALUE`` is a key-model of the rig or a region of the face (``ExpressionMapper.
region_names`` of a regional rig; for any other rig the regions the regional mapping would find on the rig's
key-models, :func:`facepuppet.mapping.motion_regions`). ``mouth`` names the regions ``mouth``, ``mouth_L``,
``mouth_R``, ``mouth_2``, ... (a region's name without its side and number; a trailing ``s`` is dropped, so
``brows`` names the ``brow`` regions). Regions are named after the key-model that placed them by its leading
lowercase word and side (``jaw``, ``mouth``, ``eye_L``, ``brow_R``, ``cheek``, ``nose``); ``background`` is
the rest of the face. A name that is a key-model and also names a region is refused (ambiguous), and so is a
name that is neither.

Regional rig (weights w_ik per region k): in region k the gain of key-model i is the key-model's gain if only
it is named, the region's if only the region is named, their product if both are, and the global gain
otherwise. Global rig (one weight per key-model): a region's gain applies to the key-models whose
displacement lies mostly in the named regions, i.e. more than half of sum_v ||T_i(v) - T_B(v)||^2 falls in
them, each vertex counted with its region mask M_k(v) (:func:`facepuppet.mapping.region_shares`); with the
same product rule. A region name that takes no key-model of a global rig is refused.

The weights of frame k become ``clip(g * w_k, low, high * max(1, g))`` channel by channel, with g the gain of
that key-model. Clipping (defaults ``low = 0``, ``high = 1``) keeps the character within the span its
designer modelled: a negative weight of a key-model is the opposite of that expression and looks wrong on
most characters, and a weight above 1 over-drives it. A gain above 1 raises the upper bound in proportion,
so ``--gain jawOpen=1.5`` can open the jaw up to 1.5 times its key-model; a gain below 1 keeps the bound 1.
Set ``low``/``high`` to None to switch either bound off.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

__all__ = ["GainConfig", "parse_gain", "gain_vector", "gain_matrix", "key_gain", "rig_gain", "apply_gain",
           "region_matches", "MAX_GAIN"]


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

    A bare number sets the global gain; ``NAME=VALUE`` the gain of one key-model or region. Comma-separated
    lists are accepted too (``"1.1,jawOpen=1.5"``). A second global gain, or a second gain for the same name,
    is an error (no value silently wins over another).
    """
    gain, per_key, seen_global = 1.0, {}, False
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
                if name.strip() in per_key:
                    raise ValueError(f"--gain {name.strip()}: given twice ({per_key[name.strip()]:g} and {g:g})")
                per_key[name.strip()] = g
            else:
                if seen_global:
                    raise ValueError(f"--gain: two overall gains given ({gain:g} and {g:g}); give one")
                gain, seen_global = g, True
    return GainConfig(gain=gain, per_key=per_key)


def region_matches(name: str, region: str) -> bool:
    """True when the gain name ``name`` names ``region`` (module notes: exact, or its stem without side/number)."""
    stem = re.sub(r"(_[LR])?(_\d+)?$", "", region)
    return name in (region, stem) or (name.endswith("s") and name[:-1] == stem)


def _check_names(config: GainConfig, names: Sequence[str], regions: Sequence[str]) -> None:
    """Every name in ``per_key`` is a key-model or names a region, not both (one error listing the valid ones)."""
    both = sorted(n for n in config.per_key if n in names and any(region_matches(n, r) for r in regions))
    if both:
        raise ValueError(f"--gain {both[0]}={config.per_key[both[0]]:g}: {both[0]!r} is both a key-model and a "
                         f"region of the rig (regions {', '.join(regions)}); ambiguous")
    unknown = sorted(n for n in config.per_key
                     if n not in names and not any(region_matches(n, r) for r in regions))
    if unknown:
        have = f"the rig has key-models {', '.join(names)}"
        if regions:
            have += f" and regions {', '.join(regions)}"
        raise ValueError(f"--gain: no key-model or region named {', '.join(unknown)} ({have})")


def gain_matrix(config: GainConfig, names: Sequence[str], regions: Sequence[str]) -> np.ndarray:
    """The gain of each (region, key-model) of a regional rig, (R, M) float (module notes).

    A name in ``per_key`` must be a key-model or name a region, not both; otherwise one error says which.
    """
    regions = list(regions)
    _check_names(config, names, regions)
    keyed = np.array([n in config.per_key for n in names])
    g = np.tile(np.array([config.per_key.get(n, config.gain) for n in names], dtype=float), (len(regions), 1))
    for k, r in enumerate(regions):
        named = [v for n, v in config.per_key.items() if n not in names and region_matches(n, r)]
        if named:
            g[k] = np.where(keyed, g[k] * named[-1], named[-1])
    return g


def key_gain(config: GainConfig, names: Sequence[str], regions: Sequence[str], shares: np.ndarray) -> np.ndarray:
    """The gain of each key-model of a global rig, (M,) float, region names allowed (module notes).

    Parameters
    ----------
    config : GainConfig
    names : sequence of M str
        Key-model names.
    regions : sequence of R str
        Region names (the background first).
    shares : (R, M) float
        Share of key-model i's squared displacement in region k (columns summing to 1).
    """
    regions = list(regions)
    _check_names(config, names, regions)
    shares = np.asarray(shares, dtype=float)
    keyed = np.array([n in config.per_key for n in names])
    g = np.array([config.per_key.get(n, config.gain) for n in names], dtype=float)
    out = g.copy()
    for n, v in config.per_key.items():
        if n in names:
            continue
        taken = shares[[k for k, r in enumerate(regions) if region_matches(n, r)]].sum(axis=0) > 0.5
        if not taken.any():
            raise ValueError(f"--gain {n}={v:g}: no key-model of the rig moves mostly in region {n} (its "
                             f"key-models lie mostly in {_mostly(names, regions, shares)})")
        out = np.where(taken, np.where(keyed, g * v, v), out)
    return out


def _mostly(names: Sequence[str], regions: Sequence[str], shares: np.ndarray) -> str:
    top = np.argmax(shares, axis=0)
    return ", ".join(f"{n}: {regions[int(k)]}" for n, k in zip(names, top, strict=True))


def rig_gain(config: GainConfig, rig) -> np.ndarray:
    """The gain of each weight channel of a rig: (M,), or (R·M,) region-major for a regional rig.

    A global rig's regions are found on its key-models only when a name needs them (module notes).
    """
    names = tuple(rig.names)
    mapper = rig.mapper
    if getattr(mapper, "regional", False):
        return gain_matrix(config, names, mapper.region_names).reshape(-1)
    base, deltas = getattr(mapper, "target_base", None), getattr(mapper, "target_deltas", None)
    if not config.per_key or base is None or deltas is None:
        return gain_vector(config, names)
    from facepuppet.mapping import METHODS, motion_regions, region_shares

    deltas = np.asarray(deltas, dtype=float)
    masks, regions = motion_regions(np.asarray(base, dtype=float), deltas, names,
                                    n_regions=int(METHODS["regional"].defaults["n_regions"]))
    return key_gain(config, names, regions, region_shares(deltas, masks))


def gain_vector(config: GainConfig, names: Sequence[str]) -> np.ndarray:
    """The gain of each key-model, (M,) float; a name in ``per_key`` that the rig lacks is an error."""
    unknown = sorted(set(config.per_key) - set(names))
    if unknown:
        raise ValueError(f"--gain: no key-model named {', '.join(unknown)} (the rig has {', '.join(names)})")
    return np.array([config.per_key.get(n, config.gain) for n in names], dtype=float)


def apply_gain(weights: np.ndarray, config: GainConfig, names: Sequence[str],
               regions: Sequence[str] | None = None) -> np.ndarray:
    """Scale and clip weights.

    Parameters
    ----------
    weights : (..., M) float, or (..., R, M) with ``regions``
    config : GainConfig
    names : sequence of M str
        Key-model names, in the order of the weights' last axis.
    regions : sequence of R str, optional
        Region names, in the order of the weights' second-to-last axis (regional weights).

    Returns
    -------
    Same shape, float, a new array; NaN stays NaN.
    """
    w = np.asarray(weights, dtype=float)
    if w.shape[-1:] != (len(names),):
        raise ValueError(f"weights must have {len(names)} channels (one per key-model), got shape {w.shape}")
    if regions is not None:
        if w.ndim < 2 or w.shape[-2] != len(regions):
            raise ValueError(f"regional weights must have shape (..., {len(regions)}, {len(names)}), got {w.shape}")
        g = gain_matrix(config, names, regions)
    else:
        g = gain_vector(config, names)
    out = w * g
    if config.low is not None:
        out = np.where(out < config.low, config.low, out)
    if config.high is not None:
        hi = config.high * np.maximum(1.0, g)
        out = np.where(out > hi, hi, out)
    return out
