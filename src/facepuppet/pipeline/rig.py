"""The rig: key expressions paired with key-models by name, the mapper fitted on the pairs, and its file.

:func:`fit_rig` pairs a :class:`~facepuppet.io.performer.Performer` with a
:class:`~facepuppet.io.character.Character` (:func:`pair_by_name`) and fits an
:class:`~facepuppet.mapping.ExpressionMapper`; :func:`save_rig` / :func:`load_rig` write and read the rig
file (``RIG.npz``, written by ``facepuppet rig``), a fitted mapper with its character and pairing.

The rig file is a NumPy ``.npz`` archive read without pickle:

=========================  ==========  ================================================================
key                        shape       meaning
=========================  ==========  ================================================================
``format``                 ()          the string ``"facepuppet-rig"``
``version``                ()          integer format version, currently 2 (1 still reads)
``mapper.<key>``           any         the fitted mapper's arrays (``ExpressionMapper.to_arrays()``)
``character.neutral``      (V, 3)      the character's neutral mesh
``character.targets``      (K, V, 3)   all its key-models (absolute positions)
``character.names``        (K,)        their names
``character.faces``        (T, 3)      optional: triangles
``character.name``         ()          the character's name
``character.source``       (B,) uint8  optional (version 2): the character's whole glTF scene as one GLB
``names``                  (M,)        the paired key-model names, in the mapper's example order
``point_names``            (P,)        the performer's feature point names (may be empty)
=========================  ==========  ================================================================

The character is kept whole, so an exported GLB has all its morph targets; the mapper's M weights go to the
key-models named in ``names`` (:meth:`Rig.character_weights`) and the rest stay at zero. With
``character.source`` (a character read from glTF / VRM), the GLB written is that scene with one animation added
(:mod:`facepuppet.export.scene_animation`); without it (OBJ characters, version 1 rigs), the bare mesh.

A rig fitted with ``method="regional"`` (:attr:`Rig.regional`) maps a frame to weights w_ik per region k and
key-model i; the animation carries them as R·M channels (:attr:`Rig.channel_names`, region-major), and its GLB
has the R·M morph targets M_k ⊙ (T_i − T_B), added to the character's own scene
(:mod:`facepuppet.export.scene_regional`) or on the bare mesh (:meth:`Rig.split_character`), which a player
blends into T = T_B + Σ_k Σ_i M_k ⊙ w_ik (T_i − T_B). The file is the same; the mapper's arrays hold the masks.
"""

from __future__ import annotations

import inspect
import os
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from facepuppet._util.atomic import atomic_path
from facepuppet._util.npz import check_format, read_npz
from facepuppet.errors import FacepuppetError
from facepuppet.io.character import Character
from facepuppet.io.performer import Performer

__all__ = ["Rig", "Pairing", "pair_by_name", "fit_rig", "save_rig", "load_rig", "read_rig_arrays",
           "rig_from_arrays", "RIG_FORMAT", "RIG_VERSION"]

RIG_FORMAT = "facepuppet-rig"
RIG_VERSION = 2
_MAPPER, _CHAR = "mapper.", "character."
#: The fitted mapping's arrays that hold only finite numbers in a sound rig.
_MAPPER_NUMBERS = ("source_base", "source_examples", "target_base", "target_deltas", "point_scale", "whiten",
                   "solver_masks", "solver_G", "solver_H", "solver_Hd", "solver_Fs", "solver_omega")


@dataclass(frozen=True)
class Rig:
    """A fitted mapping from a performer to a character.

    Attributes
    ----------
    mapper : ExpressionMapper
        Fitted on the paired examples, in the order of ``names``.
    character : Character
        The whole character (all its key-models).
    names : tuple of M str
        Paired key-model names, in the mapper's example order.
    point_names : tuple of P str
        The performer's feature point names (empty if the performer file had none).
    backend : str or None
        The tracker the key expressions were captured with; None when unknown (an older file).
    profile_hash : str or None
        Content hash of the colour tracker's performer profile they were captured with; None when none or
        unknown.
    """

    mapper: Any
    character: Character
    names: tuple[str, ...]
    point_names: tuple[str, ...] = ()
    backend: str | None = None
    profile_hash: str | None = None

    def __post_init__(self) -> None:
        unknown = [n for n in self.names if n not in self.character.names]
        if unknown:
            raise ValueError(f"paired names not among the character's key-models: {', '.join(unknown)}")
        if len(set(self.names)) != len(self.names):
            raise ValueError("paired names must be unique")

    @property
    def target_indices(self) -> np.ndarray:
        """(M,) index of each paired key-model in ``character.names``."""
        return np.array([self.character.names.index(n) for n in self.names], dtype=np.int64)

    @property
    def regional(self) -> bool:
        """True when the mapper gives one row of weights per region (method ``regional``)."""
        return bool(getattr(self.mapper, "regional", False))

    @property
    def region_names(self) -> tuple[str, ...]:
        """The regional mapper's R region names (the background first); empty for a global rig."""
        return tuple(str(r) for r in self.mapper.region_names) if self.regional else ()

    @property
    def channel_names(self) -> tuple[str, ...]:
        """Names of the animation's weight channels: ``names`` (M), or for a regional rig
        ``"<region>/<key-model>"`` region-major (R·M, channel k·M + i is w_ik)."""
        if not self.regional:
            return tuple(self.names)
        return tuple(f"{r}/{n}" for r in self.region_names for n in self.names)

    def split_character(self) -> Character:
        """A regional rig's character as it plays: T_B with the R·M morph targets M_k ⊙ (T_i − T_B) of the
        paired key-models, named and ordered as :attr:`channel_names`
        (:func:`facepuppet.export.gltf_regional.split_character`)."""
        from facepuppet.export.gltf_regional import split_character

        c = self.character
        paired = Character(c.neutral, np.asarray(c.targets)[self.target_indices], tuple(self.names), c.faces,
                           c.name)
        return split_character(paired, self.mapper.region_masks, self.region_names)

    def character_weights(self, weights: np.ndarray) -> np.ndarray:
        """Spread the mapper's weights (..., M) over all the character's key-models (..., K), zeros elsewhere."""
        weights = np.asarray(weights, dtype=np.float64)
        if weights.shape[-1:] != (len(self.names),):
            raise ValueError(f"weights must end in {len(self.names)} values, got shape {weights.shape}")
        out = np.zeros(weights.shape[:-1] + (len(self.character.names),))
        out[..., self.target_indices] = weights
        return out


@dataclass(frozen=True)
class Pairing:
    """Key expressions matched with key-models by name (exact, case-sensitive).

    Attributes
    ----------
    names : tuple of str
        Names on both sides, in the performer's order.
    only_performer : tuple of str
        Key expressions with no key-model of that name.
    only_character : tuple of str
        Key-models with no key expression of that name.
    """

    names: tuple[str, ...]
    only_performer: tuple[str, ...]
    only_character: tuple[str, ...]


def pair_by_name(performer_names: Sequence[str], character_names: Sequence[str]) -> Pairing:
    """Pair key expressions with key-models of exactly the same name."""
    other = set(character_names)
    mine = set(performer_names)
    return Pairing(names=tuple(n for n in performer_names if n in other),
                   only_performer=tuple(n for n in performer_names if n not in other),
                   only_character=tuple(n for n in character_names if n not in mine))


def fit_rig(performer: Performer, character: Character, *, method: str | None = None) -> tuple[Rig, Pairing]:
    """Pair ``performer`` with ``character`` by name and fit an ExpressionMapper on the pairs.

    Parameters
    ----------
    performer : Performer
        Source base and examples (feature points).
    character : Character
        Target base and key-models.
    method : str, optional
        The mapper's method by name; None takes ``ExpressionMapper.fit``'s default.

    Returns
    -------
    (Rig, Pairing)
        The rig, and the pairing with the names left without a partner on either side.
    """
    from facepuppet.mapping import ExpressionMapper

    pairing = pair_by_name(performer.names, character.names)
    if not pairing.names:
        raise FacepuppetError(
            f"no key expression has a key-model of the same name (performer: {_some(performer.names)}; "
            f"character {character.name!r}: {_some(character.names)}); names must match exactly")
    examples = np.stack([performer.examples[performer.names.index(n)] for n in pairing.names])
    targets = np.stack([character.targets[character.names.index(n)] for n in pairing.names])
    options: dict[str, Any] = {}
    if method is not None:
        options["method"] = method
    params = inspect.signature(ExpressionMapper.fit).parameters
    if "names" in params or any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values()):
        options["names"] = pairing.names  # a mapper that takes names uses them in its diagnostics
    if performer.noise is not None:
        options["point_scale"] = performer.noise  # coordinates the tracker follows poorly count less
    if performer.nuisance is not None:
        options["nuisance"] = performer.nuisance  # motion that is not an expression counts less
    mapper = ExpressionMapper.fit(performer.neutral, examples, character.neutral, targets, **options)
    rig = Rig(mapper=mapper, character=character, names=pairing.names,
              point_names=tuple(performer.point_names or ()), backend=performer.backend,
              profile_hash=performer.profile_hash)
    return rig, pairing


def _some(names: Sequence[str], limit: int = 8) -> str:
    shown = ", ".join(names[:limit])
    return shown + (f", ... ({len(names)} in all)" if len(names) > limit else "") if names else "none"


def save_rig(path: str | os.PathLike, rig: Rig) -> None:
    """Write ``rig`` to ``path`` (.npz, no pickle), atomically."""
    c = rig.character
    arrays: dict[str, np.ndarray] = {
        "format": np.asarray(RIG_FORMAT),
        "version": np.asarray(RIG_VERSION, dtype=np.int64),
        _CHAR + "neutral": np.asarray(c.neutral),
        _CHAR + "targets": np.asarray(c.targets),
        _CHAR + "names": np.asarray(c.names, dtype=str),
        _CHAR + "name": np.asarray(c.name),
        "names": np.asarray(rig.names, dtype=str),
        "point_names": np.asarray(rig.point_names, dtype=str),
    }
    for key in ("backend", "profile_hash"):
        if getattr(rig, key) is not None:
            arrays[key] = np.asarray(str(getattr(rig, key)))
    if c.faces is not None:
        arrays[_CHAR + "faces"] = np.asarray(c.faces, dtype=np.int64)
    if c.source is not None:
        arrays[_CHAR + "source"] = np.frombuffer(c.source, dtype=np.uint8)
    for key, value in rig.mapper.to_arrays().items():
        value = np.asarray(value)
        if value.dtype == object:
            raise TypeError(f"mapper array {key!r} has dtype object, which cannot be saved without pickle")
        arrays[_MAPPER + key] = value
    with atomic_path(path, suffix=".npz") as tmp:
        np.savez_compressed(tmp, **arrays)


def _source(array: np.ndarray | None) -> bytes | None:
    if array is None:
        return None
    if array.dtype != np.uint8 or array.ndim != 1:
        raise ValueError(f"character.source must be (B,) uint8, got {array.dtype} {array.shape}")
    return array.tobytes()


def load_rig(path: str | os.PathLike) -> Rig:
    """Read a rig file; a missing, corrupt, truncated or newer-version file raises FacepuppetError naming it."""
    return rig_from_arrays(read_rig_arrays(path), path)


def read_rig_arrays(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """The rig file's arrays (the module's table), inflated and checked for their format and members, with
    neither the mapping's modules imported nor the rig built (:func:`rig_from_arrays` does both): what a batch
    sends its Ray actors."""
    arrays = read_npz(path, "rig file", known=("format", "version", "names", "point_names", "backend",
                                               "profile_hash"), prefixes=(_CHAR, _MAPPER))
    check_format(arrays, path, "rig file", RIG_FORMAT, RIG_VERSION)
    needed = [_CHAR + k for k in ("neutral", "targets", "names", "name")] + ["names", "point_names"]
    missing = [k for k in needed if k not in arrays]
    if missing:
        raise FacepuppetError(f"{path}: rig file lacks {', '.join(missing)}")
    return arrays


def rig_from_arrays(arrays: dict[str, np.ndarray], path: str | os.PathLike) -> Rig:
    """The rig of the arrays :func:`read_rig_arrays` read from ``path`` (named in the messages); damaged values
    raise FacepuppetError naming it."""
    from facepuppet.mapping import ExpressionMapper

    try:
        character = Character(
            neutral=arrays[_CHAR + "neutral"].astype(np.float64),
            targets=arrays[_CHAR + "targets"].astype(np.float64),
            names=tuple(str(n) for n in np.atleast_1d(arrays[_CHAR + "names"])),
            faces=arrays.get(_CHAR + "faces"),
            name=str(arrays[_CHAR + "name"]),
            source=_source(arrays.get(_CHAR + "source")),
        )
        mapper_arrays = {k[len(_MAPPER):]: v for k, v in arrays.items() if k.startswith(_MAPPER)}
        damaged = sorted(k for k, v in mapper_arrays.items() if k in _MAPPER_NUMBERS and v.dtype.kind in "fc"
                         and not np.isfinite(v).all())
        if damaged:
            raise FacepuppetError(f"the fitted mapping holds NaN or infinite values ({', '.join(damaged)}); "
                                  f"fit the rig again")
        if not (np.isfinite(character.neutral).all() and np.isfinite(character.targets).all()):
            raise FacepuppetError("the character's vertices hold NaN or infinite values")
        mapper = ExpressionMapper.from_arrays(mapper_arrays)
        return Rig(mapper=mapper, character=character,
                   names=tuple(str(n) for n in np.atleast_1d(arrays["names"])),
                   point_names=tuple(str(n) for n in np.atleast_1d(arrays["point_names"])),
                   backend=str(arrays["backend"]) if "backend" in arrays else None,
                   profile_hash=str(arrays["profile_hash"]) if "profile_hash" in arrays else None)
    except FacepuppetError as e:
        raise FacepuppetError(f"{path}: invalid rig file ({e})") from e
    except (ValueError, TypeError, KeyError, IndexError) as e:
        raise FacepuppetError(f"{path}: invalid rig file ({type(e).__name__}: {e})") from e
