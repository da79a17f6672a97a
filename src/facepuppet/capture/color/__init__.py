"""The paper's colour tracker (§3): Eq. 1 and the contrast C, blobs in anthropometric rectangles, Bezier snakes.

:class:`ColorTracker` (:mod:`.tracker`) tracks frames with a performer :class:`Profile` (:mod:`.profile`),
which :func:`train_profile` (:mod:`.train`) learns from labelled frames; :func:`precompile` compiles the
tracker's numba kernels ahead of the first frame. The names are imported on first use, so that
``python -m facepuppet.capture.color.precompile`` (the compile workers) loads only what it needs.
"""

from importlib import import_module

__all__ = ["ColorTracker", "ColorTrackerConfig", "Profile", "default_profile", "load_profile", "save_profile",
           "train_profile", "precompile"]

#: Public name -> the module of this package that defines it.
_HOME = {"ColorTracker": "tracker", "ColorTrackerConfig": "config", "Profile": "profile",
         "default_profile": "profile", "load_profile": "profile", "save_profile": "profile",
         "train_profile": "train", "precompile": "precompile"}


def __getattr__(name: str):
    if name in _HOME:
        return getattr(import_module(f"{__name__}.{_HOME[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
