"""Export: glTF morph-weight animation, Live Link Face CSV, preview rendering, smoothing."""
