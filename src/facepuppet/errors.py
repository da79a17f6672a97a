"""The package's one exception type for runtime failures (bad files, singular systems, lost inputs)."""

from __future__ import annotations

__all__ = ["FacepuppetError"]


class FacepuppetError(RuntimeError):
    """A runtime failure the user can act on; its message is one line naming the file or argument."""
