"""Input and output: frame sources, characters (glTF/GLB, OBJ), track files and the performer's key expressions.

The rig file, which holds a fitted mapper, is read and written by :mod:`facepuppet.pipeline.rig`.
"""

from facepuppet.io.character import Character, load_character, save_character
from facepuppet.io.gltf import read_gltf, write_glb
from facepuppet.io.obj import read_obj, read_obj_character, write_obj, write_obj_character
from facepuppet.io.performer import Performer, load_performer, save_performer
from facepuppet.io.track import Track, load_track, save_track

__all__ = [
    # characters
    "Character", "load_character", "save_character", "read_gltf", "write_glb", "read_obj", "read_obj_character",
    "write_obj", "write_obj_character",
    # performer key expressions, tracks
    "Performer", "load_performer", "save_performer", "Track", "load_track", "save_track",
]
