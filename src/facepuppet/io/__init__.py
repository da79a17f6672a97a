"""Input and output: frame sources, characters (glTF/GLB, OBJ), performer examples, track and rig files."""
