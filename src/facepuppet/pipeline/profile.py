"""Training the colour tracker's performer profile on a clip of the performer, labelled by MediaPipe (§3.1).

``facepuppet calibrate --train-profile`` runs it before capturing the key expressions; the profile it writes
is the ``--profile`` of track, calibrate and animate.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from facepuppet.errors import FacepuppetError
from facepuppet.io.track import Track
from facepuppet.pipeline.tracking import TrackerOptions, get_track

__all__ = ["train_profile_on_media", "EVERY", "MAX_FRAMES"]

#: Train on every EVERY-th labelled frame ...
EVERY = 3
#: ... and on at most MAX_FRAMES of them.
MAX_FRAMES = 150


def train_profile_on_media(media: str | os.PathLike, path: str | os.PathLike, *, labels: Track | None = None,
                           model: str | None = None, every: int = EVERY, max_frames: int = MAX_FRAMES,
                           progress: bool | None = None) -> Track:
    """Train the colour tracker's performer profile on ``media``, labelled by the landmark backend, and save it.

    Parameters
    ----------
    media : str or PathLike
        A short clip of the performer (the video of the key expressions will do).
    path : str or PathLike
        Where to save the profile.
    labels : Track, optional
        A MediaPipe track of ``media`` made before; tracked here otherwise.
    model : str, optional
        MediaPipe model file.
    every, max_frames : int
        Train on every ``every``-th labelled frame, at most ``max_frames`` of them.
    progress : bool, optional
        Progress bar of the labelling; None shows it when stderr is a terminal.

    Returns
    -------
    Track
        The MediaPipe track used as labels (its blendshape scores serve ``--auto``).
    """
    from facepuppet.capture.color.profile import save_profile
    from facepuppet.capture.color.train import train_profile
    from facepuppet.io.frames import open_media

    if labels is None:
        labels = get_track(media, TrackerOptions(backend="mediapipe", model=model, progress=progress))
    keep = np.flatnonzero(labels.valid)[::max(1, every)][:max_frames]
    if len(keep) == 0:
        raise FacepuppetError(f"{media}: no face found to train the colour tracker's profile on")
    wanted, frames = set(keep.tolist()), []
    with open_media(media) as src:
        for k, rgb in enumerate(src):
            if k in wanted:
                frames.append(rgb)
            if k >= keep[-1]:
                break
    profile = train_profile(frames, labels.curves[keep[:len(frames)]], name=Path(media).stem,
                            rotations=np.asarray(labels.rotation[keep[:len(frames)]], dtype=float))
    save_profile(path, profile)
    return labels
