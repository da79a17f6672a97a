"""Built-in characters by name (``--character toy``, ``--character monkey``): GLB scenes with a material,
vertex colours and normals.

:func:`builtin_character` returns the character with :attr:`Character.source` set to its GLB, so an animation
is written into that scene (colours and all); :func:`character_glb` gives the GLB bytes; :func:`load_character_arg`
is what the CLI calls with a ``--character`` argument: an existing path is read as a file or folder, else a
built-in name (:data:`BUILTIN`) is taken.

The colours are vertex colours (``COLOR_0``) under one white, rough, non-metallic material, so any glTF viewer
shows the character as the demo's preview draws it (the Toy green with red lips). The characters are built
by :mod:`facepuppet.demo.toy` and :mod:`facepuppet.demo.monkey`.
"""

from __future__ import annotations

import os
from pathlib import Path

from facepuppet.errors import FacepuppetError
from facepuppet.io.character import Character, load_character
from facepuppet.io.gltf import colored_glb

__all__ = ["BUILTIN", "builtin_character", "character_glb", "load_character_arg"]

#: Built-in characters: name -> what it is.
BUILTIN = {"toy": "the demo's Toy: a cartoon head with 13 ARKit-named key-models",
           "monkey": "a monkey (the paper's Fig. 7): wide muzzle, deep jaw, high brows; the same 13 key-models"}


def _parts(name: str):
    if name == "toy":
        from facepuppet.demo.toy import toy_character, toy_colors

        return toy_character(), toy_colors()
    if name == "monkey":
        from facepuppet.demo.monkey import monkey_character, monkey_colors

        return monkey_character(), monkey_colors()
    raise FacepuppetError(f"no built-in character {name!r}; built-in: {', '.join(BUILTIN)}")


def character_glb(name: str) -> bytes:
    """GLB bytes of built-in character ``name``: mesh with normals, vertex colours, a material, morph targets."""
    return colored_glb(*_parts(name))


def builtin_character(name: str) -> Character:
    """Built-in character ``name`` with its GLB as :attr:`Character.source`."""
    from dataclasses import replace

    character, _ = _parts(name)
    return replace(character, source=character_glb(name))


def load_character_arg(arg: str | os.PathLike, **options) -> Character:
    """A ``--character`` argument: an existing file or folder (``load_character``), else a built-in name."""
    if Path(arg).exists():
        return load_character(arg, **options)
    if str(arg) not in BUILTIN:
        raise FacepuppetError(f"{arg}: no such file or folder (built-in characters: {', '.join(BUILTIN)})")
    if any(v is not None for v in options.values()):
        raise ValueError(f"--neutral / --mesh are for character files, not the built-in {arg!r}")
    return builtin_character(str(arg))
