"""Synthesis (paper §5.4 and its wires): deforming a character with wire curves (Singh & Fiume, SIGGRAPH 98).

``wire_deform(points, reference, wire, radius, scale=...)`` deforms points with one wire; ``WireDeformer``
binds a mesh to several reference curves once and deforms it per frame. ``character_wires`` finds (or
``read_wire_paths`` reads) a character's wires as vertex paths, ``fit_wires`` represents each key-model by its
wire curves and (r, s) per wire, and ``reproduction_errors`` says how much of each key-model they reproduce.
"""

from facepuppet.synthesis.deformer import DEFAULT_EXPONENT, WireDeformer, combine_displacements
from facepuppet.synthesis.wire import falloff, wire_deform

__all__ = ["DEFAULT_EXPONENT", "WireDeformer", "combine_displacements", "falloff", "wire_deform"]
