"""The head's yaw and pitch for the built-in profile, measured on the frame: the nose's tip against the eyes.

The colour tracker's face frame is an in-plane similarity on the eye centres (its roll, size and place); a
trained profile reads the turn with its learnt model (:mod:`.head_turn`). Without one, the turn is measured on
the nose's tip, the point of the face that stands farthest in front of the eyes and moves least with the
expression (the lids, brows and lips move around it):

- **The tip's shift.** Seen along the line of sight under weak perspective, a point ``z`` proud of the eye centres
  moves ``z sin(yaw)`` sideways and ``z sin(pitch)`` up or down against them, while the eye distance ``D`` shrinks
  only as ``cos(yaw)``; so in face units (the eye distance) the tip moves ``k sin(angle)`` from its place in a frontal
  face, with ``k = z / D`` (:data:`NOSE_DEPTH` sideways, :data:`TIP_DEPTH` up and down). The tip and nostrils
  (:data:`TIP_REGION`) are resampled upright in the face frame (:data:`TIP_SAMPLES_PER_UNIT`; a face of many pixels to
  a sample is first halved by Gaussian pyramid levels) and their detail (the grey blurred over the finer of
  :data:`TIP_SIGMA` less its blur over the wider: the nostrils, the tip's highlight, the sides' edges, not the light's
  slope across the face) is found in each frame by normalised cross-correlation with a running reference, within
  :data:`TIP_SEARCH` of where it was last read sideways and of its place in the first frame measured up and down
  (never more than :data:`TIP_REACH` from that place). The place is then taken from the first frame's tip where that
  matches (:data:`MIN_FIRST_MATCH`) within :data:`TIP_REFINE` of it, to a fraction of a sample by a parabola through
  the best match and its neighbours along each axis, and only such a tip is blended into the running reference (at
  :data:`TIP_LEARN`: the nose's look changes as the head turns and nods, and the nostrils show and hide; the first tip
  anchors it). A match with the running reference under :data:`MIN_TIP_MATCH` (the tip hidden, the face frame off the
  face) gives no reading: the last angles are held, and after :data:`TIP_MISSES` such frames in a row the tip is taken
  afresh from the next frame.
- **The neutral.** The reference frame need not face the camera, noses and lights are not symmetric, where
  the eye centres are found on a face differs between people, and the camera may look from above or below:
  the neutral shift is, per axis, the running median of the shifts of the last :data:`NEUTRAL_FRAMES`
  measured frames (the performer faces the camera most of the time; nothing later is looked at). The angles
  are the turn from the performer's usual pose.

Conventions: face units (the eye-centre distance) from the eyes' midpoint, x right, y down in the upright face
frame; yaw and pitch in radians, positive as :meth:`~facepuppet.capture.pose.HeadPose.angles`' (the yaw: the
nose towards the head's +x, the performer's left, the image's right; the pitch: the nose down).
"""

from __future__ import annotations

import bisect
import math

import cv2
import numpy as np

__all__ = ["TIP_REGION", "TIP_SAMPLES_PER_UNIT", "TIP_SIGMA", "TIP_SEARCH", "TIP_REACH", "MIN_TIP_MATCH",
           "MIN_FIRST_MATCH", "TIP_REFINE", "TIP_LEARN", "TIP_MISSES", "NOSE_DEPTH", "TIP_DEPTH", "NEUTRAL_FRAMES",
           "MEASURE_EVERY", "LOOK_SHARE", "face_to_image", "tip_detail", "tip_window", "tip_shift", "NoseTurn"]

# Constants                      unit                what it is
TIP_REGION = (-0.12, 0.55, 0.12, 0.83)  # face units  (x0, y0, x1, y1): the nose's tip and nostrils
TIP_SAMPLES_PER_UNIT = 50.0      # samples / unit    grey samples of the tip's region per face unit
TIP_SIGMA = (0.01, 0.08)         # face units        Gaussian blurs of the tip's detail: the noise's, the light's
TIP_SEARCH = 0.3                 # face units        farthest the tip is sought from where it was last read
#                                                    (sideways) and from its place in the reference (up and down)
#: Face units: the farthest the tip is read from its place in the reference, each way. The tip moves
#: :data:`NOSE_DEPTH` sin(yaw) sideways, and the reference need not face the camera: sought only within
#: :data:`TIP_SEARCH` of the reference's place, a performer's face turned 30 degrees either way
#: (``benchmarks/eval_turned.py``; MediaPipe's yaw spread 13.6 degrees) had its tip held at the search's edge.
TIP_REACH = 0.5
MIN_TIP_MATCH = 0.7              # correlation       least match of the tip with the running reference for a reading
MIN_FIRST_MATCH = 0.5            # correlation       least match of the first frame's tip to place the tip and learn
TIP_REFINE = 0.05                # face units        farthest the first reference's match is sought from the
#                                                    running reference's
TIP_LEARN = 0.1                  # fraction          share of each matched tip blended into the running reference
TIP_MISSES = 10                  # frames            measured frames in a row without a reading after which the
#                                                    tip is taken afresh (references and neutrals)
#: Face units the nose's tip moves sideways against the eye centres per unit of sin(yaw): its depth in front
#: of the eye centres over their distance, at the scale at which the landmark backend's head pose (a PnP on
#: the generic face) reads the same turn (measured 0.7-0.95 on the shared clips).
NOSE_DEPTH = 0.9
#: Face units the nose's tip moves down against the eye centres per unit of sin(pitch), at the same scale
#: (measured 0.6-1.2 on the shared clips).
TIP_DEPTH = 1.0
NEUTRAL_FRAMES = 300             # frames            measured frames of the neutral shift's running medians
#                                                    (30 s at 30 /s, measured on every third)
MEASURE_EVERY = 3                # frames            the nose is measured on every this many frames (the last
#                                                    reading held between: the angles are filtered after)
#: Share (yaw, pitch) of the direction of the line of sight through the head (:func:`~.head_turn.ray_angles`)
#: added to the turn measured against it (:func:`~.head_turn.turn_angles`): for the yaw the trained model's
#: middle share (how much a head's place goes with its turn depends on how the performer moves); none for the
#: pitch (a camera above or below the face is in the neutral already: the shared clips' pitch errors grew
#: with half of it).
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


def tip_detail(rgb: np.ndarray, M: np.ndarray) -> np.ndarray:
    """The detail (float32, rows down the face, :data:`TIP_SAMPLES_PER_UNIT` per face unit) of
    :data:`TIP_REGION` grown by :data:`TIP_REACH` on every side, of the frame ``rgb`` (H, W, 3) uint8 in the
    face frame ``M`` (face units -> image pixels; samples half a step in from the region's edges, the frame's
    edge pixels repeated beyond it)."""
    s, n = TIP_REACH, TIP_SAMPLES_PER_UNIT
    x0, y0, x1, y1 = TIP_REGION[0] - s, TIP_REGION[1] - s, TIP_REGION[2] + s, TIP_REGION[3] + s
    step = 1.0 / n
    size = (int(round((x1 - x0) * n)), int(round((y1 - y0) * n)))
    Q = np.array([[step, 0.0, x0 + 0.5 * step], [0.0, step, y0 + 0.5 * step], [0.0, 0.0, 1.0]])
    W = (np.vstack([np.asarray(M, dtype=float), [0.0, 0.0, 1.0]]) @ Q)[:2]
    spacing = float(np.sqrt(abs(np.linalg.det(W[:, :2]))))          # image pixels between two samples
    g = None
    if spacing > 2.0 and np.isfinite(W).all():
        # A face many pixels to a sample: its rectangle of the frame, in grey, halved by levels of a Gaussian
        # pyramid until a sample spans at most 2 pixels, so that the samples do not alias the skin's and the
        # nostrils' fine detail (each level's 5-tap blur is the anti-aliasing).
        corners = W @ np.array([[0.0, size[0], 0.0, size[0]], [0.0, 0.0, size[1], size[1]], [1.0, 1.0, 1.0, 1.0]])
        pad = int(np.ceil(1.5 * spacing)) + 1
        h, w = rgb.shape[:2]
        c0, r0 = max(int(corners[0].min()) - pad, 0), max(int(corners[1].min()) - pad, 0)
        c1, r1 = min(int(corners[0].max()) + pad + 1, w), min(int(corners[1].max()) + pad + 1, h)
        if c1 - c0 > 1 and r1 - r0 > 1:
            part = cv2.cvtColor(rgb[r0:r1, c0:c1], cv2.COLOR_RGB2GRAY)
            W = W.copy()
            W[:, 2] -= (c0, r0)
            while spacing > 2.0 and min(part.shape) > 8:
                part = cv2.pyrDown(part)                # pixel x of the half is pixel 2x of the whole
                W *= 0.5
                spacing *= 0.5
            if spacing > 2.0:                           # a sliver at the frame's edge: blurred instead
                part = cv2.GaussianBlur(part, (0, 0), 0.5 * spacing)
            g = cv2.warpAffine(part, W, size, flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                               borderMode=cv2.BORDER_REPLICATE)
    if g is None:
        g = cv2.cvtColor(cv2.warpAffine(rgb, W, size, flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                        borderMode=cv2.BORDER_REPLICATE), cv2.COLOR_RGB2GRAY)
    g = g.astype(np.float32)
    return cv2.GaussianBlur(g, (0, 0), TIP_SIGMA[0] * n) - cv2.GaussianBlur(g, (0, 0), TIP_SIGMA[1] * n)


def tip_window() -> tuple[int, int, int, int]:
    """The samples (x0, y0, x1, y1) of :data:`TIP_REGION` in :func:`tip_detail`'s array, at no shift."""
    n, s = TIP_SAMPLES_PER_UNIT, TIP_REACH
    x0, y0, x1, y1 = TIP_REGION
    a = int(round(s * n))
    return a, a, a + int(round((x1 - x0) * n)), a + int(round((y1 - y0) * n))


def _peak_offset(lo: float, mid: float, hi: float) -> float:
    """Sub-sample place (-0.5 .. 0.5) of a peak of value ``mid`` between its neighbours' ``lo`` and ``hi``
    (the vertex of the parabola through the three)."""
    curv = lo - 2.0 * mid + hi
    return min(max(0.5 * (lo - hi) / curv, -0.5), 0.5) if curv < 0 else 0.0


def _spread(a: np.ndarray) -> float:
    """Standard deviation of the float32 array ``a`` (OpenCV's: a fraction of numpy's cost on small arrays)."""
    return float(cv2.meanStdDev(a)[1][0, 0])


def tip_shift(detail: np.ndarray, reference: np.ndarray, near: tuple[float, float] | None = None,
              reach: float = TIP_SEARCH) -> tuple[float, float, float]:
    """Where the ``reference`` tip (the :func:`tip_window` of an earlier :func:`tip_detail`) lies in this
    frame's ``detail``: its shift (dx, dy) face units from the reference's place, and the match there
    (normalised correlation, -1..1), the best within ``reach`` face units of the shift ``near`` (default no
    shift; the places searched end :data:`TIP_REACH` from it); (0, 0, 0) where either has no detail."""
    if not (_spread(detail) > 1e-6 and _spread(reference) > 1e-6):
        return 0.0, 0.0, 0.0
    n = TIP_SAMPLES_PER_UNIT
    a, b, _, _ = tip_window()
    th, tw = reference.shape
    h, w = detail.shape[0] - th + 1, detail.shape[1] - tw + 1          # the places the tip may lie at
    cx, cy = (a, b) if near is None else (a + near[0] * n, b + near[1] * n)
    r = reach * n
    # the places within reach (kx0..kx1, ky0..ky1), and one more on each side, where there is one, for the
    # parabolas
    kx0, kx1 = max(int(np.ceil(cx - r)), 0), min(int(np.floor(cx + r)), w - 1)
    ky0, ky1 = max(int(np.ceil(cy - r)), 0), min(int(np.floor(cy + r)), h - 1)
    if kx1 < kx0 or ky1 < ky0:
        return 0.0, 0.0, 0.0
    x0, x1, y0, y1 = max(kx0 - 1, 0), min(kx1 + 1, w - 1), max(ky0 - 1, 0), min(ky1 + 1, h - 1)
    score = cv2.matchTemplate(detail[y0:y1 + th, x0:x1 + tw], reference, cv2.TM_CCOEFF_NORMED)
    _, best, _, (x, y) = cv2.minMaxLoc(score[ky0 - y0:ky1 - y0 + 1, kx0 - x0:kx1 - x0 + 1])
    x, y = x + kx0 - x0, y + ky0 - y0
    sh, sw = score.shape
    fx = _peak_offset(score[y, x - 1], best, score[y, x + 1]) if 0 < x < sw - 1 else 0.0
    fy = _peak_offset(score[y - 1, x], best, score[y + 1, x]) if 0 < y < sh - 1 else 0.0
    return float(x + x0 + fx - a) / n, float(y + y0 + fy - b) / n, float(best)


class _RunningMedian:
    """The median of the last ``n`` values added: a ring of them, and the same values kept in order."""

    def __init__(self, n: int):
        self._ring = np.zeros(int(n))
        self._sorted: list[float] = []
        self._count = 0

    def reset(self) -> None:
        self._sorted, self._count = [], 0

    def add(self, x: float) -> float:
        """Add ``x`` (the oldest value leaves a full window); the median of the window after it."""
        n, ring = len(self._ring), self._sorted
        if self._count >= n:
            del ring[bisect.bisect_left(ring, float(self._ring[self._count % n]))]
        self._ring[self._count % n] = x
        bisect.insort(ring, x)
        self._count += 1
        m = len(ring)
        return ring[m // 2] if m % 2 else 0.5 * (ring[m // 2 - 1] + ring[m // 2])


class NoseTurn:
    """The yaw and pitch (radians) of successive frames of one take (the module notes); the tip's references
    and the running neutrals are the state.

    Parameters
    ----------
    frames : int
        Measured frames the neutrals' running medians span.
    every : int
        The nose is measured on every ``every``-th call, starting with the first.
    """

    def __init__(self, frames: int = NEUTRAL_FRAMES, every: int = MEASURE_EVERY):
        self._every, self._calls = max(int(every), 1), 0
        self._neutral = (_RunningMedian(frames), _RunningMedian(frames))   # the tip's dx and dy
        self._first: np.ndarray | None = None                               # the first frame's tip
        self._running: np.ndarray | None = None                             # the running reference
        self._last = np.zeros(2)                                            # (yaw, pitch) last read, radians
        self._dx: float | None = None                                       # the tip's sideways shift last read
        self._misses = 0                                                    # measured frames in a row unread

    def _forget(self) -> None:
        """Forget the tip's references and the neutrals (the tip is taken afresh from the next frame)."""
        for m in self._neutral:
            m.reset()
        self._first = self._running = self._dx = None
        self._misses = 0

    def unfollow(self) -> None:
        """Seek the next tip about the reference's place again, not sideways from where it was last read (the face
        is being found anew: its frame may have jumped)."""
        self._dx = None

    @property
    def due(self) -> bool:
        """Whether the next call measures the nose (else it returns the last reading without looking)."""
        return self._calls % self._every == 0

    def skip(self) -> np.ndarray:
        """A call that does not measure (:attr:`due` False): counts it and returns the last (yaw, pitch) (2,)
        radians."""
        self._calls += 1
        return self._last.copy()

    def __call__(self, rgb: np.ndarray, M: np.ndarray) -> np.ndarray:
        """The (yaw, pitch) (2,) radians of the frame ``rgb`` (H, W, 3) uint8 whose face frame is ``M`` (face
        units -> image pixels, :func:`face_to_image`): the last ones read (at first zero) when the call is not
        one that measures, no tip with detail has been seen yet (the first reference is the first frame's
        tip region that has any), or the tip matches the running reference less than :data:`MIN_TIP_MATCH`
        (after :data:`TIP_MISSES` such frames in a row the tip is taken afresh)."""
        if not self.due:
            return self.skip()
        self._calls += 1
        detail = tip_detail(rgb, M)
        x0, y0, x1, y1 = tip_window()
        if self._first is None:
            if not _spread(detail[y0:y1, x0:x1]) > 1e-6:
                return self._last.copy()
            self._first = np.ascontiguousarray(detail[y0:y1, x0:x1])
            self._running = self._first.copy()
        # sought within TIP_SEARCH sideways of where it was last read (a turn goes far), up and down of the
        # reference's place
        dx, dy, match = tip_shift(detail, self._running, None if self._dx is None else (self._dx, 0.0))
        if match < MIN_TIP_MATCH:
            self._misses += 1
            if self._misses >= TIP_MISSES:
                self._forget()
            return self._last.copy()
        self._misses = 0
        fx, fy, first = tip_shift(detail, self._first, (dx, dy), TIP_REFINE)
        if first >= MIN_FIRST_MATCH:
            # placed by the first frame's tip, and only then learnt from: the running reference follows the
            # tip's look, never a place the first tip does not match
            dx, dy = fx, fy
            n = TIP_SAMPLES_PER_UNIT
            i, j = int(round(dx * n)), int(round(dy * n))
            seen = detail[y0 + j:y1 + j, x0 + i:x1 + i]
            if seen.shape == self._running.shape:
                self._running += TIP_LEARN * (seen - self._running)
        self._dx = dx
        for k, (d, depth) in enumerate(((dx, NOSE_DEPTH), (dy, TIP_DEPTH))):
            neutral = self._neutral[k].add(d)
            self._last[k] = math.asin(min(max((d - neutral) / depth, -1.0), 1.0))
        return self._last.copy()
