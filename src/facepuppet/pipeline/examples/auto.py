"""Key expressions picked from a video by the landmark backend's ARKit blendshape scores (``--auto``).

For characters whose key-models carry ARKit names: the scores pick the frame that best shows each key-model
and the most relaxed frames as neutral; by default every frame's points are then fitted as a blend of the
scores, each key-model moving only its own part of the face (:func:`from_auto`, :func:`regress_picks`).
"""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence

import numpy as np

from facepuppet.arkit import arkit_parts
from facepuppet.errors import FacepuppetError
from facepuppet.io.performer import Performer
from facepuppet.io.track import Track
from facepuppet.mapping.noise import coordinate_noise, head_turn_nuisance
from facepuppet.pipeline.examples.checks import FACE_MOTION_FLOOR, explaining_blend, face_scale, make_performer
from facepuppet.pipeline.examples.config import NEUTRAL, ExamplesConfig
from facepuppet.pipeline.examples.regions import movable, regional_fit
from facepuppet.pipeline.examples.window import average_near, lowest_window, need_faces
from facepuppet.pipeline.tracking import TrackerOptions, get_track

__all__ = ["from_auto", "blendshape_scores", "regress_picks", "side_mask", "UNTRACKED", "PRIORITY",
           "RIDGE", "SIDE_WIDTH"]

log = logging.getLogger(__name__)

#: ARKit blendshapes the feature curves cannot see (prefixes).
UNTRACKED = ("eyeLook", "tongue")

#: The expressions that matter most, kept first (a later one shown only together with an earlier one is left
#: out); the rest follow by score.
PRIORITY = ("jawOpen", "eyeBlink", "mouthSmile", "browInnerUp", "browDown", "browOuterUp", "mouthFunnel",
            "mouthPucker", "mouthFrown", "mouthStretch", "eyeWide", "mouthRollLower", "cheekPuff", "eyeSquint")

#: Ridge of :func:`regress_picks`, as a share of the mean diagonal of the scores' Gram matrix.
RIDGE = 1e-3
#: Width of the left/right split of :func:`side_mask` (logistic scale), as a share of the face's size.
SIDE_WIDTH = 0.05


def blendshape_scores(track: Track) -> tuple[np.ndarray, tuple[str, ...]]:
    """The track's blendshape scores (F, B) and their B names (the landmark backend's extras)."""
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


def regress_picks(picks: dict, groups: list, per_group: np.ndarray, track: Track, ok: np.ndarray,
                  neutral: np.ndarray) -> np.ndarray:
    """Replace each picked expression (in place) by the displacement its score explains over the whole clip,
    in the part of the face it moves; return the face at zero scores, the new neutral.

    Real faces combine expressions (a smile narrows the eyes, a frown lowers the brows, an exaggerated performer
    opens the mouth while blinking), so the frame that shows one key-model best also shows some of others.
    Over all valid frames f, the displacements from ``neutral`` are fitted as an affine blend of the shown
    groups' scores, ``x_f - S ≈ c + Σ_g s_g(f) B_g``, where each B_g is zero outside the points its
    blendshapes move (:func:`facepuppet.pipeline.examples.regions.movable`: a blink moves the eyelids, not the
    lips) and each region's points are fitted on the scores of the groups that move them, by ridge least
    squares (:func:`~facepuppet.pipeline.examples.regions.regional_fit`, ridge :data:`RIDGE`). ``S + c`` is
    the face at zero scores, a neutral that needs no fully relaxed frame; ``S + c + B_g`` (the face at score
    1 of group g alone) replaces the picked frame's points.

    Parameters
    ----------
    picks : dict of group -> (score, (P, D) points, (start, stop)) or None
    groups : list of G groups (tuples of blendshape names)
    per_group : (F, G) float
        Each group's score per frame.
    track : Track
    ok : (F,) bool
        Frames with a face, scores and feature points.
    neutral : (P, D) float
        The most relaxed frames' points.

    Returns
    -------
    (P, D) float
        The neutral face S + c (``neutral`` itself when no group was picked).
    """
    shown = [j for j, g in enumerate(groups) if picks[g] is not None]
    if not shown:
        return neutral
    allowed = movable([groups[j] for j in shown], track.point_names)
    B, c = regional_fit(per_group[ok][:, shown], track.points[ok] - neutral[None], allowed, RIDGE,
                        intercept=True)
    base = neutral + c
    for row, j in enumerate(shown):
        best, _, span = picks[groups[j]]
        picks[groups[j]] = (best, base + B[row], span)
    return base


def _priority(parts: tuple[str, ...]) -> int:
    base = parts[0].removesuffix("Left").removesuffix("Right")
    return PRIORITY.index(base) if base in PRIORITY else len(PRIORITY)


def side_mask(points: np.ndarray, side: str, width: float) -> np.ndarray:
    """(P,) weight in [0, 1] of each neutral feature point on the performer's ``side`` (x > 0 is left):
    a logistic step of scale ``width`` about the median x."""
    x = points[:, 0] - np.median(points[:, 0])
    s = 1.0 / (1.0 + np.exp(-x / max(width, 1e-9)))
    return s if side == "left" else 1.0 - s


def _upright_only(track: Track, ok: np.ndarray) -> bool:
    """Whether the track's head pose only rolls (its depth axis never moves): the turns are in its points."""
    R = track.rotation[ok]
    return bool(len(R)) and bool(np.isfinite(R).all()) and float(np.ptp(R[:, :, 2], axis=0).max()) < 1e-6


def from_auto(media: str | os.PathLike, names: Sequence[str], *, config: ExamplesConfig | None = None,
              scores_track: Track | None = None, track: Track | None = None) -> Performer:
    """Capture the key expressions from a video, picked by the landmark backend's ARKit blendshape scores.

    For each key-model whose name is an ARKit blendshape (any common spelling, see
    :func:`facepuppet.arkit.arkit_parts`) the frame with the highest score of its blendshapes minus the mean score
    of the other key-models' is taken; the neutral face is the run of ``config.window`` valid frames with the lowest
    total score (gaze and tongue shapes are left out: the curves do not see them). Feature points are averaged over
    the steadiest window near each pick; with ``config.auto_method == "regress"`` (default) they are then replaced
    by what each score explains over the clip in the part of the face its blendshapes move, and the neutral by the
    face at zero scores (:func:`regress_picks`). One side of a left/right pair (``eyeBlink_L`` with ``eyeBlink_R``,
    or ICT's ``cheekPuff_L``) gets the displacement of the symmetric expression on its own side of the face only (x
    > 0 is the performer's left), since performers rarely show one side alone. Then, the common expressions first
    (:data:`PRIORITY`) and the rest by score, key-models are left out (and reported in the warnings) that the
    performer never shows (score below ``config.min_score``), that barely move the feature points, or that are shown
    only together with one already kept (``config.blend_tolerance``; the mapping could not tell them apart). With
    ``regress`` the kept key-models are then fitted again without the left-out ones, so that together they
    explain the clip as the mapping will see it.

    The noise is :func:`facepuppet.mapping.noise.coordinate_noise` with the kept key-models' scores. When the
    track's own head pose never turns (the colour tracker's is upright: a turn of the head moves its feature
    points), the landmark backend's head rotation gives the nuisance
    (:func:`facepuppet.mapping.noise.head_turn_nuisance`).

    Parameters
    ----------
    media : str or PathLike
        A video of the performer making faces.
    names : sequence of str
        The character's key-model names.
    config : ExamplesConfig, optional
        ``config.tracker`` makes the feature points; blendshape scores always come from MediaPipe.
    scores_track : Track, optional
        A MediaPipe track of ``media`` made before (with ``blendshapes`` in its extras).
    track : Track, optional
        A track of ``media`` by ``config.tracker``'s backend made before (defaults to ``scores_track`` when
        that backend is MediaPipe).
    """
    config = config or ExamplesConfig()
    if scores_track is None:
        mp_opts = TrackerOptions(backend="mediapipe", model=config.tracker.model, progress=config.tracker.progress)
        scores_track = get_track(media, mp_opts)
    if track is None:
        track = scores_track if config.tracker.backend == "mediapipe" else get_track(media, config.tracker)
    if track.n_frames != scores_track.n_frames:
        raise FacepuppetError(f"{media}: the two tracks differ in length ({track.n_frames} and "
                              f"{scores_track.n_frames} frames)")
    need_faces(track, media)
    scores, score_names = blendshape_scores(scores_track)
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
        if any(p.startswith(UNTRACKED) for p in parts[0]):
            skipped.append(f"{name} (gaze and tongue are not tracked by the feature curves)")
            continue
        wanted.append((name, parts[0], parts[1]))
    if not wanted:
        raise FacepuppetError("--auto: none of the character's key-models carries an ARKit name "
                              f"({', '.join(names)}); use --marks")
    s = np.where(ok[:, None], scores, np.nan)
    used = sorted({col[p] for _, parts, _ in wanted for p in parts})
    relax = np.where(ok, np.nan_to_num(s[:, used]).sum(axis=1), np.inf)
    neutral_span = lowest_window(relax, ok, config.window)
    if neutral_span is None:
        neutral, neutral_span = average_near(track, NEUTRAL, int(np.argmin(relax)), config)
    else:
        neutral = track.points[neutral_span[0]:neutral_span[1]].mean(axis=0)
    width = face_scale(neutral) * SIDE_WIDTH

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
        pts, span = average_near(track, g[0], f, config)
        picks[g] = (best, pts, span)
    if config.auto_method == "regress":
        neutral = regress_picks(picks, groups, per_group, track, ok, neutral)

    # Keep the clearest first; leave out what the performer never shows, what barely moves, and what is
    # shown only together with a key-model already kept (the mapping could not tell them apart).
    order = sorted(range(len(shown)), key=lambda i: (_priority(shown[i][1]), -(picks[shown[i][1]] or (-1.0,))[0]))
    disp_all = [picks[shown[i][1]][1] - neutral for i in order if picks[shown[i][1]] is not None]
    rms_all = [float(np.sqrt((d ** 2).sum(axis=1).mean())) for d in disp_all]
    floor = max(config.min_motion * float(np.median(rms_all)) if rms_all else 0.0,
                FACE_MOTION_FLOOR * face_scale(neutral))
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
                twin = explaining_blend(full, kept_groups, config.blend_tolerance)
                verdict[parts] = f"shown only together with {twin}" if twin else ""
                if not twin:
                    kept_groups.append((name, full, rms))
        if verdict[parts]:
            skipped.append(f"{name} ({verdict[parts]})")
            continue
        if side is not None:
            pts = neutral + side_mask(neutral, side, width)[:, None] * full
        chosen[name] = pts
        frames[name] = span
    if skipped:
        log.info("--auto left out: %s", "; ".join(skipped))
    if not chosen:
        raise FacepuppetError(f"{media}: the performer shows none of the key-models clearly "
                              f"({'; '.join(skipped)})")
    kept = tuple(n for n in names if n in chosen)
    kept_groups_idx = sorted({groups.index(parts) for name, parts, _ in shown if name in chosen})
    if config.auto_method == "regress":
        # Fitted again with the kept key-models alone: together they explain the clip as the mapping will see it.
        kept_picks = {groups[j]: picks[groups[j]] for j in kept_groups_idx}
        neutral = regress_picks(kept_picks, [groups[j] for j in kept_groups_idx], per_group[:, kept_groups_idx],
                                track, ok, neutral)
        for name, parts, side in shown:
            if name in chosen:
                full = kept_picks[parts][1] - neutral
                chosen[name] = neutral + (full if side is None else side_mask(neutral, side, width)[:, None] * full)
    noise = coordinate_noise(track.points[ok], per_group[ok][:, kept_groups_idx], neutral)
    nuisance = (head_turn_nuisance(track.points[ok], scores_track.rotation[ok], scores[ok], neutral)
                if _upright_only(track, ok) else None)
    return make_performer(neutral, np.stack([chosen[n] for n in kept]), kept, track.point_names, frames, config,
                          noise=noise, nuisance=nuisance, left_out=skipped)
