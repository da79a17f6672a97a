"""Helpers every stage shares: atomic writes, versioned ``.npz`` files; they import nothing of facepuppet but errors."""

__all__: list[str] = []
