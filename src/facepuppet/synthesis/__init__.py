"""Synthesis (paper §5.4): blending key-models (Eq. 14) and wire deformation."""
