"""Content hashes of files: what a rig or track records of the media and profile it came from."""

from __future__ import annotations

import hashlib
import os
import stat

__all__ = ["file_digest", "media_record", "CHUNK"]

#: Bytes read at a time while hashing (memory stays flat in the file's size).
CHUNK = 1 << 20


def file_digest(path: str | os.PathLike) -> str | None:
    """``"blake2b:<hex>"`` of a regular file's bytes, read in :data:`CHUNK` pieces; None for anything else
    (a folder, a camera, a missing file)."""
    try:
        if not stat.S_ISREG(os.stat(path).st_mode):
            return None
        h = hashlib.blake2b(digest_size=20)
        with open(path, "rb") as f:
            while chunk := f.read(CHUNK):
                h.update(chunk)
    except (OSError, ValueError):
        return None
    return f"blake2b:{h.hexdigest()}"


def media_record(path: str | os.PathLike, frames: int) -> dict | None:
    """``{"size": bytes, "frames": frames, "hash": file_digest}`` of a media file; None if it is no regular
    file (an image folder, ``camera:N``)."""
    digest = file_digest(path)
    if digest is None:
        return None
    return {"size": int(os.stat(path).st_size), "frames": int(frames), "hash": digest}
