"""The performer's key expressions file (``EXAMPLES.npz``): the paper's source base and source examples.

``facepuppet calibrate`` writes it; ``facepuppet rig`` pairs its examples with a character's key-models by
name. It is a NumPy ``.npz`` archive read without pickle:

=================  ===========  ==========================================================================
key                shape        meaning
=================  ===========  ==========================================================================
``format``         ()           the string ``"facepuppet-performer"``
``version``        ()           integer format version, currently 1
``neutral``        (P, D)       feature points of the relaxed face (source base S_B), D = 2 or 3
``examples``       (M, P, D)    feature points of each key expression (source examples S_i)
``names``          (M,)         name of each key expression; pairs it with the key-model of the same name
``point_names``    (P,)         optional: names of the feature points (as in the track file)
``noise``          (P, D)       optional: noise scale of each coordinate as the tracker gives it (> 0)
``nuisance``       (K, P, D)    optional: feature points of frames whose motion is not an expression (a
                                neutral face while the head moves); the mapping discounts that motion
=================  ===========  ==========================================================================

Feature points are in head coordinates (head pose removed), the same space as the track file's ``points``.
Names are unique, non-empty and compared exactly (case-sensitive). All values are finite.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from facepuppet._util.atomic import atomic_path
from facepuppet._util.npz import check_format, read_npz
from facepuppet.errors import FacepuppetError

__all__ = ["Performer", "save_performer", "load_performer", "PERFORMER_FORMAT", "PERFORMER_VERSION"]

PERFORMER_FORMAT = "facepuppet-performer"
PERFORMER_VERSION = 1


@dataclass(frozen=True)
class Performer:
    """A performer's neutral face and named key expressions, as feature points.

    Attributes
    ----------
    neutral : (P, D) float
        Source base S_B.
    examples : (M, P, D) float
        Source examples S_i.
    names : tuple of M str
    point_names : tuple of P str, or None
    noise : (P, D) float, or None
        Noise scale of each feature coordinate as the tracker gives it (positive; see
        :func:`facepuppet.mapping.noise.coordinate_noise`): the mapping divides displacements by it.
        None: all coordinates alike.
    nuisance : (K, P, D) float, or None
        Feature points of frames whose motion away from ``neutral`` is no expression (the neutral face while
        the head moves, or what the tracker adds that no key expression explains): the mapping discounts
        the directions they move in (the mapper's ``nuisance`` option).
    frames : dict of str -> (int, int)
        Where the key expressions came from: for each name (``neutral`` included), the frames
        ``[start, stop)`` of the footage that were averaged. Not stored in the file (empty when loaded).
    warnings : tuple of str
        What the checks of :mod:`facepuppet.pipeline.examples.checks` found, and the key-models left out
        (messages starting with ``"left out "``). Not stored in the file (empty when loaded).
    backend : str or None
        The tracker that made the feature points (``"color"``, ``"mediapipe"``); None when unknown.
    profile_hash : str or None
        Content hash of the colour tracker's performer profile used; None when none or unknown.
    """

    neutral: np.ndarray
    examples: np.ndarray
    names: tuple[str, ...]
    point_names: tuple[str, ...] | None = None
    noise: np.ndarray | None = None
    nuisance: np.ndarray | None = None
    frames: dict[str, tuple[int, int]] = field(default_factory=dict, compare=False)
    warnings: tuple[str, ...] = field(default=(), compare=False)
    backend: str | None = None
    profile_hash: str | None = None

    def __post_init__(self) -> None:
        n, e = np.shape(self.neutral), np.shape(self.examples)
        if len(n) != 2 or n[1] not in (2, 3) or n[0] < 1:
            raise ValueError(f"neutral must have shape (P, 2) or (P, 3), got {n}")
        if len(e) != 3 or e[1:] != n or e[0] < 1:
            raise ValueError(f"examples must have shape (M, {n[0]}, {n[1]}) with M >= 1, got {e}")
        if not (np.all(np.isfinite(self.neutral)) and np.all(np.isfinite(self.examples))):
            raise ValueError("neutral and examples must be finite (no NaN or inf)")
        if len(self.names) != e[0]:
            raise ValueError(f"names must hold {e[0]} names, one per example, got {len(self.names)}")
        if any(not isinstance(x, str) or not x for x in self.names):
            raise ValueError("names must be non-empty strings")
        if len(set(self.names)) != len(self.names):
            dup = sorted({x for x in self.names if self.names.count(x) > 1})
            raise ValueError(f"example names must be unique; repeated: {', '.join(dup)}")
        if self.point_names is not None and len(self.point_names) != n[0]:
            raise ValueError(f"point_names must hold {n[0]} names, got {len(self.point_names)}")
        if self.noise is not None:
            z = np.asarray(self.noise)
            if z.shape != n or not (np.all(np.isfinite(z)) and np.all(z > 0)):
                raise ValueError(f"noise must hold positive finite numbers with shape {n}, got shape {z.shape}")
        if self.nuisance is not None:
            z = np.asarray(self.nuisance)
            if z.ndim != 3 or z.shape[1:] != n or len(z) < 1 or not np.all(np.isfinite(z)):
                raise ValueError(f"nuisance must hold finite numbers with shape (K, {n[0]}, {n[1]}), "
                                 f"got shape {z.shape}")


#: The members a key expressions file may hold.
PERFORMER_KEYS = ("format", "version", "neutral", "examples", "names", "point_names", "noise", "nuisance",
                  "backend", "profile_hash")


def save_performer(path: str | os.PathLike, performer: Performer) -> None:
    """Write ``performer`` to ``path`` (.npz, no pickle), atomically."""
    arrays = {
        "format": np.asarray(PERFORMER_FORMAT),
        "version": np.asarray(PERFORMER_VERSION, dtype=np.int64),
        "neutral": np.asarray(performer.neutral, dtype=np.float64),
        "examples": np.asarray(performer.examples, dtype=np.float64),
        "names": np.asarray(performer.names, dtype=str),
    }
    if performer.point_names is not None:
        arrays["point_names"] = np.asarray(performer.point_names, dtype=str)
    if performer.noise is not None:
        arrays["noise"] = np.asarray(performer.noise, dtype=np.float64)
    if performer.nuisance is not None:
        arrays["nuisance"] = np.asarray(performer.nuisance, dtype=np.float64)
    if performer.backend is not None:
        arrays["backend"] = np.asarray(performer.backend)
    if performer.profile_hash is not None:
        arrays["profile_hash"] = np.asarray(performer.profile_hash)
    with atomic_path(path, suffix=".npz") as tmp:
        np.savez_compressed(tmp, **arrays)


def load_performer(path: str | os.PathLike) -> Performer:
    """Read a key expressions file; anything wrong with it raises FacepuppetError naming the file."""
    arrays = read_npz(path, "key expressions file", known=PERFORMER_KEYS)
    check_format(arrays, path, "key expressions file", PERFORMER_FORMAT, PERFORMER_VERSION)
    missing = [k for k in ("neutral", "examples", "names") if k not in arrays]
    if missing:
        raise FacepuppetError(f"{path}: key expressions file lacks {', '.join(missing)}")
    try:
        point_names = arrays.get("point_names")
        return Performer(
            neutral=arrays["neutral"].astype(np.float64),
            examples=arrays["examples"].astype(np.float64),
            names=tuple(str(n) for n in np.atleast_1d(arrays["names"])),
            point_names=None if point_names is None else tuple(str(n) for n in np.atleast_1d(point_names)),
            noise=arrays["noise"].astype(np.float64) if "noise" in arrays else None,
            nuisance=arrays["nuisance"].astype(np.float64) if "nuisance" in arrays else None,
            backend=str(arrays["backend"]) if "backend" in arrays else None,
            profile_hash=str(arrays["profile_hash"]) if "profile_hash" in arrays else None,
        )
    except (ValueError, TypeError, IndexError, KeyError) as e:
        raise FacepuppetError(f"{path}: invalid key expressions file ({e})") from e
