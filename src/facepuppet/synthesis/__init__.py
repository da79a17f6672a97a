"""Synthesis (paper §5.4 and its wires): deforming a character with wire curves (Singh & Fiume, SIGGRAPH 98).

``wire_deform(points, reference, wire, radius, scale=...)`` deforms points with one wire; ``WireDeformer``
binds a mesh to several reference curves once and deforms it per frame. ``find_wire_paths`` finds (or
``read_wire_paths`` reads) a character's wires as vertex paths, ``fit_wires`` represents each key-model by its
wire curves and (r, s) per wire, and ``reproduction_errors`` says how much of each key-model they reproduce.
``region_masks`` / ``regional_blend`` / ``split_targets`` blend key-models region by region (the wires'
influence as a partition of unity).
"""

from facepuppet.synthesis.deformer import DEFAULT_EXPONENT, WireDeformer, combine_displacements
from facepuppet.synthesis.fit import CharacterWires, FitOptions, fit_wires, reproduction_errors
from facepuppet.synthesis.paths import (
    FORMAT_NAME,
    FORMAT_VERSION,
    FindOptions,
    check_paths,
    find_wire_paths,
    mesh_graph,
    read_wire_paths,
    write_wire_paths,
)
from facepuppet.synthesis.regions import region_masks, region_support, regional_blend, split_targets
from facepuppet.synthesis.wire import bind_points, falloff, wire_deform

__all__ = [
    "DEFAULT_EXPONENT",
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "CharacterWires",
    "FindOptions",
    "FitOptions",
    "WireDeformer",
    "bind_points",
    "check_paths",
    "combine_displacements",
    "falloff",
    "find_wire_paths",
    "fit_wires",
    "mesh_graph",
    "read_wire_paths",
    "region_masks",
    "region_support",
    "regional_blend",
    "reproduction_errors",
    "split_targets",
    "wire_deform",
    "write_wire_paths",
]
