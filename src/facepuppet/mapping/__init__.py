"""Expression mapping (paper §4-5): PCA parameter space, cardinal basis functions and better solvers.

``ExpressionMapper.fit(...)`` builds a mapper from paired examples, ``weights(points)`` evaluates it per frame
and ``synthesize(weights)`` blends the character (Eq. 14). The method names are listed in :data:`METHODS`.
"""

from facepuppet.mapping._methods import DEFAULT_METHOD, METHODS
from facepuppet.mapping.mapper import FORMAT_VERSION, ExpressionMapper, MapperOptions

__all__ = ["ExpressionMapper", "MapperOptions", "METHODS", "DEFAULT_METHOD", "FORMAT_VERSION"]
