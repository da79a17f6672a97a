"""Key expressions from a video and a marks file that names the key expression shown at a time or frame.

Marks file
----------
One mark per line, ``WHEN,NAME``; blank lines and lines starting with ``#`` are ignored, and so is a header
line ``time,name`` (or ``frame,name``). ``WHEN`` is a time in seconds written ``1.5s``, a clock time
``00:01.5`` (``MM:SS.s`` or ``HH:MM:SS.s``), or a frame index as a plain integer (0 = first frame).
``NAME`` is ``neutral`` for the neutral face, otherwise a key-model name of the character.

Optionally, ``START-END,head-motion`` marks a span (any of the time forms above on both sides) in which the
performer keeps a neutral face and moves the head: turns, nods, tilts, leans in and out, at the speed of a
performance. What the tracker reports there is motion that is no expression, and the mapping discounts it
(the mapper's ``nuisance`` option); it matters most with the colour tracker, whose yaw and pitch are read
off the nose's tip or the crop's look, not solved from 3D points. Several spans may be marked. Example::

    # time_or_frame,name
    0.5s,neutral
    00:02.0,jawOpen
    95,mouthSmile
    14s-20s,head-motion
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from facepuppet.errors import FacepuppetError
from facepuppet.io.performer import Performer
from facepuppet.io.track import Track
from facepuppet.mapping.noise import noise_from_examples
from facepuppet.pipeline.examples.checks import make_performer
from facepuppet.pipeline.examples.config import NEUTRAL, ExamplesConfig
from facepuppet.pipeline.examples.window import average_near, need_faces
from facepuppet.pipeline.tracking import get_track

__all__ = ["Mark", "parse_when", "read_marks", "from_marked_track", "from_marks", "HEAD_MOTION",
           "MIN_HEAD_MOTION_FRAMES"]

#: The name that marks a span of a neutral face with the head moving (marks file).
HEAD_MOTION = "head-motion"
#: Least frames with a face over the head-motion spans.
MIN_HEAD_MOTION_FRAMES = 10


@dataclass(frozen=True)
class Mark:
    """One line of a marks file: the frame and the key-model name (``line`` for messages); for a
    ``head-motion`` span, ``frame`` is its first frame and ``stop`` the frame after its last."""

    frame: int
    name: str
    line: int
    when: str
    stop: int | None = None


_CLOCK = re.compile(r"^(?:(\d+):)?(\d+):(\d+(?:\.\d*)?)$")


def parse_when(text: str, fps: float) -> int:
    """Frame index of a marks-file time: ``1.5s`` (seconds), ``00:01.5`` (clock) or ``45`` (frame).

    Raises ValueError for anything else (a bare ``1.5`` is ambiguous and refused).
    """
    s = text.strip()
    if re.fullmatch(r"\d+", s):
        return int(s)
    if re.fullmatch(r"\d+(\.\d*)?s", s, re.IGNORECASE) or re.fullmatch(r"\.\d+s", s, re.IGNORECASE):
        return int(round(float(s[:-1]) * fps))
    m = _CLOCK.match(s)
    if m:
        hours, minutes, seconds = int(m.group(1) or 0), int(m.group(2)), float(m.group(3))
        return int(round((3600 * hours + 60 * minutes + seconds) * fps))
    raise ValueError(f"{text!r} is not a time: write seconds as 1.5s, a clock time as 00:01.5, "
                     f"or a frame as a whole number")


def read_marks(path: str | os.PathLike, fps: float, n_frames: int,
               names: Sequence[str] | None = None) -> list[Mark]:
    """Read and check a marks file (format in the module docstring).

    Parameters
    ----------
    path : str or PathLike
    fps : float
        Frame rate of the video (to turn times into frames).
    n_frames : int
        Frames in the video; a mark at or past the end is an error.
    names : sequence of str, optional
        The character's key-model names; a mark naming anything else is an error.

    Raises
    ------
    ValueError
        Naming the file, the line and what is wrong: unreadable time, unknown name, past the end, a name
        marked twice, no ``neutral`` mark, no key expression at all.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as e:
        raise ValueError(f"{path}: cannot read marks file ({e})") from e
    known = None if names is None else set(names) | {NEUTRAL, HEAD_MOTION}
    marks: list[Mark] = []
    seen: dict[str, int] = {}
    for no, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        parts = [p.strip() for p in re.split(r"[,;\t]", line)]
        if len(parts) != 2 or not parts[1]:
            raise ValueError(f"{path} line {no}: expected WHEN,NAME, got {line!r}")
        when, name = parts
        if not marks and when.lower() in ("time", "frame", "time_or_frame", "when"):
            continue
        stop = None
        try:
            if name == HEAD_MOTION:
                if when.count("-") != 1:
                    raise ValueError(f"{HEAD_MOTION} marks a span: write START-END, such as 14s-20s (got {when!r})")
                start_text, stop_text = when.split("-")
                frame, stop = parse_when(start_text, fps), parse_when(stop_text, fps)
                if stop <= frame:
                    raise ValueError(f"the span {when} ends before it starts")
            elif when.startswith("-"):
                raise ValueError(f"a time cannot be negative, got {when!r}")
            elif "-" in when:
                raise ValueError(f"only {HEAD_MOTION} marks a span (START-END); {name!r} marks one time, got "
                                 f"{when!r}")
            else:
                frame = parse_when(when, fps)
        except ValueError as e:
            raise ValueError(f"{path} line {no}: {e}") from None
        if known is not None and name not in known:
            raise ValueError(f"{path} line {no}: the character has no key-model named {name!r} "
                             f"(it has {', '.join(sorted(known - {NEUTRAL}))}; and 'neutral')")
        if frame >= n_frames or (stop is not None and stop > n_frames):
            raise ValueError(f"{path} line {no}: {when} ({name}) is past the end of the video "
                             f"({n_frames} frames, {n_frames / fps:.2f} s)")
        if name in seen and name != HEAD_MOTION:
            raise ValueError(f"{path} line {no}: {name!r} is marked twice (first on line {seen[name]})")
        seen[name] = no
        marks.append(Mark(frame, name, no, when, stop))
    if NEUTRAL not in seen:
        raise ValueError(f"{path}: no mark names the neutral face (a line such as '0.5s,{NEUTRAL}')")
    if sum(m.name != HEAD_MOTION for m in marks) < 2:
        raise ValueError(f"{path}: marks only the neutral face; mark at least one key expression")
    return marks


def from_marked_track(track: Track, marks: Sequence[Mark], config: ExamplesConfig | None = None) -> Performer:
    """Key expressions from a track of the marked video: the feature points averaged around each mark.

    The frames of the ``head-motion`` spans, if any, become the nuisance; the noise is
    :func:`facepuppet.mapping.noise.noise_from_examples` over the track's frames with a face.
    """
    config = config or ExamplesConfig()
    averaged, frames = {}, {}
    spans = [m for m in marks if m.name == HEAD_MOTION]
    for mark in marks:
        if mark.name != HEAD_MOTION:
            averaged[mark.name], frames[mark.name] = average_near(track, mark.name, mark.frame, config)
    names = tuple(m.name for m in marks if m.name not in (NEUTRAL, HEAD_MOTION))
    neutral, examples = averaged[NEUTRAL], np.stack([averaged[n] for n in names])
    noise = noise_from_examples(track.points[track.valid], neutral, examples)
    return make_performer(neutral, examples, names, track.point_names, frames, config, noise=noise,
                          nuisance=_head_motion(track, spans))


def _head_motion(track: Track, spans: Sequence[Mark]) -> np.ndarray | None:
    """(K, P, D) feature points of the frames with a face in the head-motion spans; None without spans."""
    if not spans:
        return None
    take = np.zeros(track.n_frames, bool)
    for m in spans:
        take[m.frame:m.stop] = True
    take &= track.valid & np.isfinite(track.points).all(axis=(1, 2))
    if take.sum() < MIN_HEAD_MOTION_FRAMES:
        where = ", ".join(f"{m.when} (line {m.line})" for m in spans)
        raise FacepuppetError(f"{HEAD_MOTION} {where}: only {int(take.sum())} frames with a face; at least "
                              f"{MIN_HEAD_MOTION_FRAMES} are needed")
    return track.points[take]


def from_marks(media: str | os.PathLike, marks: str | os.PathLike, *, names: Sequence[str] | None = None,
               config: ExamplesConfig | None = None, track: Track | None = None) -> Performer:
    """Capture the key expressions from a video and a marks file.

    Parameters
    ----------
    media : str or PathLike
        The video of the key expressions (or an image folder).
    marks : str or PathLike
        The marks file (module docstring).
    names : sequence of str, optional
        The character's key-model names, to check the marks against.
    config : ExamplesConfig, optional
    track : Track, optional
        A track of ``media`` made before (skips tracking).
    """
    config = config or ExamplesConfig()
    if track is None:
        from facepuppet.io.frames import open_media

        with open_media(media) as src:      # check the marks before the (slow) tracking
            fps, count = src.fps, src.frame_count
        if count is not None:
            read_marks(marks, fps, count, names)
        track = get_track(media, config.tracker)
    need_faces(track, media)
    return from_marked_track(track, read_marks(marks, track.fps, track.n_frames, names), config)
