"""facepuppet: performance-driven facial animation from one ordinary camera.

The data flows one way: frames -> capture (features) -> mapping (blend weights) -> synthesis / export.
"""

from __future__ import annotations

from facepuppet.errors import FacepuppetError

__version__ = "0.1.0"
__all__ = ["ExpressionMapper", "FacepuppetError", "__version__"]


def __getattr__(name: str):
    # Lazy so that `import facepuppet` stays cheap for the CLI and the capture stage.
    if name == "ExpressionMapper":
        from facepuppet.mapping import ExpressionMapper

        return ExpressionMapper
    raise AttributeError(f"module 'facepuppet' has no attribute {name!r}")
