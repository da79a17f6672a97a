"""Expression mapping (paper §4-5): PCA parameter space, cardinal basis functions and bounded solvers.

``ExpressionMapper.fit(...)`` builds a mapper from paired examples, ``weights(points)`` evaluates it per frame
and ``synthesize(weights)`` blends the character (Eq. 14). The method names are listed in :data:`METHODS`.
:mod:`facepuppet.mapping.noise` makes the mapper's ``point_scale`` and ``nuisance`` from tracked frames.
``motion_regions`` finds a character's regions from its key-models and ``region_shares`` says how much of each
key-model's motion lies in each region (the ``regional`` method's regions; per-region gains).
"""

from facepuppet.mapping._methods import DEFAULT_METHOD, METHODS
from facepuppet.mapping._regions import motion_regions, region_shares
from facepuppet.mapping.mapper import FORMAT_VERSION, ExpressionMapper, MapperOptions
from facepuppet.mapping.noise import coordinate_noise, head_turn_nuisance, noise_from_examples

__all__ = ["ExpressionMapper", "MapperOptions", "METHODS", "DEFAULT_METHOD", "FORMAT_VERSION", "coordinate_noise",
           "noise_from_examples", "head_turn_nuisance", "motion_regions", "region_shares"]
