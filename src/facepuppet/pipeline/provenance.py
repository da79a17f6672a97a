"""What a rig or track records of where it came from, compared with what it is used with.

A rig records the tracker (``backend``) and the performer profile (``profile_hash``) its key expressions were
captured with; a track its backend and the media file it tracked (size, frames, content hash). Files without
these fields (older ones) are not checked. A rig used with another tracker, or a track used with another
video, is refused (the feature points, or the frames, would not be the ones the file describes); another
performer profile than the rig's is told as a warning (a retrained profile of the same performer is right).
"""

from __future__ import annotations

import logging
import os

from facepuppet._util.digest import file_digest
from facepuppet.errors import FacepuppetError

__all__ = ["check_rig_backend", "check_rig_profile", "check_track_media"]

log = logging.getLogger(__name__)


def check_rig_backend(rig, backend: str | None, rig_label: str = "rig", what: str = "--backend") -> None:
    """FacepuppetError if the rig records another tracker than ``backend`` (None: nothing to compare)."""
    made = getattr(rig, "backend", None)
    if made is not None and backend is not None and made != backend:
        raise FacepuppetError(f"{rig_label}: its key expressions were captured with the {made} tracker, not "
                              f"{what} {backend}; use {what} {made}, or calibrate and rig again with {backend}")


def check_rig_profile(rig, profile: str | os.PathLike | None, rig_label: str = "rig") -> str | None:
    """A warning (also logged) if the rig records another performer profile than the file ``profile``."""
    made = getattr(rig, "profile_hash", None)
    if made is None:
        return None
    used = file_digest(profile) if profile is not None else None
    if used == made:
        return None
    msg = (f"{rig_label}: captured with another performer profile than "
           f"{'--profile ' + str(profile) if profile is not None else 'none (the generic one)'}; the feature "
           f"points may differ from the key expressions'")
    log.warning("%s", msg)
    return msg


def check_track_media(track, media: str | os.PathLike | None, track_label: str = "--track") -> None:
    """FacepuppetError if ``track`` records a media file and ``media`` is another file (size or hash)."""
    made = getattr(track, "media", None)
    if made is None or media is None or not os.path.isfile(media):
        return
    size = os.stat(media).st_size
    if size != made["size"] or file_digest(media) != made["hash"]:
        raise FacepuppetError(f"{track_label}: is a track of another video than {media} (its size or content "
                              f"differs from the tracked file's); track {media} again or give its own track")
