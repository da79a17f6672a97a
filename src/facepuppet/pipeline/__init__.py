"""The user's journey as library calls: calibrate a performer, animate a character, smooth and scale weights.

Orchestration only: tracking lives in :mod:`facepuppet.capture`, mapping in :mod:`facepuppet.mapping`,
file formats in :mod:`facepuppet.io` and :mod:`facepuppet.export`.
"""

from __future__ import annotations

import importlib

__all__ = [
    "SmoothingConfig",
    "OneEuroFilter",
    "smooth",
    "GainConfig",
    "apply_gain",
    "parse_gain",
    "CalibrateConfig",
    "calibrate",
    "AnimateConfig",
    "Animation",
    "animate",
    "map_track",
]

_WHERE = {
    "SmoothingConfig": "smoothing",
    "OneEuroFilter": "smoothing",
    "smooth": "smoothing",
    "GainConfig": "gain",
    "apply_gain": "gain",
    "parse_gain": "gain",
    "CalibrateConfig": "calibrate",
    "calibrate": "calibrate",
    "AnimateConfig": "animate",
    "Animation": "animate",
    "animate": "animate",
    "map_track": "animate",
}


def __getattr__(name: str):
    # Lazy: calibrate and animate pull in the trackers and exporters, smoothing and gain need numpy only.
    if name in _WHERE:
        return getattr(importlib.import_module(f"facepuppet.pipeline.{_WHERE[name]}"), name)
    raise AttributeError(f"module 'facepuppet.pipeline' has no attribute {name!r}")
