"""Capture (paper §3): colour transform, blobs, Bezier snakes, head pose, feature points; landmark backend."""
