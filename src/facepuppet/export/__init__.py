"""Export: glTF morph-weight animation, Live Link Face CSV, preview rendering, smoothing."""

from facepuppet.export.csv import write_weights_csv
from facepuppet.export.gltf_animation import write_animated_glb

__all__ = [
    "write_animated_glb", "write_weights_csv",
]
