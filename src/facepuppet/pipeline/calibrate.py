"""Make a performer's key expressions (the paper's source base and source examples) from footage.

Three ways, all ending in a :class:`PerformerExamples` (saved as the performer examples file that
``facepuppet rig --performer`` reads):

- :func:`calibrate_marks`: a calibration video and a marks file that names the key expression shown at a
  time or frame; the feature points are averaged over the steadiest few frames near each mark;
- :func:`calibrate_auto`: for characters whose key-models carry ARKit names, the landmark backend's
  blendshape scores pick the frame that best shows each key-model, and the most relaxed frame as neutral;
- :func:`calibrate_interactive`: from a camera; the key-model's name and a picture of it are shown, the
  performer copies it and presses a key.

:func:`check_examples` then names key expressions too close to each other to tell apart, or barely different
from neutral (the paper's mapping cannot separate them, §5).

Marks file
----------
One mark per line, ``WHEN,NAME``; blank lines and lines starting with ``#`` are ignored, and so is a header
line ``time,name`` (or ``frame,name``). ``WHEN`` is a time in seconds written ``1.5s``, a clock time
``00:01.5`` (``MM:SS.s`` or ``HH:MM:SS.s``), or a frame index as a plain integer (0 = first frame).
``NAME`` is ``neutral`` for the neutral face, otherwise a key-model name of the character.

Optionally, ``START-END,head-motion`` marks a span (any of the time forms above on both sides) in which the
performer keeps a neutral face and moves the head: turns, nods, tilts, leans in and out, at the speed of a
performance. What the tracker reports there is motion that is no expression, and the mapping discounts it
(the mapper's ``nuisance`` option): with the colour tracker, whose head pose holds yaw and pitch at zero, it
matters most. Several spans may be marked. Example::

    # time_or_frame,name
    0.5s,neutral
    00:02.0,jawOpen
    95,mouthSmile
    14s-20s,head-motion
"""

from __future__ import annotations

import logging
import os
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from facepuppet.arkit import arkit_parts
from facepuppet.errors import FacepuppetError
from facepuppet.io.track import Track
from facepuppet.pipeline._tracking import TrackerOptions, get_track, tracker_kwargs

__all__ = [
    "CalibrateConfig",
    "PerformerExamples",
    "Mark",
    "read_marks",
    "parse_when",
    "steadiest_window",
    "examples_from_marks",
    "calibrate_marks",
    "calibrate_auto",
    "coordinate_noise",
    "head_turn_nuisance",
    "calibrate_interactive",
    "check_examples",
    "save_examples",
    "make_profile",
    "NEUTRAL",
    "HEAD_MOTION",
]

log = logging.getLogger(__name__)

#: The name that marks the neutral face.
NEUTRAL = "neutral"
#: The name that marks a span of a neutral face with the head moving (marks file).
HEAD_MOTION = "head-motion"
#: Least frames with a face over the head-motion spans.
MIN_HEAD_MOTION_FRAMES = 10


@dataclass(frozen=True, kw_only=True)
class CalibrateConfig:
    """Options of calibration.

    Attributes
    ----------
    tracker : TrackerOptions
        The tracker that makes the feature points (it must be the one ``animate`` will use).
    window : int
        Frames averaged per key expression.
    search : float
        Seconds either side of a mark (or of the frame ``--auto`` picked) searched for the steadiest window.
    min_score : float
        ``--auto``: a key-model whose blendshape score never reaches this is left out (and reported).
    min_motion : float
        A key expression whose RMS displacement from neutral is below ``min_motion`` times the median over all
        key expressions is reported as barely different from neutral.
    min_separation : float
        Two key expressions closer (RMS) than ``min_separation`` times the smaller of their displacements are
        reported as too close to tell apart.
    auto_method : {"regress", "frames"}
        ``--auto``: ``frames`` takes each key-model's points from the frames that show it best; ``regress``
        (default) separates expressions a performer shows together by fitting every frame's points as a blend
        of the blendshape scores (:func:`_regress_picks`).
    """

    tracker: TrackerOptions = field(default_factory=TrackerOptions)
    window: int = 5
    search: float = 0.3
    min_score: float = 0.3
    min_motion: float = 0.15
    min_separation: float = 0.3
    auto_method: str = "regress"

    def __post_init__(self) -> None:
        if self.auto_method not in ("regress", "frames"):
            raise ValueError(f"auto_method must be 'regress' or 'frames', got {self.auto_method!r}")
        if self.window < 1:
            raise ValueError(f"window must be at least 1 frame, got {self.window}")
        if self.search < 0:
            raise ValueError(f"search must be >= 0 seconds, got {self.search}")


@dataclass(frozen=True)
class PerformerExamples:
    """A performer's neutral face and key expressions, as feature points.

    Attributes
    ----------
    neutral : (P, D) float
        Source base S_B.
    examples : (M, P, D) float
        Source examples S_i, in ``names`` order.
    names : tuple of M str
        Key-model names the examples pair with.
    point_names : tuple of P str
        Feature point names (the tracker's).
    frames : dict of str -> (int, int)
        For each name (``neutral`` included), the frames ``[start, stop)`` averaged.
    warnings : tuple of str
        What :func:`check_examples` found.
    noise : (P, D) float or None
        Each coordinate's noise scale (:func:`coordinate_noise`), from the blendshape scores (``--auto``) or
        the key expressions' blends (marks); None when there were too few frames or from a camera.
    nuisance : (K, P, D) float or None
        Feature points whose motion away from the neutral face is no expression: the frames of the marked
        ``head-motion`` spans (marks), or the head's turns as the landmark backend sees them (``--auto``
        with a tracker whose pose does not turn, :func:`head_turn_nuisance`); None otherwise.
    """

    neutral: np.ndarray
    examples: np.ndarray
    names: tuple[str, ...]
    point_names: tuple[str, ...]
    frames: dict = field(default_factory=dict)
    warnings: tuple[str, ...] = ()
    noise: np.ndarray | None = None
    nuisance: np.ndarray | None = None


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
        Frame rate of the calibration video (to turn times into frames).
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


def steadiest_window(points: np.ndarray, valid: np.ndarray, centre: int, radius: int,
                     window: int) -> tuple[int, int] | None:
    """The run of ``window`` valid frames near ``centre`` where the feature points move least.

    Parameters
    ----------
    points : (F, P, D) float
    valid : (F,) bool
    centre : int
        The marked frame.
    radius : int
        Frames either side of ``centre`` the window may reach.
    window : int
        Frames in the window (fewer if the video is shorter).

    Returns
    -------
    (start, stop) or None
        The window ``[start, stop)``: least summed squared frame-to-frame motion, ties to the one nearest
        ``centre``; None if no run of valid frames of that length lies within reach.
    """
    n = len(valid)
    window = max(1, min(window, n))
    lo, hi = max(0, centre - radius), min(n, centre + radius + 1)
    best, best_key = None, None
    step = np.zeros(n)
    if n > 1:
        d = np.diff(points, axis=0)
        step[1:] = np.einsum("fpd,fpd->f", d, d)
    for start in range(lo, hi - window + 1):
        stop = start + window
        if not valid[start:stop].all():
            continue
        motion = float(step[start + 1:stop].sum())
        key = (motion, abs((start + stop - 1) / 2 - centre))
        if best_key is None or key < best_key:
            best, best_key = (start, stop), key
    return best


def _average(track: Track, name: str, centre: int, config: CalibrateConfig) -> tuple[np.ndarray, tuple[int, int]]:
    radius = int(round(config.search * track.fps))
    span = steadiest_window(track.points, track.valid, centre, radius, config.window)
    if span is None:   # too few valid frames for a full window: take whatever valid frames lie within reach
        lo, hi = max(0, centre - radius), min(track.n_frames, centre + radius + 1)
        idx = np.flatnonzero(track.valid[lo:hi]) + lo
        if len(idx) == 0:
            raise FacepuppetError(f"{name} (frame {centre}): no face was tracked within {config.search:g} s "
                                  f"of it")
        span = (int(idx[0]), int(idx[-1]) + 1)
        return track.points[idx].mean(axis=0), span
    return track.points[span[0]:span[1]].mean(axis=0), span


def examples_from_marks(track: Track, marks: Sequence[Mark], config: CalibrateConfig | None = None,
                        ) -> PerformerExamples:
    """Average the feature points around each mark of a tracked calibration video; the frames of the
    ``head-motion`` spans, if any, become the nuisance (:class:`PerformerExamples`)."""
    config = config or CalibrateConfig()
    averaged, frames = {}, {}
    spans = [m for m in marks if m.name == HEAD_MOTION]
    for mark in marks:
        if mark.name != HEAD_MOTION:
            averaged[mark.name], frames[mark.name] = _average(track, mark.name, mark.frame, config)
    names = tuple(m.name for m in marks if m.name not in (NEUTRAL, HEAD_MOTION))
    neutral, examples = averaged[NEUTRAL], np.stack([averaged[n] for n in names])
    result = _finish(neutral, examples, names, track.point_names, frames, config)
    return replace(result, noise=_noise_from_examples(track, neutral, examples), nuisance=_head_motion(track, spans))


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


def _noise_from_examples(track: Track, neutral: np.ndarray, examples: np.ndarray) -> np.ndarray | None:
    """:func:`coordinate_noise` with each frame's blend of the key expressions (least squares) as its scores:
    what the key expressions cannot express in the calibration video. None with too few frames."""
    pts = track.points[track.valid]
    if len(pts) < len(examples) + 10:
        return None
    E = (examples - neutral[None]).reshape(len(examples), -1)
    W, *_ = np.linalg.lstsq(E.T, (pts - neutral[None]).reshape(len(pts), -1).T, rcond=None)
    return coordinate_noise(pts, W.T, neutral)


def _finish(neutral: np.ndarray, examples: np.ndarray, names: tuple[str, ...], point_names: Sequence[str],
            frames: dict, config: CalibrateConfig) -> PerformerExamples:
    warnings = check_examples(neutral, examples, names, min_motion=config.min_motion,
                              min_separation=config.min_separation)
    for w in warnings:
        log.info("%s", w)
    return PerformerExamples(neutral, examples, names, tuple(point_names), frames, tuple(warnings))


def calibrate_marks(media: str | os.PathLike, marks: str | os.PathLike, *, names: Sequence[str] | None = None,
                    config: CalibrateConfig | None = None, track: Track | None = None) -> PerformerExamples:
    """Key expressions from a calibration video and a marks file.

    Parameters
    ----------
    media : str or PathLike
        The calibration video (or image folder).
    marks : str or PathLike
        The marks file (module docstring).
    names : sequence of str, optional
        The character's key-model names, to check the marks against.
    config : CalibrateConfig, optional
    track : Track, optional
        A track of ``media`` made before (skips tracking).
    """
    config = config or CalibrateConfig()
    if track is None:
        from facepuppet.io.frames import open_media

        with open_media(media) as src:      # check the marks before the (slow) tracking
            fps, count = src.fps, src.frame_count
        if count is not None:
            read_marks(marks, fps, count, names)
        track = get_track(media, config.tracker)
    _need_faces(track, media)
    return examples_from_marks(track, read_marks(marks, track.fps, track.n_frames, names), config)


def _need_faces(track: Track, media) -> None:
    if not np.any(track.valid):
        raise FacepuppetError(f"{media}: no face was tracked in any frame")


# --- automatic calibration from blendshape scores ------------------------------------------------------

def _blendshape_scores(track: Track) -> tuple[np.ndarray, tuple[str, ...]]:
    extras = track.extras or {}
    if "blendshapes" not in extras:
        raise FacepuppetError("--auto needs the landmark backend's blendshape scores, and the track has none "
                              "(track with --backend mediapipe)")
    scores = np.asarray(extras["blendshapes"], dtype=float)
    names = extras.get("blendshape_names")
    if names is None:
        from facepuppet.capture.landmarks import BLENDSHAPE_NAMES as names
    names = tuple(str(n) for n in names)
    if scores.shape[1] != len(names):
        raise FacepuppetError(f"track has {scores.shape[1]} blendshape scores but {len(names)} names")
    return scores, names


#: ARKit blendshapes the feature curves cannot see (prefixes).
_UNTRACKED = ("eyeLook", "tongue")

#: --auto keeps the expressions that matter most first (a later one shown only together with an earlier one is
#: left out); the rest follow by score.
_PRIORITY = ("jawOpen", "eyeBlink", "mouthSmile", "browInnerUp", "browDown", "browOuterUp", "mouthFunnel",
             "mouthPucker", "mouthFrown", "mouthStretch", "eyeWide", "mouthRollLower", "cheekPuff", "eyeSquint")


def _regress_picks(picks: dict, groups: list, per_group: np.ndarray, track: Track, ok: np.ndarray,
                   neutral: np.ndarray) -> None:
    """Replace each picked expression by the displacement its score explains over the whole clip.

    Real faces combine expressions (a smile narrows the eyes, a frown lowers the brows), so the frame that
    shows one key-model best also shows some of others. Over all valid frames f, the displacements from
    neutral are fitted as a blend of the shown groups' scores, ``x_f - S_B ≈ Σ_g s_g(f) B_g``, by ridge least
    squares; ``S_B + B_g`` (the face at score 1 of group g alone) replaces the picked frame's points.
    """
    shown = [j for j, g in enumerate(groups) if picks[g] is not None]
    if not shown:
        return
    X = per_group[ok][:, shown]                                          # (F, G)
    Y = (track.points[ok] - neutral[None]).reshape(int(ok.sum()), -1)   # (F, P*D)
    gram = X.T @ X
    ridge = 1e-3 * np.trace(gram) / len(shown)
    B = np.linalg.solve(gram + ridge * np.eye(len(shown)), X.T @ Y)     # (G, P*D)
    for row, j in enumerate(shown):
        best, _, span = picks[groups[j]]
        picks[groups[j]] = (best, neutral + B[row].reshape(neutral.shape), span)


def _blend_of(d: np.ndarray, kept: list[tuple[str, np.ndarray, float]], tolerance: float) -> str:
    """Names of kept displacements whose blend comes within ``tolerance * |d|`` of ``d``; '' if none does."""
    if not kept:
        return ""
    A = np.stack([e.ravel() for _, e, _ in kept], axis=1)           # (N, K)
    c, *_ = np.linalg.lstsq(A, d.ravel(), rcond=None)
    if np.linalg.norm(A @ c - d.ravel()) >= tolerance * np.linalg.norm(d):
        return ""
    share = np.abs(c) * np.linalg.norm(A, axis=0)
    names = [kept[i][0] for i in np.argsort(-share) if share[i] > 0.1 * share.max()]
    return " and ".join(names[:3]) if len(names) <= 3 else ", ".join(names[:3]) + ", ..."


def _priority(parts: tuple[str, ...]) -> int:
    base = parts[0].removesuffix("Left").removesuffix("Right")
    return _PRIORITY.index(base) if base in _PRIORITY else len(_PRIORITY)


def _side_mask(points: np.ndarray, side: str, width: float) -> np.ndarray:
    """(P,) weight in [0, 1] of each neutral feature point on the performer's ``side`` (x > 0 is left)."""
    x = points[:, 0] - np.median(points[:, 0])
    s = 1.0 / (1.0 + np.exp(-x / max(width, 1e-9)))
    return s if side == "left" else 1.0 - s


def calibrate_auto(media: str | os.PathLike, names: Sequence[str], *, config: CalibrateConfig | None = None,
                   scores_track: Track | None = None, track: Track | None = None) -> PerformerExamples:
    """Key expressions picked from a video by the landmark backend's ARKit blendshape scores.

    For each key-model whose name is an ARKit blendshape (any common spelling, see
    :func:`facepuppet.arkit.arkit_parts`) the frame with the highest score of its blendshapes minus
    the mean score of the other key-models' is taken; the neutral face is the valid frame with the lowest
    total score (gaze and tongue shapes are left out: the curves do not see them). Feature points are
    averaged over the steadiest window near each pick. One side of a
    left/right pair (``eyeBlink_L`` with ``eyeBlink_R``, or ICT's ``cheekPuff_L``) gets the displacement of
    the symmetric expression on its own side of the face only (x > 0 is the performer's left), since
    performers rarely show one side alone. Then, the common expressions first (jaw, blinks, smiles, brows,
    ...) and the rest by score, key-models are left out (and reported) that
    the performer never shows (score below ``min_score``), that barely move the feature points, or that are
    shown only together with one already kept (the mapping could not tell them apart).

    When the track's own head pose never turns (the colour tracker's is upright: a turn of the head moves its
    feature points), the landmark backend's head rotation gives the nuisance (:func:`head_turn_nuisance`).

    Parameters
    ----------
    media : str or PathLike
        A video of the performer making faces.
    names : sequence of str
        The character's key-model names.
    config : CalibrateConfig, optional
        ``config.tracker`` makes the feature points; blendshape scores always come from MediaPipe.
    scores_track : Track, optional
        A MediaPipe track of ``media`` made before (with ``blendshapes`` in its extras).
    track : Track, optional
        A track of ``media`` by ``config.tracker``'s backend made before (defaults to ``scores_track`` when
        that backend is MediaPipe).
    """
    config = config or CalibrateConfig()
    if scores_track is None:
        mp_opts = TrackerOptions(backend="mediapipe", model=config.tracker.model, progress=config.tracker.progress)
        scores_track = get_track(media, mp_opts)
    if track is None:
        track = scores_track if config.tracker.backend == "mediapipe" else get_track(media, config.tracker)
    if track.n_frames != scores_track.n_frames:
        raise FacepuppetError(f"{media}: the two tracks differ in length ({track.n_frames} and "
                              f"{scores_track.n_frames} frames)")
    _need_faces(track, media)
    scores, score_names = _blendshape_scores(scores_track)
    col = {n: i for i, n in enumerate(score_names)}
    # A frame with a face but no head pose (the solver failed) has curves but no points in the head.
    ok = (track.valid & scores_track.valid & np.isfinite(scores).all(axis=1)
          & np.isfinite(track.points).all(axis=(1, 2)))
    if not ok.any():
        raise FacepuppetError(f"{media}: no frame has both a face and blendshape scores")

    wanted, skipped = [], []
    for name in names:
        parts = arkit_parts(name)
        if parts is None or not all(p in col for p in parts[0]):
            skipped.append(f"{name} (not an ARKit name)")
            continue
        if any(p.startswith(_UNTRACKED) for p in parts[0]):
            skipped.append(f"{name} (gaze and tongue are not tracked by the feature curves)")
            continue
        wanted.append((name, parts[0], parts[1]))
    if not wanted:
        raise FacepuppetError("--auto: none of the character's key-models carries an ARKit name "
                              f"({', '.join(names)}); use --marks")
    s = np.where(ok[:, None], scores, np.nan)
    used = sorted({col[p] for _, parts, _ in wanted for p in parts})
    relax = np.where(ok, np.nan_to_num(s[:, used]).sum(axis=1), np.inf)
    neutral_frame = int(np.argmin(relax))
    neutral, neutral_span = _average(track, NEUTRAL, neutral_frame, config)
    width = _face_scale(neutral) * 0.05

    # A key-model is shown by its blendshapes; one side of a left/right pair by the symmetric expression
    # (both sides' scores), whose displacement is then split between the sides of the face.
    shown: list[tuple[str, tuple[str, ...], str | None]] = []
    for name, parts, side in wanted:
        if side is None and len(parts) == 1 and parts[0].endswith(("Left", "Right")):
            base = parts[0][:-4] if parts[0].endswith("Left") else parts[0][:-5]
            mate = base + ("Right" if parts[0].endswith("Left") else "Left")
            if mate in col and any(mate in p for _, p, _ in wanted):
                shown.append((name, (base + "Left", base + "Right"), "left" if parts[0].endswith("Left")
                              else "right"))
                continue
        shown.append((name, parts, side))
    groups = sorted({parts for _, parts, _ in shown})
    per_group = np.stack([s[:, [col[p] for p in g]].mean(axis=1) for g in groups], axis=1)       # (F, G)
    total = np.nansum(per_group, axis=1)
    picks: dict[tuple[str, ...], tuple[float, np.ndarray, tuple[int, int]] | None] = {}
    for j, g in enumerate(groups):
        others = (total - per_group[:, j]) / max(len(groups) - 1, 1)
        merit = np.where(ok, per_group[:, j] - others, -np.inf)
        f = int(np.argmax(merit))
        best = float(per_group[f, j])
        if not best >= config.min_score:
            picks[g] = None
            continue
        pts, span = _average(track, g[0], f, config)
        picks[g] = (best, pts, span)
    if config.auto_method == "regress":
        _regress_picks(picks, groups, per_group, track, ok, neutral)

    # Keep the clearest first; leave out what the performer never shows, what barely moves, and what is
    # shown only together with a key-model already kept (the mapping could not tell them apart).
    order = sorted(range(len(shown)), key=lambda i: (_priority(shown[i][1]), -(picks[shown[i][1]] or (-1.0,))[0]))
    disp_all = [picks[shown[i][1]][1] - neutral for i in order if picks[shown[i][1]] is not None]
    rms_all = [float(np.sqrt((d ** 2).sum(axis=1).mean())) for d in disp_all]
    floor = max(config.min_motion * float(np.median(rms_all)) if rms_all else 0.0,
                0.005 * _face_scale(neutral))
    chosen: dict[str, np.ndarray] = {}
    frames = {NEUTRAL: neutral_span}
    kept_groups: list[tuple[str, np.ndarray, float]] = []
    verdict: dict[tuple[str, ...], str] = {}       # per group: "" kept, else why it is left out
    for i in order:
        name, parts, side = shown[i]
        pick = picks[parts]
        if pick is None:
            skipped.append(f"{name} (never shown: best score {np.nanmax(s[:, [col[p] for p in parts]]):.2f})")
            continue
        _, pts, span = pick
        full = pts - neutral            # both sides of a pair are judged together, before the split
        if parts not in verdict:
            rms = float(np.sqrt((full ** 2).sum(axis=1).mean()))
            if rms < floor:
                verdict[parts] = "barely moves the feature points"
            else:
                twin = _blend_of(full, kept_groups, config.min_separation)
                verdict[parts] = f"shown only together with {twin}" if twin else ""
                if not twin:
                    kept_groups.append((name, full, rms))
        if verdict[parts]:
            skipped.append(f"{name} ({verdict[parts]})")
            continue
        if side is not None:
            pts = neutral + _side_mask(neutral, side, width)[:, None] * full
        chosen[name] = pts
        frames[name] = span
    if skipped:
        log.info("--auto left out: %s", "; ".join(skipped))
    if not chosen:
        raise FacepuppetError(f"{media}: the performer shows none of the key-models clearly "
                              f"({'; '.join(skipped)})")
    kept = tuple(n for n in names if n in chosen)
    result = _finish(neutral, np.stack([chosen[n] for n in kept]), kept, track.point_names, frames, config)
    left_out = tuple(f"left out {x}" for x in skipped)
    kept_groups_idx = sorted({groups.index(parts) for name, parts, _ in shown if name in chosen})
    noise = coordinate_noise(track.points[ok], per_group[ok][:, kept_groups_idx], neutral)
    nuisance = head_turn_nuisance(track, scores_track, scores, ok, neutral) if _upright_only(track, ok) else None
    return PerformerExamples(result.neutral, result.examples, result.names, result.point_names, result.frames,
                             result.warnings + left_out, noise, nuisance)


def _upright_only(track: Track, ok: np.ndarray) -> bool:
    """Whether the track's head pose only rolls (its depth axis never moves): the turns are in its points."""
    R = track.rotation[ok]
    return bool(len(R)) and bool(np.isfinite(R).all()) and float(np.ptp(R[:, :, 2], axis=0).max()) < 1e-6


def head_turn_nuisance(track: Track, scores_track: Track, scores: np.ndarray, ok: np.ndarray,
                       neutral: np.ndarray) -> np.ndarray | None:
    """The motion of ``track``'s feature points that follows the head's turns as the landmark backend sees
    them, as nuisance points (K, P, D) for the mapping (:class:`PerformerExamples`).

    Over the frames ``ok``, the displacements are fitted as an affine function of the blendshape scores and of
    the head's small-angle yaw, pitch and roll (entries (0, 2), (1, 2) and (1, 0) of ``scores_track``'s
    rotation, centred), ``x_f − S_B ≈ c + Σ_b s_b(f) E_b + Σ_a θ_a(f) H_a`` (least squares); the nuisance
    points are ``S_B + Σ_a θ_a(f) H_a``, the turns with the expressions taken out. None without rotations
    that turn or with fewer than twice as many frames as terms.

    On the shared clips with the colour tracker (``--auto`` against ICT, the calibration on one half of a clip
    and the correlation with MediaPipe's scores on the other) it raised the jaw of performer_a 0.18 -> 0.37,
    the blink and smile of performer_b 0.33 -> 0.46 and 0.09 -> 0.17, the smile of performer_c 0.33 -> 0.91
    (a's smile 0.09 -> 0.01). With MediaPipe's own points, which its pose already frees of the turns, it is not
    used: it lowered performer_b's jaw (0.63 -> 0.51).
    """
    R = scores_track.rotation
    use = ok & np.isfinite(R).all(axis=(1, 2))
    angles = np.stack([R[use, 0, 2], R[use, 1, 2], R[use, 1, 0]], axis=1)
    if len(angles) < 2 * (1 + scores.shape[1] + angles.shape[1]) or float(np.ptp(angles, axis=0).max()) < 1e-6:
        return None
    angles -= angles.mean(axis=0)
    X = np.hstack([np.ones((len(angles), 1)), scores[use], angles])
    Y = (track.points[use] - neutral[None]).reshape(len(angles), -1)
    coef, *_ = np.linalg.lstsq(X, Y, rcond=None)
    return neutral[None] + (angles @ coef[-angles.shape[1]:]).reshape(len(angles), *neutral.shape)


#: Floors of :func:`coordinate_noise`: shares of the median point's noise and of the median point's motion.
NOISE_FLOOR = 0.1
MOTION_FLOOR = 0.05


def coordinate_noise(points: np.ndarray, scores: np.ndarray, neutral: np.ndarray,
                     floor: float = NOISE_FLOOR, motion_floor: float = MOTION_FLOOR) -> np.ndarray:
    """Each feature coordinate's noise scale: how much of its motion the shown expressions' scores leave
    unexplained.

    Over the frames f, the displacements are fitted as an affine function of the scores,
    ``x_f − S_B ≈ c + Σ_g s_g(f) B_g`` (least squares); the scale of coordinate j is the robust standard
    deviation of its residuals, ``σ_j = (median_f r_fj² / 0.455)^½`` (0.455: the median of a χ²₁ variable),
    raised to at least a floor, ``σ_j ← (σ_j² + σ₀²)^½``, ``σ₀ = max(floor · σ̃, motion_floor · b̃)`` with σ̃
    the median over points of their RMS σ and b̃ the median over points of their RMS motion per unit score
    (B_g): a coordinate that never moves would otherwise count infinitely, and noise far below the
    expressions' own motion does not matter. The mapping divides displacements by it (the mapper's
    ``point_scale``): tracking noise and motion no key-model explains weigh less.

    Parameters
    ----------
    points : (F, P, D) float
        Feature points of the frames with a face and scores.
    scores : (F, G) float
        Their scores, one column per expression kept (blendshape scores, or blend weights of the examples).
    neutral : (P, D) float

    Returns
    -------
    (P, D) float, positive
    """
    F = len(points)
    Y = (np.asarray(points, dtype=float) - neutral[None]).reshape(F, -1)
    X = np.column_stack([np.asarray(scores, dtype=float), np.ones(F)])
    coef, *_ = np.linalg.lstsq(X, Y, rcond=None)
    resid = Y - X @ coef
    sigma = np.sqrt(np.median(resid ** 2, axis=0) / 0.455).reshape(neutral.shape)
    per_point = np.sqrt((sigma ** 2).mean(axis=1))
    motion = np.sqrt((coef[:-1].reshape(len(coef) - 1, *neutral.shape) ** 2).mean(axis=(0, 2)))
    least = max(floor * float(np.median(per_point)), motion_floor * float(np.median(motion)))
    if not least > 0:
        least = max(float(per_point.max()), float(motion.max()), 1e-9)
    return np.sqrt(sigma ** 2 + least ** 2)


# --- interactive calibration from a camera --------------------------------------------------------------

#: Keys that capture the current expression (space, enter) and that cancel (q, Esc).
CAPTURE_KEYS = (ord(" "), 13, 10)
CANCEL_KEYS = (ord("q"), 27)

KeySource = Callable[[int, np.ndarray], int]
"""Called once per camera frame with (frame index, the picture shown); returns a key code or -1."""


def _window_key_source(title: str = "facepuppet calibrate") -> KeySource:
    """Show the picture in an OpenCV window and read the keyboard; a clear error when there is no display."""
    import sys

    import cv2

    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise FacepuppetError("--camera needs a display to show the key expressions, and none is available "
                              "(DISPLAY is not set); calibrate from a recorded video with --marks or --auto")

    def show(k: int, picture: np.ndarray) -> int:
        try:
            cv2.imshow(title, cv2.cvtColor(picture, cv2.COLOR_RGB2BGR))
            return int(cv2.waitKey(1))
        except cv2.error as e:
            raise FacepuppetError("--camera cannot open a window (OpenCV was built without a GUI, as "
                                  "opencv-python-headless is); calibrate from a recorded video with --marks "
                                  "or --auto") from e

    return show


def _prompt_picture(frame: np.ndarray, picture: np.ndarray | None, title: str, hint: str) -> np.ndarray:
    import cv2

    h = frame.shape[0]
    if picture is None:
        picture = np.full((h, h // 2, 3), 40, np.uint8)
    from facepuppet.export.preview import side_by_side

    out = side_by_side(frame, picture).copy()
    for y, text, scale in ((30, title, 0.8), (h - 15, hint, 0.5)):
        cv2.putText(out, text, (10, y), cv2.FONT_HERSHEY_SIMPLEX, scale, (0, 0, 0), 3, cv2.LINE_AA)
        cv2.putText(out, text, (10, y), cv2.FONT_HERSHEY_SIMPLEX, scale, (255, 255, 255), 1, cv2.LINE_AA)
    return out


def calibrate_interactive(camera: str, character, *, config: CalibrateConfig | None = None,
                          keys: KeySource | None = None, render: Callable[[str], np.ndarray] | None = None,
                          ) -> PerformerExamples:
    """Key expressions captured live: the performer copies each key-model shown and presses a key.

    The neutral face comes first, then each key-model of ``character`` in turn. For each, the camera frame
    (with its name) is shown beside a rendered picture of the key-model; space or enter captures it (the
    points of the steadiest ``config.window`` frames among the next ``2 * window`` valid ones are averaged),
    q or Esc cancels.

    Parameters
    ----------
    camera : str
        ``camera:N`` (device N), or ``camera:VIDEO`` with a video standing in for the device.
    character : Character
        The character whose key-models are shown.
    config : CalibrateConfig, optional
    keys : KeySource, optional
        Where key presses come from; by default an OpenCV window (which needs a display).
    render : callable name -> (H, W, 3) uint8, optional
        Picture of a key-model (``neutral`` included); by default rendered with
        :func:`facepuppet.export.render.render_mesh`.
    """
    from facepuppet.capture.tracking import make_tracker
    from facepuppet.io.frames import open_media

    config = config or CalibrateConfig()
    keys = keys or _window_key_source()
    render = render or _key_model_renderer(character)
    todo = [NEUTRAL, *character.names]
    pictures: dict[str, np.ndarray] = {}
    captured: dict[str, np.ndarray] = {}
    frames: dict[str, tuple[int, int]] = {}
    tracker = make_tracker(config.tracker.backend, **tracker_kwargs(config.tracker))
    point_names = None
    try:
        with open_media(camera) as src:
            step_ms = 1000.0 / src.fps
            buffer: list[np.ndarray] = []
            start = None
            for k, rgb in enumerate(src):
                if not todo:
                    break
                name = todo[0]
                feats = tracker.track(rgb, int(round(k * step_ms)))
                if point_names is None:
                    point_names = getattr(tracker, "point_names", None)
                if start is not None:                       # collecting after a key press
                    if feats.valid:
                        buffer.append(np.asarray(feats.points, dtype=float))
                    if len(buffer) >= 2 * config.window or k - start > 4 * config.window + 10:
                        if not buffer:
                            raise FacepuppetError(f"{camera}: no face was tracked while capturing {name}")
                        pts = np.stack(buffer)
                        span = steadiest_window(pts, np.ones(len(pts), bool), len(pts) // 2, len(pts),
                                                config.window) or (0, len(pts))
                        captured[name] = pts[span[0]:span[1]].mean(axis=0)
                        frames[name] = (start + span[0], start + span[1])
                        todo.pop(0)
                        buffer, start = [], None
                    continue
                if name not in pictures:
                    pictures[name] = render(name)
                status = "face found" if feats.valid else "no face"
                shown = _prompt_picture(rgb, pictures[name], f"{name} ({len(captured) + 1}/"
                                        f"{len(character.names) + 1})",
                                        f"copy the face, press space ({status}); q quits")
                key = keys(k, shown)
                if key in CANCEL_KEYS:
                    raise FacepuppetError("calibration cancelled; nothing was written")
                if key in CAPTURE_KEYS:
                    start = k
    finally:
        tracker.close()
    if todo:
        raise FacepuppetError(f"{camera}: the camera stopped before every key expression was captured "
                              f"(missing {', '.join(todo)})")
    names = tuple(character.names)
    from facepuppet.capture.curves import POINT_NAMES

    return _finish(captured[NEUTRAL], np.stack([captured[n] for n in names]), names,
                   point_names or POINT_NAMES, frames, config)


def _key_model_renderer(character) -> Callable[[str], np.ndarray]:
    from facepuppet.export.render import Camera, render_mesh

    camera = Camera.fit(character.neutral, (360, 360), margin=0.12)
    index = {n: i for i, n in enumerate(character.names)}

    def render(name: str) -> np.ndarray:
        verts = character.neutral if name == NEUTRAL else character.targets[index[name]]
        if character.faces is None:
            return np.full((360, 360, 3), 40, np.uint8)
        return render_mesh(verts, character.faces, camera=camera)

    return render


# --- the colour tracker's performer profile ------------------------------------------------------------

def make_profile(media: str | os.PathLike, path: str | os.PathLike, *, labels: Track | None = None,
                 model: str | None = None, every: int = 3, max_frames: int = 150,
                 progress: bool | None = None) -> Track:
    """Train the colour tracker's performer profile on a clip, labelled by the landmark backend (§3.1).

    Parameters
    ----------
    media : str or PathLike
        A short clip of the performer (the calibration video will do).
    path : str or PathLike
        Where to save the profile (``--profile`` of track, calibrate and animate).
    labels : Track, optional
        A MediaPipe track of ``media`` made before; tracked here otherwise.
    model : str, optional
        MediaPipe model file.
    every, max_frames : int
        Train on every ``every``-th labelled frame, at most ``max_frames`` of them.

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
    profile = train_profile(frames, labels.curves[keep[:len(frames)]], name=Path(media).stem)
    save_profile(path, profile)
    return labels


# --- checks and output ------------------------------------------------------------------------------------

def _face_scale(points: np.ndarray) -> float:
    return float(np.sqrt(((points - points.mean(axis=0)) ** 2).sum(axis=1).mean()))


def check_examples(neutral: np.ndarray, examples: np.ndarray, names: Sequence[str], *, min_motion: float = 0.15,
                   min_separation: float = 0.2) -> list[str]:
    """Name key expressions that barely differ from neutral or that are too close to tell apart.

    Parameters
    ----------
    neutral : (P, D) float
    examples : (M, P, D) float
    names : sequence of M str
    min_motion : float
        Relative to the median RMS displacement of all examples (and at least 0.5 % of the face's size).
    min_separation : float
        Relative to the smaller RMS displacement of the two examples.

    Returns
    -------
    list of str, one message per problem, naming the key expressions.
    """
    d = np.asarray(examples, dtype=float) - np.asarray(neutral, dtype=float)[None]
    rms = np.sqrt((d ** 2).sum(axis=2).mean(axis=1))
    floor = max(min_motion * float(np.median(rms)), 0.005 * _face_scale(np.asarray(neutral, dtype=float)))
    out = [f"{names[i]} barely differs from neutral (moves the feature points {rms[i]:.3g} RMS, "
           f"the median key expression {np.median(rms):.3g})" for i in range(len(names)) if rms[i] < floor]
    weak = {i for i in range(len(names)) if rms[i] < floor}
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            if i in weak or j in weak:
                continue
            sep = float(np.sqrt(((d[i] - d[j]) ** 2).sum(axis=1).mean()))
            if sep < min_separation * min(rms[i], rms[j]):
                out.append(f"{names[i]} and {names[j]} are too close to tell apart (they differ by {sep:.3g} "
                           f"RMS, each moves about {min(rms[i], rms[j]):.3g})")
    return out


def save_examples(path: str | os.PathLike, result: PerformerExamples) -> None:
    """Write the performer examples file that ``facepuppet rig --performer`` reads (atomically)."""
    from facepuppet.io.performer import Performer, save_performer

    save_performer(path, Performer(result.neutral, result.examples, result.names, result.point_names,
                                   result.noise, result.nuisance))
