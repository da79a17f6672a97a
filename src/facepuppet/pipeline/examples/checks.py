"""Checks of the key expressions: the ones too close to each other to tell apart, or barely different from
neutral (the paper's mapping cannot separate them, §5), and the :class:`Performer` that carries the findings."""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np

from facepuppet.io.performer import Performer
from facepuppet.pipeline.examples.config import MIN_MOTION, MIN_SEPARATION, ExamplesConfig

__all__ = ["check_examples", "explaining_blend", "face_scale", "make_performer", "FACE_MOTION_FLOOR",
           "MAIN_SHARE"]

log = logging.getLogger(__name__)

#: Least RMS displacement of a key expression from neutral, as a share of the face's size (:func:`face_scale`).
FACE_MOTION_FLOOR = 0.005
#: :func:`explaining_blend` names the kept expressions whose share of the blend exceeds this share of the largest.
MAIN_SHARE = 0.1


def face_scale(points: np.ndarray) -> float:
    """RMS distance of the points (P, D) from their centroid: the face's size in the points' units."""
    return float(np.sqrt(((points - points.mean(axis=0)) ** 2).sum(axis=1).mean()))


def check_examples(neutral: np.ndarray, examples: np.ndarray, names: Sequence[str], *,
                   min_motion: float = MIN_MOTION, min_separation: float = MIN_SEPARATION) -> list[str]:
    """Name key expressions that barely differ from neutral or that are too close to tell apart.

    Parameters
    ----------
    neutral : (P, D) float
    examples : (M, P, D) float
    names : sequence of M str
    min_motion : float
        Relative to the median RMS displacement of all examples (and at least :data:`FACE_MOTION_FLOOR` of
        the face's size).
    min_separation : float
        Relative to the smaller RMS displacement of the two examples.

    Returns
    -------
    list of str, one message per problem, naming the key expressions.
    """
    d = np.asarray(examples, dtype=float) - np.asarray(neutral, dtype=float)[None]
    rms = np.sqrt((d ** 2).sum(axis=2).mean(axis=1))
    floor = max(min_motion * float(np.median(rms)),
                FACE_MOTION_FLOOR * face_scale(np.asarray(neutral, dtype=float)))
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


def explaining_blend(d: np.ndarray, kept: Sequence[tuple[str, np.ndarray, float]], tolerance: float) -> str:
    """Names of the kept displacements whose least-squares blend comes within ``tolerance * |d|`` of ``d``.

    Parameters
    ----------
    d : (P, D) float
        A key expression's displacement from neutral.
    kept : sequence of (name, (P, D) displacement, RMS)
        The key expressions kept so far.
    tolerance : float
        Largest norm of the blend's residual, as a share of ``|d|`` (Euclidean norms).

    Returns
    -------
    str
        ``"a and b"`` (at most three names, the largest shares first), or ``""`` if no blend comes that close.
    """
    if not kept:
        return ""
    A = np.stack([e.ravel() for _, e, _ in kept], axis=1)           # (N, K)
    c, *_ = np.linalg.lstsq(A, d.ravel(), rcond=None)
    if np.linalg.norm(A @ c - d.ravel()) >= tolerance * np.linalg.norm(d):
        return ""
    share = np.abs(c) * np.linalg.norm(A, axis=0)
    names = [kept[i][0] for i in np.argsort(-share) if share[i] > MAIN_SHARE * share.max()]
    return " and ".join(names[:3]) if len(names) <= 3 else ", ".join(names[:3]) + ", ..."


def make_performer(neutral: np.ndarray, examples: np.ndarray, names: tuple[str, ...], point_names: Sequence[str],
                   frames: dict, config: ExamplesConfig, *, noise: np.ndarray | None = None,
                   nuisance: np.ndarray | None = None, left_out: Sequence[str] = ()) -> Performer:
    """The :class:`Performer` of checked key expressions: :func:`check_examples`' findings (logged) are its
    ``warnings``, followed by ``"left out ..."`` for each of ``left_out``."""
    warnings = check_examples(neutral, examples, names, min_motion=config.min_motion,
                              min_separation=config.min_separation)
    for w in warnings:
        log.info("%s", w)
    return Performer(neutral, examples, names, tuple(point_names), noise, nuisance, frames=frames,
                     warnings=tuple(warnings) + tuple(f"left out {x}" for x in left_out))
