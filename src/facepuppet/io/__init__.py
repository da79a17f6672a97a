"""Input and output: frame sources, characters (glTF/GLB, OBJ), performer examples, track and rig files."""

from facepuppet.io.character import Character, load_character, save_character
from facepuppet.io.gltf import read_gltf, write_glb
from facepuppet.io.obj import read_obj, read_obj_character, write_obj, write_obj_character
from facepuppet.io.performer import Performer, load_performer, save_performer
from facepuppet.io.rig import Pairing, Rig, fit_rig, load_rig, pair_by_name, save_rig

__all__ = [
    # characters
    "Character", "load_character", "save_character", "read_gltf", "write_glb", "read_obj", "read_obj_character",
    "write_obj", "write_obj_character",
    # performer key expressions, rigs
    "Performer", "load_performer", "save_performer", "Rig", "Pairing", "pair_by_name", "fit_rig", "load_rig",
    "save_rig",
]
