"""Following the face between frames: the face crop aligned on a reference crop of the acquisition (ECC,
:mod:`.align`), and the evidence that the face followed is still the face found (:class:`FollowState`).

The search starts where the alignment put the face in the last frame, so a couple of steps suffice; the eyes
then correct the result (:class:`~facepuppet.capture.color.tracker.ColorTracker`).

Conventions: crop matrices (2, 3) map image pixels to crop pixels; the aligned crops are grey float32 at
``scale`` times the tracker's crop resolution.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import cv2
import numpy as np

from facepuppet.capture.color.align import blur3, ecc_affine
from facepuppet.capture.color.config import FollowConfig
from facepuppet.capture.color.face import CROP_EXTENT, FaceFrame, same_frame, then_affine
from facepuppet.capture.color.refind import LostFace

__all__ = ["Follower", "FollowState", "ECC_EPS", "ECC_BLUR", "UNIT_JUMP", "UNIT_GAIN", "FRAME_MS", "LOST_MEMORY",
           "OWN_LIKENESS", "OWN_CHECKS", "NEAR"]

log = logging.getLogger(__name__)

# Tuning constants       unit          what it does
ECC_EPS = 1e-3           # correlation   the alignment's convergence tolerance (ECC)
ECC_BLUR = 3             # pixels        Gaussian blur of the alignment's images (ECC; :func:`.align.blur3`)
UNIT_JUMP = (0.65, 1.5)  # ratio         size change from the slow reference that loses the face
UNIT_GAIN = 0.05         # per frame     gain of the slow reference size, per FRAME_MS of time followed
FRAME_MS = 1000.0 / 30   # milliseconds  the frame time UNIT_GAIN is given for
LOST_MEMORY = 1000       # milliseconds  a lost face's last frame is searched near this long
OWN_LIKENESS = 0.6       # fraction      of the face's best likeness a face found again must show ...
OWN_CHECKS = 3           # checks        ... at its first checks
#: How near (face units, log size, radians of roll) a face found again and not yet checked must be to the last face
#: that was, to stand for it once lost.
NEAR = (0.5, 0.25, 0.2)


@dataclass
class FollowState:
    """The face being followed from frame to frame, and the evidence that it is still the face found."""

    frame: FaceFrame | None = None          # the face frame of the last frame (None: lost)
    misses: int = 0                         # frames in a row without the eyes
    correction: np.ndarray | None = None    # the eyes' smoothed correction (a, b, tx, ty), crop pixels
    unit_ref: float = 1.0                   # slow reference of the face's size, image pixels
    skin: bool = True                       # whether the last measured crop's cheeks looked like skin
    skin_found: bool = True                 # whether they did where the face was found
    dropped: FaceFrame | None = None        # the frame the face was last followed in, while it is lost
    lost_ms: float = 0.0                    # time the face was lost at, milliseconds
    ref_ms: float | None = None             # time the slow size reference was last moved at, milliseconds
    doubted: bool = False                   # it was lost because its crop no longer looked like a face
    score: float | None = None              # smoothed likeness of the followed crop
    score_ref: float | None = None          # the face's own likeness: the best smoothed one of this face
    found_again: int = 0                    # checks left at which a face found again must look like itself
    check_in: int = 1                       # frames to the next check of the likeness
    pose: object = None                     # the last head pose (the next solve starts there)
    #: The last face lost that had passed its first checks (its frame, size reference and the time it was lost
    #: at), kept while the faces found again after it have not (:attr:`found_again`).
    pending: tuple[FaceFrame, float, float] | None = None

    def still_the_face(self, frame: FaceFrame, correlation: float | None, config: FollowConfig,
                       ms: float | None = None) -> bool:
        """Whether the evidence of the face itself says the followed face (now in ``frame``) is still there: the
        crop's alignment on the reference crop of the acquisition succeeded and matches it (``correlation``,
        :attr:`Follower.correlation`; closer where the cheeks no longer look like skin though they did), the
        eyes were found within the last ``max_misses`` frames, and the face's size kept near its slow
        reference (which then follows it, by :data:`UNIT_GAIN` per :data:`FRAME_MS` since it last moved: as
        fast in time whatever the frames skipped; ``ms``: this frame's time, None: one frame later)."""
        bar = config.min_correlation if self.skin or not self.skin_found else config.skinless_correlation
        if correlation is None or correlation < bar:
            log.debug("face lost: its crop no longer matches the reference (correlation %s)", correlation)
            return False
        if self.misses > config.max_misses or not UNIT_JUMP[0] < frame.unit / self.unit_ref < UNIT_JUMP[1]:
            return False
        frames = 1.0 if ms is None or self.ref_ms is None else max(ms - self.ref_ms, 0.0) / FRAME_MS
        self.ref_ms = ms
        self.unit_ref += (1.0 - (1.0 - UNIT_GAIN) ** frames) * (frame.unit - self.unit_ref)
        return True

    def lost_face(self, ms: float) -> LostFace | None:
        """The face just lost (in this frame, of time ``ms``, or in the last :data:`LOST_MEMORY` milliseconds) with
        the size it had (the slow size reference), or None.

        A face found again that is lost before it has passed its first checks is the face just lost only where it
        is about where the face that had passed them was (:attr:`pending`, :func:`_near`: a face behind a passing
        hand, found and lost in turn); elsewhere, or rolled off it, that face is (a candidate taken on the hair or
        an ear beside a turned head, lost at once, would otherwise be where the next search looks, and each such
        face would lead the search further off the face), or none once it was lost more than
        :data:`LOST_MEMORY` ago."""
        if self._stray():
            frame, unit, lost_ms = self.pending
            return LostFace(frame, unit, max(ms - lost_ms, 0.0)) if ms - lost_ms <= LOST_MEMORY else None
        last = self.frame or self.dropped
        if last is None:
            return None
        return LostFace(last, self.unit_ref, 0.0 if self.frame is not None else max(ms - self.lost_ms, 0.0))

    def _stray(self) -> bool:
        """Whether the face followed now was found again, has not yet passed its first checks, and is not about
        where the last face that had passed them was (:attr:`pending`, :func:`_near`)."""
        return self.frame is not None and self.pending is not None and not _near(self.frame, self.pending[0])

    def found(self, last: LostFace | None, ms: float) -> None:
        """A face was found in the frame of time ``ms``; ``last``: the face lost that it was searched near
        (:meth:`lost_face`). Until the face found has passed its first checks, the last face that had passed them
        stays :attr:`pending`."""
        self.dropped = None
        if last is None:
            self.pending = None
        elif self.pending is None:
            self.pending = (last.frame, last.unit, ms - last.ms)

    def drop(self, ms: float, doubted: bool = False) -> None:
        """The face is lost in the frame of time ``ms`` (``doubted``: its crop no longer looked like a face); its
        last frame is kept for a while (:meth:`lost_face`: a face that had not yet passed its first checks and is
        not about where the last face that had was leaves that face's frame instead)."""
        if self._stray():
            self.dropped, self.unit_ref, self.lost_ms = self.pending
            self.pending = None
        elif self.frame is not None:
            self.dropped, self.lost_ms = self.frame, ms
        self.frame, self.doubted, self.ref_ms = None, self.doubted or doubted, None
        if ms - self.lost_ms > LOST_MEMORY:
            self.dropped = self.score_ref = self.pending = None

    def still_like_a_face(self, score: float, config: FollowConfig) -> bool:
        """Now and then: whether the followed crop, of likeness ``score`` to a face, still looks like one (the
        likeness smoothed over checks).

        The bar is ``config.min_followed_score``; at the first :attr:`found_again` checks after the face was
        found again (:data:`OWN_CHECKS`), :data:`OWN_LIKENESS` of the best this face has shown if higher (a face
        found again while a hand still covered part of it may sit off the face, and looks less like it than the
        face did, more so once the hand has gone; another performer's face may look little like the profile's
        layout all along, and expressions move the likeness of any face).
        """
        self.score = score if self.score is None else 0.5 * (self.score + score)
        bar = config.min_followed_score
        if self.found_again and self.score_ref is not None:
            bar = max(bar, OWN_LIKENESS * self.score_ref)
        self.found_again = max(int(self.found_again) - 1, 0)
        if not self.found_again:
            self.pending = None                 # the face found again has shown it is the face
        self.score_ref = self.score if self.score_ref is None else max(self.score_ref, self.score)
        if self.score < bar:
            log.debug("face lost: the followed crop no longer looks like a face (score %.2f)", self.score)
            return False
        return True


def _near(frame: FaceFrame, other: FaceFrame) -> bool:
    """Whether ``frame`` is about where ``other`` is: within :data:`NEAR` (face units of ``other``, log size,
    radians of roll) of it."""
    move, size, roll = NEAR
    return abs(other.turn_to(frame)) <= roll and same_frame(other, frame, move, size)


class Follower:
    """The alignment of each frame's face crop on the reference crop taken when the face was acquired.

    Parameters
    ----------
    size : (int, int)
        Width and height of the tracker's face crop, pixels.
    px : float
        Crop pixels per face unit.
    config : FollowConfig
    both_axes : bool
        Size the face by what the alignment's axis that changed least says (:meth:`_height_share`), else by its
        horizontal axis alone: a trained profile reads the head's nod off the crop's look, which sizing by the
        vertical axis would in part take out.
    """

    def __init__(self, size: tuple[int, int], px: float, config: FollowConfig, both_axes: bool = True):
        self.size = size
        self.both_axes = both_axes
        self.px = px
        self.config = config
        self.origin_px = -np.asarray(CROP_EXTENT[:2], dtype=float) * px   # the face frame's origin, crop pixels
        #: (h, w) float32 grey reference crop, or None before an acquisition.
        self.ref: np.ndarray | None = None
        #: The reference crop blurred as the alignment compares it (:func:`.align.blur3`), (h, w) float32.
        self.template: np.ndarray | None = None
        #: Crop matrix (2, 3) where the alignment last put the face.
        self.followed: np.ndarray | None = None
        #: The last alignment's correlation of the aligned crop with the reference (ECC's criterion, in [-1, 1]),
        #: or None when it failed.
        self.correlation: float | None = None
        #: The share of the alignment's vertical axis in the face's size (:meth:`_height_share`), 0..1, and
        #: that size (image pixels per face unit), of the last alignment.
        self.height_share, self.unit = 0.0, 1.0

    def reset(self) -> None:
        """Forget the reference (the face is being acquired afresh)."""
        self.ref = self.template = None

    def start(self, rgb: np.ndarray, frame: FaceFrame) -> None:
        """Take the reference crop of ``frame`` in the RGB frame (H, W, 3) uint8."""
        self.followed = frame.crop_matrix(self.px)
        self.height_share, self.unit = 0.0, frame.unit
        self.ref = self.grey(rgb, self.followed)
        self.template = blur3(self.ref)

    def grey(self, rgb: np.ndarray, A: np.ndarray) -> np.ndarray:
        """The face crop of crop matrix ``A`` at ``config.scale`` resolution, grey, float32."""
        w, h = self.size
        f = self.config.scale
        small = cv2.warpAffine(rgb, A * f, (int(w * f), int(h * f)), flags=cv2.INTER_LINEAR,
                               borderMode=cv2.BORDER_REPLICATE)
        return cv2.cvtColor(small, cv2.COLOR_RGB2GRAY).astype(np.float32)

    def follow(self, rgb: np.ndarray, A: np.ndarray, units: tuple[float, float] | None = None) -> FaceFrame | None:
        """The face frame moved by aligning the face crop of crop matrix ``A`` on the reference (affine ECC),
        or None when the alignment fails or puts the face at a size (image pixels per face unit) outside
        ``units`` (low, high); then where the face was last aligned is kept (:meth:`aligned`)."""
        # First guess: the face where the alignment last put it (reference half-res crop -> current one).
        f = self.config.scale
        guess = then_affine(cv2.invertAffineTransform(self.followed), A)
        guess[:, 2] *= f
        self.correlation = None
        try:
            ok, cc, W = ecc_affine(self.template, self.grey(rgb, A), guess, self.config.iterations, ECC_EPS)
        except np.linalg.LinAlgError:
            # The crop's texture cannot fix every parameter of the affine (its gradients all along one direction:
            # a sleeve's edge filling it, a smooth shade across a covered lens): no alignment.
            return None
        if not ok:
            return None
        self.correlation = float(cc)
        W[:, 2] /= f
        G = then_affine(W, cv2.invertAffineTransform(A))      # crop pixels -> image pixels, where the face is now
        axes = _axes(G)
        share = self._height_share(axes)
        moved = self._frame_of(G, share, axes)
        if units is not None and not units[0] < moved.unit < units[1]:
            return None
        self.followed = cv2.invertAffineTransform(G)
        self.height_share, self.unit = share, moved.unit
        return moved

    def aligned(self) -> FaceFrame:
        """The face frame where the last successful alignment put the face (the reference's own frame before
        the first): the eyes' correction not applied."""
        G = cv2.invertAffineTransform(self.followed)
        return self._frame_of(G, self.height_share, _axes(G))

    def _height_share(self, axes: tuple[float, float]) -> float:
        """The share of the vertical axis of a crop-to-image matrix in the face's size, from its ``axes``' lengths
        ``(w, h)`` (:func:`_axes`): how much ``w`` changed from the size the last alignment gave the face, of how
        much both changed: ``dw / (dw + dh)``, ``dw = |log(w px / unit)|``, ``dh`` alike. A turn or a nod changes
        one axis of an affine fit of the frontal reference (a turned head stretches the horizontal one: the near
        half of the face, seen more frontally, widens and holds most of the texture; a nod shortens the
        vertical one), a move towards the camera both alike: the face's size is what the axis that changed
        least says."""
        if not self.both_axes:
            return 0.0
        dw = abs(np.log(axes[0] * self.px / self.unit))
        dh = abs(np.log(axes[1] * self.px / self.unit))
        return dw / (dw + dh) if dw + dh > 1e-12 else 0.0

    def _frame_of(self, G: np.ndarray, height_share: float, axes: tuple[float, float]) -> FaceFrame:
        """The face frame of the crop-to-image matrix ``G`` (2, 3) whose axes have the lengths ``axes`` = (w, h)
        (:func:`_axes`): its origin, the roll of its horizontal axis ``G[:, 0]``, and as its size (image pixels
        per face unit) the geometric mean of its axes' lengths weighted by ``height_share``
        (:meth:`_height_share`): ``w^(1 - share) h^share``."""
        width, height = axes
        size = width ** (1.0 - height_share) * height ** height_share
        return FaceFrame(G[:, :2] @ self.origin_px + G[:, 2], G[:, 0] * (size / width * self.px))


def _axes(G: np.ndarray) -> tuple[float, float]:
    """The lengths (w, h) of the horizontal and vertical axes ``G[:, 0]``, ``G[:, 1]`` of a (2, 3) matrix."""
    return float(np.hypot(G[0, 0], G[1, 0])), float(np.hypot(G[0, 1], G[1, 1]))
