"""The user's journey as library calls: capture the performer's key expressions, fit the rig, animate.

Orchestration only: tracking lives in :mod:`facepuppet.capture`, mapping in :mod:`facepuppet.mapping`,
file formats in :mod:`facepuppet.io` and :mod:`facepuppet.export`.

- :mod:`.tracking`: which tracker makes the features (:class:`TrackerOptions`);
- :mod:`.examples`: capturing the performer's key expressions (``from_marks``, ``from_auto``,
  ``from_camera``; :class:`ExamplesConfig`);
- :mod:`.profile`: training the colour tracker's performer profile on a clip (:func:`train_profile_on_media`);
- :mod:`.rig`: pairing key expressions with key-models and fitting the mapper (:func:`fit_rig`), the rig file;
- :mod:`.animate`: a performance mapped onto the rig's character, smoothed (:mod:`.smoothing`) and scaled
  (:mod:`.gain`).
"""

from __future__ import annotations

import importlib

__all__ = [
    "TrackerOptions",
    "ExamplesConfig",
    "examples",
    "train_profile_on_media",
    "Rig",
    "Pairing",
    "pair_by_name",
    "fit_rig",
    "save_rig",
    "load_rig",
    "SmoothingConfig",
    "OneEuroFilter",
    "smooth",
    "GainConfig",
    "apply_gain",
    "parse_gain",
    "AnimateConfig",
    "Animation",
    "animate",
    "map_track",
]

_WHERE = {
    "TrackerOptions": "tracking",
    "ExamplesConfig": "examples",
    "train_profile_on_media": "profile",
    "Rig": "rig",
    "Pairing": "rig",
    "pair_by_name": "rig",
    "fit_rig": "rig",
    "save_rig": "rig",
    "load_rig": "rig",
    "SmoothingConfig": "smoothing",
    "OneEuroFilter": "smoothing",
    "smooth": "smoothing",
    "GainConfig": "gain",
    "apply_gain": "gain",
    "parse_gain": "gain",
    "AnimateConfig": "animate",
    "Animation": "animate",
    "animate": "animate",
    "map_track": "animate",
}
#: Subpackages reached as attributes.
_SUBPACKAGES = ("examples",)


def __getattr__(name: str):
    # Lazy: examples and animate pull in the trackers and exporters, smoothing and gain need numpy only.
    if name in _SUBPACKAGES:
        return importlib.import_module(f"facepuppet.pipeline.{name}")
    if name in _WHERE:
        return getattr(importlib.import_module(f"facepuppet.pipeline.{_WHERE[name]}"), name)
    raise AttributeError(f"module 'facepuppet.pipeline' has no attribute {name!r}")
