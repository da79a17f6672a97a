"""The head's yaw for the built-in profile, measured on the frame: the nose's axis of mirror symmetry against the eyes.

The colour tracker's face frame is an in-plane similarity on the eye centres (its roll, size and place); a
trained profile reads the turn with its learnt model (:mod:`.head_turn`). Without one, the yaw is measured:

- **The nose's axis.** The nose is a mirror-symmetric ridge standing in front of the eyes. Seen along the line
  of sight under weak perspective, a point ``z`` cm proud of the eye centres moves ``z sin(yaw)`` sideways
  against them while the eye distance ``D`` shrinks only as ``cos(yaw)``; so in face units (the eye distance)
  the nose's axis of symmetry lies ``k sin(yaw)`` from the eyes' midpoint, with ``k = z / D``
  (:data:`NOSE_DEPTH`). The axis is found in :data:`NOSE_REGION` of the frame (resampled upright in the face
  frame, :data:`SAMPLES_PER_UNIT`) as the vertical line about which the region's detail matches its own mirror
  image best (normalised correlation over :data:`MIRROR_HALF` either side, sub-sample by a parabola through
  the best three), within :data:`SEARCH` of the midpoint. Where the match has a second peak nearly as high
  (within :data:`PEAK_MARGIN`; under a turn, the line between the nose's far side and the cheek can mirror as
  well as the nose), the frame gives no reading: the last one is held. The detail is the grey lightly blurred
  less its blur over the wider of :data:`DETAIL_SIGMA`: the nostrils, the tip's highlight, the sides' edges,
  not the light's slope across the face.
- **The neutral.** The light and the nose are not quite symmetric, and where the eye centres are found on a
  face differs between people: the neutral axis is the running median of the axes of the last
  :data:`NEUTRAL_FRAMES` measured frames (the performer faces the camera most of the time; nothing later is
  looked at).

Pitch is not measured here (the nose's vertical place against the eyes moves with the lids, brows and upper
lip as much as with a nod): it stays zero.

Conventions: face units (the eye-centre distance) from the eyes' midpoint, x right, y down in the upright face
frame; yaw in radians, positive as :meth:`~facepuppet.capture.pose.HeadPose.angles`' (the nose towards the
head's +x, the performer's left: the image's right).
"""

from __future__ import annotations

import bisect
import math

import cv2
import numba as nb
import numpy as np

from facepuppet._util.jit import KERNEL

__all__ = ["NOSE_REGION", "SAMPLES_PER_UNIT", "DETAIL_SIGMA", "MIRROR_HALF", "SEARCH", "NOSE_DEPTH",
           "NEUTRAL_FRAMES", "PEAK_MARGIN", "PEAK_APART", "MEASURE_EVERY", "MIN_MATCH", "LOOK_SHARE", "nose_axis",
           "mirror_scores", "face_to_image", "NoseTurn"]

# Constants                      unit                what it is
NOSE_REGION = (-0.6, 0.35, 0.6, 0.88)  # face units  (x0, y0, x1, y1): the nose from its middle to its base
SAMPLES_PER_UNIT = 50.0          # samples / unit    grey samples of the region per face unit
DETAIL_SIGMA = (0.015, 0.08)     # face units        Gaussian blurs: the noise's, and the light's slope's
MIRROR_HALF = 0.3                # face units        width compared either side of a candidate axis
SEARCH = 0.2                     # face units        largest distance of the axis from the eyes' midpoint
PEAK_MARGIN = 0.1                # correlation       least lead of the best peak of the match over any other
PEAK_APART = 0.05                # face units        ... of those this far from it or farther
#: Face units the nose's axis moves against the eye centres per unit of sin(yaw): the depth of the nose in
#: front of the eye centres over their distance, at the scale the head pose of the landmark backend (a PnP on
#: the generic face) gives the same turn.
NOSE_DEPTH = 0.9
NEUTRAL_FRAMES = 300             # frames            the running median of the neutral axis (10 s at 30 /s)
MEASURE_EVERY = 3               # frames            the nose is measured on every this many frames (the last
#                                                    reading held between: the yaw is filtered after)
MIN_MATCH = 0.2                  # correlation       least mirror match of the best axis for a reading
#: Share (yaw, pitch) of the direction of the line of sight through the head (:func:`~.head_turn.ray_angles`)
#: added to the yaw measured against it (:func:`~.head_turn.turn_angles`): the trained model's middle share
#: for the yaw (how much a head's place goes with its turn depends on how the performer moves); none for the
#: pitch, which is not measured.
LOOK_SHARE = (0.5, 0.0)


def face_to_image(A: np.ndarray, S_px: np.ndarray, px: float, origin: tuple[float, float]) -> np.ndarray:
    """(2, 3) affine from face units (the placed layout's: eyes' midpoint at 0) to image pixels.

    Parameters
    ----------
    A : (2, 3)
        The crop matrix (image pixels -> crop pixels).
    S_px : (2, 3)
        The placement of the layout on the crop (crop pixels of the unmoved crop -> crop pixels).
    px : float
        Crop pixels per face unit of the unmoved crop.
    origin : (2,)
        Face units of the crop's top left corner (``CROP_EXTENT[:2]``).
    """
    S_px = np.asarray(S_px, dtype=float)
    L = S_px[:, :2] * px                                          # face units -> crop pixels
    t = S_px[:, 2] - L @ np.asarray(origin, dtype=float)
    Ainv = cv2.invertAffineTransform(np.asarray(A, dtype=float))  # crop pixels -> image pixels
    return np.hstack([Ainv[:, :2] @ L, (Ainv[:, :2] @ t + Ainv[:, 2])[:, None]])


def nose_axis(rgb: np.ndarray, M: np.ndarray) -> tuple[float, float, float] | None:
    """The nose's axis of mirror symmetry in :data:`NOSE_REGION` (the module notes).

    Parameters
    ----------
    rgb : (H, W, 3) uint8
        The frame.
    M : (2, 3)
        Face units -> image pixels (:func:`face_to_image`).

    Returns
    -------
    (float, float, float) or None
        The axis's x, face units from the eyes' midpoint; its mirror match (normalised correlation); and the
        match's lead over that of the best other peak (local maximum, the search's ends included) at least
        :data:`PEAK_APART` away (infinite when there is none). None when the region has no detail.
    """
    x0, y0, x1, y1 = NOSE_REGION
    n = SAMPLES_PER_UNIT
    step = 1.0 / n
    size = (int(round((x1 - x0) * n)), int(round((y1 - y0) * n)))
    Q = np.array([[step, 0.0, x0 + 0.5 * step], [0.0, step, y0 + 0.5 * step], [0.0, 0.0, 1.0]])
    W = (np.vstack([np.asarray(M, dtype=float), [0.0, 0.0, 1.0]]) @ Q)[:2]
    g = cv2.cvtColor(cv2.warpAffine(rgb, W, size, flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                    borderMode=cv2.BORDER_REPLICATE), cv2.COLOR_RGB2GRAY).astype(np.float32)
    fine, coarse = (s * n for s in DETAIL_SIGMA)
    # the light's slope: the blur over `coarse` samples, taken on a copy a quarter the size (the same to a
    # fraction of a grey level, at a sixteenth of the work)
    small = cv2.resize(g, (max(size[0] // 4, 1), max(size[1] // 4, 1)), interpolation=cv2.INTER_AREA)
    slope = cv2.resize(cv2.GaussianBlur(small, (0, 0), coarse / 4.0), size, interpolation=cv2.INTER_LINEAR)
    detail = cv2.GaussianBlur(g, (0, 0), fine) - slope
    half = int(round(MIRROR_HALF * n))
    centre = int(round(-x0 * n - 0.5))                            # the sample column at x = 0
    reach = int(round(SEARCH * n))
    cs = np.arange(max(centre - reach, half), min(centre + reach, size[0] - half - 1) + 1)
    score = mirror_scores(detail, cs, half)
    if score.size == 0:
        return None
    j = int(np.argmax(score))
    left, right = np.r_[-np.inf, score[:-1]], np.r_[score[1:], -np.inf]
    others = (score >= left) & (score >= right) & (np.abs(cs - cs[j]) >= PEAK_APART * n)
    lead = float(score[j] - score[others].max()) if others.any() else np.inf
    off = 0.0
    if 0 < j < len(score) - 1:
        curv = score[j - 1] - 2.0 * score[j] + score[j + 1]
        if curv < 0:
            off = 0.5 * float(score[j - 1] - score[j + 1]) / float(curv)
    return x0 + (float(cs[j]) + off + 0.5) / n, float(score[j]), lead


@nb.njit(**KERNEL)
def mirror_scores(detail: np.ndarray, cs: np.ndarray, half: int) -> np.ndarray:
    """Normalised correlation of the ``half`` columns left of each candidate column ``cs[k]``, mirrored, with the
    ``half`` right of it, over all rows of ``detail`` (R, W) float32; an empty array when a side has no
    variance at some candidate (``half <= cs[k] < W - half`` for each k)."""
    rows = detail.shape[0]
    count = half * rows
    out = np.empty(len(cs))
    for k in range(len(cs)):
        c = cs[k]
        cross = sl = sr = ql = qr = 0.0
        for r in range(rows):
            for u in range(1, half + 1):
                a = np.float64(detail[r, c - u])
                b = np.float64(detail[r, c + u])
                cross += a * b
                sl += a
                sr += b
                ql += a * a
                qr += b * b
        var_l = ql - sl * sl / count
        var_r = qr - sr * sr / count
        if not (var_l > 0.0 and var_r > 0.0):
            return np.empty(0)
        out[k] = (cross - sl * sr / count) / np.sqrt(var_l * var_r)
    return out


class NoseTurn:
    """The yaw (radians) of successive frames of one take (the module notes); the running neutral is the state.

    Parameters
    ----------
    frames : int
        Measured frames the neutral's running median spans.
    every : int
        The nose is measured on every ``every``-th call, starting with the first.
    """

    def __init__(self, frames: int = NEUTRAL_FRAMES, every: int = MEASURE_EVERY):
        self._every, self._calls = max(int(every), 1), 0
        self._seen = np.zeros(int(frames))        # ring buffer of the last axes
        self._sorted: list[float] = []            # the same axes in ascending order (the median's)
        self._count = 0
        self._last = 0.0                          # the last yaw read, radians

    def reset(self) -> None:
        """Forget the neutral and the last reading (a new take, or a new face)."""
        self._count, self._last, self._sorted, self._calls = 0, 0.0, [], 0

    @property
    def due(self) -> bool:
        """Whether the next call measures the nose (else it returns the last reading without looking)."""
        return self._calls % self._every == 0

    def skip(self) -> float:
        """A call that does not measure (:attr:`due` False): counts it and returns the last reading, radians."""
        self._calls += 1
        return self._last

    def __call__(self, rgb: np.ndarray, M: np.ndarray) -> float:
        """The yaw (radians) of the frame ``rgb`` (H, W, 3) uint8 whose face frame is ``M`` (face units -> image
        pixels, :func:`face_to_image`); the last one read (at first zero) when the nose's axis is not found
        (no detail, a mirror match under :data:`MIN_MATCH` or a second peak within :data:`PEAK_MARGIN` of it)
        or the call is not one that measures."""
        if not self.due:
            return self.skip()
        self._calls += 1
        found = nose_axis(rgb, M)
        if found is None or found[1] < MIN_MATCH or found[2] < PEAK_MARGIN:
            return self._last
        x = found[0]
        n, ring = len(self._seen), self._sorted
        if self._count >= n:                      # the oldest axis leaves the window
            del ring[bisect.bisect_left(ring, float(self._seen[self._count % n]))]
        self._seen[self._count % n] = x
        bisect.insort(ring, x)
        self._count += 1
        m = len(ring)
        neutral = ring[m // 2] if m % 2 else 0.5 * (ring[m // 2 - 1] + ring[m // 2])
        self._last = math.asin(min(max((x - neutral) / NOSE_DEPTH, -1.0), 1.0))
        return self._last
