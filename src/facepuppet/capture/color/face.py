"""Face localisation and the face frame (paper §3.2): skin model, face box, anthropometric rectangles.

Conventions: image pixels, x right, y down, RGB order. The *face frame* is a similarity of the image: its
origin is midway between the two eye centres (each the midpoint of the eye's corners), its unit is the
distance between the eye centres, its x axis runs from the performer's right eye to the left eye (image
right for an unmirrored camera) and its y axis points down the face. Work happens in a small upright crop of
the face frame (:class:`FaceFrame`), so the feature rectangles follow the head's translation, scale and roll.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np

__all__ = [
    "SkinModel",
    "FaceFrame",
    "SKIN_Y_MIN",
    "SKIN_Y_MAX",
    "FEATURE_BOXES",
    "CROP_EXTENT",
    "skin_probability",
    "find_face",
    "light_balance",
    "similarity_from_points",
    "similarity_of_pairs",
    "scaled_about",
    "same_frame",
    "then_affine",
    "box_in_crop",
    "turned_and_shifted",
    "far_correction",
    "FAR_TURN",
]

# Tuning constants of the skin search (find_face)
#                              unit            what it does
SKIN_Y_MIN = 35                # 8-bit luma      darker pixels have unreliable chroma: never skin
SKIN_Y_MAX = 250               # 8-bit luma      brighter pixels have unreliable chroma: never skin
SKIN_OPEN = 2                  # pixels          side of the opening that clears specks off the skin mask
FACE_ASPECT = 1.5              # ratio           tallest skin region kept, times its width (neck and shoulders)
REGION_PER_EYE_DISTANCE = 2.3  # ratio           skin region's width per eye-centre distance (no eye holes)
EYE_ROW = 0.33                 # fraction        of the region's height where the eyes lie (no eye holes)
EYE_HOLE_MIN_AREA = 2          # pixels          smallest hole that may be an eye
EYE_HOLE_TOP = 0.6             # fraction        of the region's height above which the eye holes lie
EYE_SPAN = (0.25, 0.65)        # fraction        of the region's width two eye holes lie apart
EYE_TILT = 0.35                # ratio           most vertical offset of two eye holes, of their distance
HOLE_SIZE_WEIGHT = 0.3         # score per log   penalty on two holes' size ratio
HOLE_LOW_WEIGHT = 0.5          # score           bonus of lower pairs (brows lie above the eyes)

# Tuning constants of the eye correction (far_correction)
FAR_TURN = np.radians(12.0)    # radians         largest turn of the eyes against the aligned face

#: Extent of the face crop in face units: x0, y0, x1, y1 (brows above, chin below).
CROP_EXTENT = (-1.3, -0.85, 1.3, 1.95)

#: Feature rectangles in face units (x0, y0, x1, y1), placed from average adult proportions; the performer's
#: own layout (profile) shifts them. Left and right are the performer's own.
FEATURE_BOXES: dict[str, tuple[float, float, float, float]] = {
    "brow_left": (0.10, -0.62, 1.05, -0.20),
    "brow_right": (-1.05, -0.62, -0.10, -0.20),
    "eye_left": (0.16, -0.26, 0.88, 0.24),
    "eye_right": (-0.88, -0.26, -0.16, 0.24),
    "nose": (-0.42, 0.50, 0.42, 0.98),
    "mouth": (-0.72, 0.78, 0.72, 1.95),
    "cheek_left": (0.40, 0.45, 0.75, 0.75),
    "cheek_right": (-0.75, 0.45, -0.40, 0.75),
}


@dataclass(frozen=True)
class SkinModel:
    """A Gaussian skin-colour model in the (Cr, Cb) plane of YCrCb (8-bit codes).

    Attributes
    ----------
    mean : (2,) float
        Mean (Cr, Cb) of skin.
    cov : (2, 2) float
        Covariance of (Cr, Cb) of skin.
    threshold : float
        Squared Mahalanobis distance below which a pixel counts as skin.
    """

    mean: tuple[float, float] = (155.0, 110.0)
    cov: tuple[tuple[float, float], tuple[float, float]] = ((70.0, -25.0), (-25.0, 60.0))
    threshold: float = 6.0

    def table(self) -> np.ndarray:
        """Skin membership over all (Cr, Cb) codes, (256, 256) uint8 (255 = skin); cached per model."""
        key = (self.mean, self.cov, self.threshold)
        tab = _SKIN_TABLES.get(key)
        if tab is None:
            cr, cb = np.mgrid[0:256, 0:256].astype(np.float64)
            d = np.stack([cr - self.mean[0], cb - self.mean[1]], -1)
            inv = np.linalg.inv(np.asarray(self.cov, dtype=float))
            m = np.einsum("...i,ij,...j->...", d, inv, d)
            tab = np.where(m < self.threshold, 255, 0).astype(np.uint8)
            _SKIN_TABLES[key] = tab
        return tab


_SKIN_TABLES: dict = {}


def skin_probability(rgb: np.ndarray, model: SkinModel = SkinModel()) -> np.ndarray:
    """Skin mask of an RGB image, (H, W) uint8 (255 = skin-coloured)."""
    ycc = cv2.cvtColor(rgb, cv2.COLOR_RGB2YCrCb)
    mask = model.table()[ycc[..., 1], ycc[..., 2]]
    # Very dark or very bright pixels have unreliable chroma.
    mask[(ycc[..., 0] < SKIN_Y_MIN) | (ycc[..., 0] > SKIN_Y_MAX)] = 0
    return mask


def light_balance(rgb: np.ndarray, work_width: int = 128) -> np.ndarray:
    """The colour transform that evens out an image's light: channels scaled to a common mean (grey world),
    then the 1st-99th percentile range stretched to 0-255; measured on a ``work_width``-wide thumbnail.

    Parameters
    ----------
    rgb : (H, W, 3) uint8

    Returns
    -------
    (3, 4) float
        For ``cv2.transform``: out = M[:, :3] @ rgb + M[:, 3].
    """
    h, w = rgb.shape[:2]
    f = min(1.0, work_width / float(w))
    small = cv2.resize(rgb, (max(1, round(w * f)), max(1, round(h * f))), interpolation=cv2.INTER_AREA)
    means = small.reshape(-1, 3).astype(float).mean(axis=0)
    gains = means.mean() / np.maximum(means, 1.0)
    lo, hi = np.percentile(small.reshape(-1, 3) * gains, (1.0, 99.0))
    scale = 255.0 / max(hi - lo, 1.0)
    return np.column_stack([np.diag(gains * scale), np.full(3, -lo * scale)])


def find_face(rgb: np.ndarray, model: SkinModel = SkinModel(), *, work_width: int = 96,
              roi: tuple[int, int, int, int] | None = None, min_fraction: float = 0.01) -> FaceFrame | None:
    """Find the face: the largest skin region, its eye holes, and from them a first face frame.

    The frame is shrunk to about ``work_width`` pixels wide; the skin mask is closed, its largest connected
    region taken, and its holes (non-skin pixels enclosed by skin: eyes, brows, mouth) examined. The pair
    of holes most like two eyes (side by side, in the upper part of the region, a plausible distance apart)
    gives the face frame; failing that, the region's box and average proportions do.

    Parameters
    ----------
    rgb : (H, W, 3) uint8
    model : SkinModel
    work_width : int
        Width of the shrunk image the search runs on.
    roi : (x0, y0, x1, y1), optional
        Search only this part of the image (pixels).
    min_fraction : float
        Smallest skin region accepted, as a fraction of the searched area.

    Returns
    -------
    FaceFrame or None
        None when no skin region is large enough.
    """
    h, w = rgb.shape[:2]
    x0, y0, x1, y1 = (0, 0, w, h) if roi is None else (max(0, int(roi[0])), max(0, int(roi[1])),
                                                       min(w, int(roi[2])), min(h, int(roi[3])))
    if x1 - x0 < 8 or y1 - y0 < 8:
        return None
    sub = rgb[y0:y1, x0:x1]
    f = min(1.0, work_width / float(x1 - x0))
    small = cv2.resize(sub, (max(8, round((x1 - x0) * f)), max(8, round((y1 - y0) * f))),
                       interpolation=cv2.INTER_AREA)
    mask = skin_probability(small, model)
    mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, np.ones((SKIN_OPEN, SKIN_OPEN), np.uint8))
    n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    if n < 2:
        return None
    k = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    if stats[k, cv2.CC_STAT_AREA] < min_fraction * mask.size:
        return None
    bx, by, bw, bh = (int(v) for v in stats[k, :4])
    region = (labels == k).astype(np.uint8)
    # Limit the region to a face-shaped box: the neck and shoulders may join it below.
    bh = min(bh, int(round(FACE_ASPECT * bw)))
    eyes = _eye_holes(region, bx, by, bw, bh)
    if eyes is None:
        iod = bw / REGION_PER_EYE_DISTANCE
        centre = np.array([bx + bw / 2.0, by + EYE_ROW * bh])
        right, left = centre - [iod / 2, 0], centre + [iod / 2, 0]
    else:
        right, left = eyes
    scale = 1.0 / f
    off = np.array([x0, y0], dtype=float)
    return FaceFrame.from_eyes(np.asarray(right) * scale + off, np.asarray(left) * scale + off)


def _eye_holes(region: np.ndarray, bx: int, by: int, bw: int, bh: int):
    """Centres of the two eye holes of a skin region (small-image pixels), or None."""
    box = np.zeros((bh + 2, bw + 2), np.uint8)
    box[1:-1, 1:-1] = region[by:by + bh, bx:bx + bw]
    filled = box.copy()
    ff = np.zeros((bh + 4, bw + 4), np.uint8)
    cv2.floodFill(filled, ff, (0, 0), 1)
    holes = (filled == 0).astype(np.uint8)
    n, _, stats, cents = cv2.connectedComponentsWithStats(holes, connectivity=8)
    if n < 3:
        return None
    cand = [(cents[i] + [bx - 1, by - 1], stats[i, cv2.CC_STAT_AREA]) for i in range(1, n)
            if stats[i, cv2.CC_STAT_AREA] >= EYE_HOLE_MIN_AREA and cents[i][1] < EYE_HOLE_TOP * bh]
    best, best_score = None, -np.inf
    for i in range(len(cand)):
        for j in range(i + 1, len(cand)):
            (a, sa), (b, sb) = cand[i], cand[j]
            d = b - a
            dist = abs(d[0])
            if not (EYE_SPAN[0] * bw <= dist <= EYE_SPAN[1] * bw) or abs(d[1]) > EYE_TILT * dist:
                continue
            mid = (a + b) / 2.0
            # Side by side, centred, similar size; lower pairs are eyes (brows lie above them).
            score = (-abs(mid[0] - (bx + bw / 2.0)) / bw - abs(d[1]) / dist - abs(np.log(sa / sb)) * HOLE_SIZE_WEIGHT
                     + HOLE_LOW_WEIGHT * (mid[1] - by) / bh)
            if score > best_score:
                best, best_score = (a, b) if a[0] < b[0] else (b, a), score
    return best


def similarity_from_points(src: np.ndarray, dst: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """Least-squares similarity (rotation, uniform scale, translation) taking ``src`` onto ``dst``.

    Parameters
    ----------
    src, dst : (N, 2) float, N >= 2
    weights : (N,) float, optional

    Returns
    -------
    (2, 3) float
        ``dst ≈ A[:, :2] @ src + A[:, 2]``.
    """
    src = np.asarray(src, dtype=float)
    dst = np.asarray(dst, dtype=float)
    w = np.ones(len(src)) if weights is None else np.asarray(weights, dtype=float)
    w = w / w.sum()
    ms, md = w @ src, w @ dst
    a, b = src - ms, dst - md
    # z = (p + iq) with dst ≈ z * src in complex form.
    num_re = w @ (a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1])
    num_im = w @ (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    den = max(w @ (a * a).sum(1), 1e-12)
    p, q = num_re / den, num_im / den
    R = np.array([[p, -q], [q, p]])
    return np.column_stack([R, md - R @ ms])


@dataclass(frozen=True)
class FaceFrame:
    """The face frame in one image: where the eye centres are, hence the face's position, size and roll.

    Attributes
    ----------
    origin : (2,) float
        Midpoint of the eye centres, image pixels.
    axis : (2,) float
        Vector from the right eye centre to the left eye centre (image pixels): its length is the face
        unit, its direction the face's roll.
    """

    origin: np.ndarray
    axis: np.ndarray

    @classmethod
    def from_eyes(cls, right: np.ndarray, left: np.ndarray) -> FaceFrame:
        right, left = np.asarray(right, dtype=float), np.asarray(left, dtype=float)
        return cls((right + left) / 2.0, left - right)

    @cached_property
    def unit(self) -> float:
        """Face unit (distance between the eye centres) in pixels; worked out at the first reading and kept (a
        frame's arrays are not changed in place)."""
        return float(np.hypot(self.axis[0], self.axis[1]))

    @property
    def roll(self) -> float:
        """Roll angle in radians (positive: the left eye lower in the image)."""
        return float(np.arctan2(self.axis[1], self.axis[0]))

    def to_image(self) -> np.ndarray:
        """(2, 3) similarity from face units to image pixels."""
        ax, ay = self.axis
        return np.array([[ax, -ay, self.origin[0]], [ay, ax, self.origin[1]]])

    def crop_matrix(self, px: float, extent: tuple[float, float, float, float] = CROP_EXTENT) -> np.ndarray:
        """(2, 3) affine from image pixels to crop pixels (``px`` crop pixels per face unit)."""
        # face units: u = R^T (x - o) / unit, crop: c = (u - (x0, y0)) * px. Scalar arithmetic: this runs a few
        # times per tracked frame, where numpy's per-call cost would outweigh the sums.
        (ax, ay), (ox, oy) = self.axis.tolist(), self.origin.tolist()
        u2 = self.unit ** 2
        a, b = ax / u2 * px, ay / u2 * px
        return np.array([[a, b, -(a * ox + b * oy) - extent[0] * px],
                         [-b, a, -(a * oy - b * ox) - extent[1] * px]])

    def crop_size(self, px: float, extent: tuple[float, float, float, float] = CROP_EXTENT) -> tuple[int, int]:
        return int(round((extent[2] - extent[0]) * px)), int(round((extent[3] - extent[1]) * px))

    def compose(self, correction: np.ndarray) -> FaceFrame:
        """The frame moved by a similarity ``correction`` (2, 3) acting in face units."""
        (s00, _, s02), (s10, _, s12) = np.asarray(correction, dtype=float).tolist()
        (ax, ay), (ox, oy) = self.axis.tolist(), self.origin.tolist()
        # to_image() is [[ax, -ay, ox], [ay, ax, oy]]; the new axis is its rotation part applied to S's first column.
        return FaceFrame(np.array([ax * s02 - ay * s12 + ox, ay * s02 + ax * s12 + oy]),
                         np.array([ax * s00 - ay * s10, ay * s00 + ax * s10]))

    def turn_to(self, other: FaceFrame) -> float:
        """The roll of ``other`` less this frame's, radians in [-pi, pi)."""
        return (other.roll - self.roll + np.pi) % (2 * np.pi) - np.pi

    def blend(self, other: FaceFrame, alpha: float) -> FaceFrame:
        """(1 − alpha) self + alpha other, in origin, log-scale and roll."""
        o = (1 - alpha) * self.origin + alpha * other.origin
        s = np.exp((1 - alpha) * np.log(self.unit) + alpha * np.log(other.unit))
        dr = self.turn_to(other)
        r = self.roll + alpha * dr
        return FaceFrame(o, s * np.array([np.cos(r), np.sin(r)]))


def same_frame(a: FaceFrame, b: FaceFrame, move: float = 0.1, size: float = 0.1) -> bool:
    """Whether two face frames are within ``move`` face units and ``size`` in log size of each other."""
    return bool(np.hypot(*(a.origin - b.origin)) < move * a.unit and abs(np.log(a.unit / b.unit)) < size)


def then_affine(P: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """The affine map (2, 3) that applies ``P`` (2, 3), then ``Q`` (2, 3)."""
    out = np.empty((2, 3))
    out[:, :2] = Q[:, :2] @ P[:, :2]
    out[:, 2] = Q[:, :2] @ P[:, 2] + Q[:, 2]
    return out


def similarity_of_pairs(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """The similarity (2, 3) taking the two points ``src`` (2, 2) exactly onto ``dst`` (2, 2)."""
    (sx0, sy0), (sx1, sy1) = np.asarray(src).tolist()
    (dx0, dy0), (dx1, dy1) = np.asarray(dst).tolist()
    ux, uy, vx, vy = sx1 - sx0, sy1 - sy0, dx1 - dx0, dy1 - dy0
    den = max(ux * ux + uy * uy, 1e-12)
    a, b = (ux * vx + uy * vy) / den, (ux * vy - uy * vx) / den
    mx, my = 0.5 * (sx0 + sx1), 0.5 * (sy0 + sy1)
    return np.array([[a, -b, 0.5 * (dx0 + dx1) - (a * mx - b * my)], [b, a, 0.5 * (dy0 + dy1) - (b * mx + a * my)]])


def scaled_about(S: np.ndarray, point: np.ndarray, factor: float) -> np.ndarray:
    """The similarity ``S`` (2, 3) with its scale multiplied by ``factor``, ``point`` (2,) still mapped where ``S``
    maps it."""
    out = np.asarray(S, dtype=float).copy()
    out[:, :2] *= factor
    out[:, 2] += (S[:, :2] - out[:, :2]) @ np.asarray(point, dtype=float)
    return out


def box_in_crop(box, px: float) -> tuple[int, int, int, int]:
    """A rectangle (x0, y0, x1, y1) in face units as whole crop pixels of a crop of ``px`` pixels per face unit
    (:data:`CROP_EXTENT`'s corner at pixel 0)."""
    x0, y0 = CROP_EXTENT[0], CROP_EXTENT[1]
    return (int(round((box[0] - x0) * px)), int(round((box[1] - y0) * px)),
            int(round((box[2] - x0) * px)), int(round((box[3] - y0) * px)))


def turned_and_shifted(anchors: np.ndarray, correction: np.ndarray) -> np.ndarray:
    """The anchors (N, 2) crop pixels moved by the eye correction ``correction`` (4,) (a, b, tx, ty: the similarity
    [[a, -b, tx], [b, a, ty]]) without its scale: turned by its angle about the eye anchors' midpoint, which goes
    where the correction takes it."""
    a, b, tx, ty = np.asarray(correction, dtype=float).tolist()
    pts = np.asarray(anchors, dtype=float).tolist()
    mx, my = 0.5 * (pts[0][0] + pts[1][0]), 0.5 * (pts[0][1] + pts[1][1])
    s = max(float(np.hypot(a, b)), 1e-9)
    c, d = a / s, b / s                                     # the turn without the scale
    # Row vectors: p @ [[a, b], [-b, a]] is the similarity's linear part; the midpoint goes where it takes it.
    mx2, my2 = a * mx - b * my + tx, b * mx + a * my + ty
    return np.array([[c * (x - mx) - d * (y - my) + mx2, d * (x - mx) + c * (y - my) + my2] for x, y in pts])


def far_correction(correction: np.ndarray) -> bool:
    """Whether the eye correction ``correction`` (4,) (as :func:`turned_and_shifted`) turns the eyes by more than
    :data:`FAR_TURN` against where the alignment put them: more than eyes turn against a face's texture (the
    alignment follows the head's roll), an eye taken on a brow or the hair and held there by searching where it
    was."""
    a, b = float(correction[0]), float(correction[1])
    return abs(float(np.arctan2(b, a))) > FAR_TURN
