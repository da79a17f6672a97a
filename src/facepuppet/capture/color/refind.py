"""Finding a face just lost again: where, at what size and roll a face that was followed until a few frames ago
can be now (:class:`LostFace`, :func:`plausible`), and how a candidate is scored against it (:func:`likeness`).

A face is not suddenly half its size, nor somewhere else: behind a passing hand it is still where it was, at the
size it had. The size it had is the followed face's slow size reference (:attr:`.follow.FollowState.unit_ref`),
not the size of the last frame followed, which a hand arriving over the face may already have pulled off
(:data:`REFIND_SIZES`). A face coming closer fast grows more than that before it is found again; such a size is
taken only where the face cascade's window of a face that size holds it (:data:`REFIND_GROWN`): the eye search
alone may pull a candidate onto a hand and the face under it. The sizes allowed widen with the time the face
has been lost (:data:`REFIND_DRIFT`: a performer walking closer while hidden; in milliseconds, whatever the
frame rate or the frames skipped), up to :data:`LOST_SIZES`; after :data:`~.follow.LOST_MEMORY` the face is
searched afresh anywhere.

Conventions: face frames in image pixels (:class:`~facepuppet.capture.color.face.FaceFrame`); a face unit is the
eye-centre distance; sizes compared as natural logs of their ratio.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from facepuppet.capture.color.face import FaceFrame
from facepuppet.capture.color.measure import Measurement

__all__ = ["LostFace", "LOST_SIZES", "LOST_ROLL", "LOST_REACH", "REFIND_SIZES", "REFIND_GROWN", "REFIND_DRIFT",
           "plausible", "likeness", "size_band"]

# Tuning constants                      unit          what it does
LOST_SIZES = (0.65, 1.5)                # ratio         widest sizes a face just lost is found again at, of its size
LOST_ROLL = 0.5                         # radians       most roll a face just lost may be found again with
LOST_REACH = 2.0                        # face units    farthest from where a face was just lost it is found again
REFIND_SIZES = (-0.15, 0.15)            # log size      sizes a face found again at once has, of the size it had ...
REFIND_GROWN = 0.3                      # log size      ... or at most this much larger where a window holds it ...
REFIND_DRIFT = 0.3e-3                   # log size / ms ... widened by this each way per millisecond it is lost


@dataclass(frozen=True)
class LostFace:
    """A face followed until a few frames ago.

    Attributes
    ----------
    frame : FaceFrame
        The frame it was last followed in (image pixels).
    unit : float
        The size it had: its slow size reference while it was followed (image pixels per face unit).
    ms : float
        Milliseconds since it was lost (0: lost in this frame).
    """

    frame: FaceFrame
    unit: float
    ms: float = 0.0

    def at_its_size(self) -> FaceFrame:
        """The last frame scaled about its origin to the size the face had (where a hand arriving over the face
        pulled the last frame off its size, the face is there at this one)."""
        return FaceFrame(self.frame.origin.copy(), self.frame.axis * (self.unit / self.frame.unit))


def size_band(ms: float, held: bool = False) -> tuple[float, float]:
    """Smallest and largest log size change (of the size it had) of a face lost ``ms`` milliseconds ago:
    :data:`REFIND_SIZES` (growing up to :data:`REFIND_GROWN` if ``held``: a cascade window of a face that size
    holds the candidate) widened each way by :data:`REFIND_DRIFT` per millisecond, at most :data:`LOST_SIZES`."""
    drift = REFIND_DRIFT * max(float(ms), 0.0)
    grow = REFIND_GROWN if held else REFIND_SIZES[1]
    return (float(max(REFIND_SIZES[0] - drift, np.log(LOST_SIZES[0]))),
            float(min(grow + drift, np.log(LOST_SIZES[1]))))


def plausible(frame: FaceFrame, lost: LostFace, held: bool = False) -> bool:
    """Whether a face lost (``lost``) can be in ``frame`` now: its size within :func:`size_band` (with ``held``)
    of the size it had, its roll within :data:`LOST_ROLL` of its last frame's, its origin within
    :data:`LOST_REACH` of its units of its last frame's (a hand over the face with the face's eyes, a smaller
    face-like thing beside it, a skin-coloured thing elsewhere are not it)."""
    last = lost.frame
    lo, hi = size_band(lost.ms, held)
    if not lo <= np.log(frame.unit / lost.unit) <= hi:
        return False
    roll = abs(last.turn_to(frame))
    far = float(np.hypot(*(frame.origin - last.origin))) > LOST_REACH * lost.unit
    return roll <= LOST_ROLL and not far


def likeness(result: Measurement, lost: LostFace | FaceFrame | None, resize_cost: float,
             held: bool = False) -> float:
    """How much a measurement's crop looks like a face (its score), less ``resize_cost`` per unit of absolute log
    size change from the size the face just lost had; -inf where that face cannot be (:func:`plausible` with
    ``held``). ``lost``: the face just lost (a bare frame: lost in this frame, at that frame's size), or None
    (anywhere)."""
    if lost is None:
        return result.score
    if isinstance(lost, FaceFrame):
        lost = LostFace(lost, lost.unit)
    if not plausible(result.frame, lost, held):
        return -np.inf
    return result.score - resize_cost * abs(np.log(result.frame.unit / lost.unit))
