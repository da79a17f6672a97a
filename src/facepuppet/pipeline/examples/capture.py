"""``capture_examples``: the performer's key expressions from a video, by marks or picked automatically."""

from __future__ import annotations

import os
from collections.abc import Sequence

from facepuppet.io.performer import Performer
from facepuppet.io.track import Track
from facepuppet.pipeline.examples.auto import from_auto
from facepuppet.pipeline.examples.config import ExamplesConfig
from facepuppet.pipeline.examples.marks import from_marks

__all__ = ["capture_examples"]


def capture_examples(media: str | os.PathLike, *, names: Sequence[str], marks: str | os.PathLike | None = None,
                     auto: bool = False, config: ExamplesConfig | None = None, track: Track | None = None,
                     scores_track: Track | None = None) -> Performer:
    """Capture the performer's key expressions (the paper's S_B and S_i) from a calibration video.

    Parameters
    ----------
    media : str or PathLike
        The calibration video or image folder.
    names : sequence of str
        The character's key-model names (one key expression is captured per name the video shows).
    marks : str or PathLike, optional
        A marks file naming the expression at times or frames (:func:`~facepuppet.pipeline.examples.from_marks`).
    auto : bool
        Pick the frames by the landmark backend's ARKit blendshape scores instead
        (:func:`~facepuppet.pipeline.examples.from_auto`; needs the mediapipe extra and ARKit names).
    config : ExamplesConfig, optional
    track, scores_track : Track, optional
        A track of ``media`` made before (and, with ``auto``, the landmark backend's track of it).

    Returns
    -------
    Performer
    """
    if (marks is None) == (not auto):
        raise ValueError("give either a marks file or auto=True")
    if auto:
        return from_auto(media, names, config=config, scores_track=scores_track, track=track)
    return from_marks(media, marks, names=names, config=config, track=track)
