"""The paper's colour tracker (§3): Eq. 1 intensity, blobs in anthropometric rectangles, Bezier snakes.

Per frame: the face frame of the last frame (or, when the face is lost, a fresh one from the skin model)
gives a small upright crop of the face (rectangles follow translation, scale and roll); Eq. 1 and the
contrast C turn it into feature intensity; a blob is grown in each feature's rectangle; each curve is fitted
to its blob's boundary and refined as a snake (Eqs. 2-4) against the head's up-vector; the blobs' anchors
re-align the face frame for the next frame; the head pose comes from the stable curve ends.

Conventions: RGB uint8 frames; curves in image pixels (x right, y down); left and right are the performer's.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass, field

import cv2
import numpy as np

from facepuppet.capture.color.blobs import BlobConfig
from facepuppet.capture.color.eye_anchors import calibrated_anchors, eye_centres_of, landmark_curves, shared_landmarker
from facepuppet.capture.color.face import (
    CROP_EXTENT,
    FEATURE_BOXES,
    FaceFrame,
    find_face,
    light_balance,
    similarity_from_points,
)
from facepuppet.capture.color.lids import EYES, apply_lid_model
from facepuppet.capture.color.outlines import (
    BLOB_KINDS,
    BOX_NAMES,
    OUTLINE_PARTS,
    eye_centres,
    feature_intensity,
    move_boxes,
    outline_features,
    skin_fraction,
)
from facepuppet.capture.color.precompile import wait_pending
from facepuppet.capture.color.profile import GENERIC_LAYOUT, Profile, default_profile, load_profile
from facepuppet.capture.color.shape_models import FAMILIES, apply_shape_models
from facepuppet.capture.color.snakes import LOWER, UPPER, SnakeConfig, SnakeSolver, snake_fields
from facepuppet.capture.color.transform import lip_hue_table
from facepuppet.capture.curves import CURVE_NAMES, POINT_NAMES, bezier_points
from facepuppet.capture.features import FrameFeatures
from facepuppet.capture.pose import STABLE_FEATURES, estimate_pose, points_in_head, pose_point_index
from facepuppet.filters import OneEuro, OneEuroConfig

__all__ = ["ColorTrackerConfig", "ColorTracker"]

log = logging.getLogger(__name__)

_IDX = {n: i for i, n in enumerate(CURVE_NAMES)}
#: Blob options per rectangle.
_BLOB = {
    "brow": BlobConfig(seed_level=0.7, grow_level=0.45, radius=1, close=3),
    "eye": BlobConfig(seed_level=0.7, grow_level=0.35, radius=1, close=3),
    "nose": BlobConfig(seed_level=0.7, grow_level=0.4, radius=0, close=0),
    "mouth": BlobConfig(seed_level=0.6, grow_level=0.3, radius=1, close=3),
}
_BLOB_PARAMS = np.array([_BLOB[k].as_array() for k in BLOB_KINDS])
_SHIFTED = np.array([not n.startswith("cheek") for n in BOX_NAMES])     # rectangles that follow the eyes
_MOUTH_BOX = BOX_NAMES.index("mouth")
_POSE_POINTS = pose_point_index(STABLE_FEATURES)         # the stable landmarks among the curve ends
_LIDS = np.ravel(EYES)                                     # the eyelids' curves
_UP = np.array([0.0, -1.0])                                # the head's up-vector in the upright crop
_EYE2 = np.eye(2)
_CROP_ORIGIN = np.asarray(CROP_EXTENT[:2], dtype=float)
_SNAKE_MARGIN = 8                      # crop pixels around the mouth rectangle the snakes see
_CHEEK_L, _CHEEK_R = BOX_NAMES.index("cheek_left"), BOX_NAMES.index("cheek_right")
_EYE_L, _EYE_R = BOX_NAMES.index("eye_left"), BOX_NAMES.index("eye_right")

#: Curves refined as snakes, with the side their feature lies on (Fig. 3).
_SNAKE_CURVES = (("lip_upper_outer", UPPER),
                 ("lip_lower_outer", LOWER))
_SNAKE_IDX = np.array([_IDX[n] for n, _ in _SNAKE_CURVES], dtype=np.int64)
_SNAKE_SIDE = np.array([s for _, s in _SNAKE_CURVES])
_SNAKE_FIXED = np.ones(len(_SNAKE_CURVES), bool)


@dataclass(frozen=True)
class ColorTrackerConfig:
    """Options of the colour tracker.

    Attributes
    ----------
    px : float
        Crop pixels per face unit (eye-centre distance): the work is proportional to its square.
    reestimate_every : int
        Frames between re-estimates of Eq. 1's weights by the colour network.
    follow_iterations : int
        Most steps of the face crop's alignment on the reference crop (ECC) per frame.
    follow_scale : float
        Resolution of the crops aligned, as a fraction of the tracker's crop.
    snake : SnakeConfig
    smoothing : bool
        Smooth the face frame and the curves over time (speed-adaptive, :class:`OneEuro`).
    curve_filter : OneEuroConfig
        Filter of each curve control point in face units (speeds in face units per second).
    lid_filter : OneEuroConfig
        Filter of the eyelids' middle control points when the profile has an eyelid model: as steady as
        ``curve_filter`` when still, quicker when moving, for a blink lasts a few frames; its speed estimate
        is quick too (``d_cutoff`` 4 Hz), for the lid's velocity down and back up within a blink would
        otherwise average out before it opened the filter (``benchmarks/bench_animate.py``, eyeBlink weights
        against MediaPipe's scores, d_cutoff 1 -> 4 Hz: performer_c 0.79 -> 0.90, performer_b 0.37 -> 0.43,
        performer_a 0.84 both).
    shape_filter : OneEuroConfig or None
        Filter of the control points the profile's shape models read (lips, brows, eyes)
        (:mod:`~facepuppet.capture.color.shape_models`), whose readings are steadier than the rules' and whose
        lag costs more than their jitter; None passes them unfiltered.
    frame_filter : OneEuroConfig
        Filter of the face frame (eye midpoint and eye-to-eye vector, in face units).
    frame_gain : float
        Gain of the filter on the eyes' correction of the followed face frame (1: no smoothing).
    max_misses : int
        Frames in a row without the eyes after which the face is searched afresh.
    min_score, min_acquire_score, min_skinless_score : float
        Least likeness to a face (correlation with the drawn layout) to keep following a face, to acquire
        one, and to accept a crop whose cheeks do not look like skin.
    eye_window : (float, float)
        Half width and half height (face units) of the window the eye centres are searched in.
    check_every : int
        Frames between checks that the followed crop still looks like a face.
    min_followed_score : float
        Least likeness (averaged over checks) to keep following.
    landmark_acquire : bool
        When the skin model finds no face (greyscale or colour-graded images, odd light), find it with the
        landmark backend if mediapipe and its model (``$FACEPUPPET_FACE_LANDMARKER``) are available. Only
        its eye positions are used, to place the face frame; the curves still come from §3's pipeline.
    landmark_retry : int
        After the landmark backend found no face, frames to wait before asking it again (it is slow).
    landmark_model : str or None
        Path of the landmark backend's model; default ``$FACEPUPPET_FACE_LANDMARKER``.
    min_landmark_score : float
        Least likeness to a face of a frame placed by the landmark backend (-1: trust the backend).
    anchor_calibration : float
        At the first acquisition, move the eye anchors toward the eye blobs of a crop whose layout sits on the
        eyes the landmark backend sees (if available; :func:`~facepuppet.capture.color.eye_anchors.calibrated_anchors`)
        by this fraction of the way (0: never). One frame's evidence is weighed against the generic anchors:
        half the way made all three shared clips closer to MediaPipe than the whole way or none.
    anchor_scale_limits : (float, float)
        Bounds of the calibration's scale change of the layout.
    anchor_noise_floor : float
        Face units an eye anchor must move by for the calibration to move the anchors at all.
    outline_parts : tuple of str
        Which features §3.2's rules read (:data:`~facepuppet.capture.color.outlines.OUTLINE_PARTS`); the others keep
        the layout's curves. A part's rules are skipped anyway where the profile's shape models read it (its
        curves would be replaced); the snakes go with the lips' rules, the eyelid model with the eyes'.
    resize_cost : float
        When the face was just lost, candidates for finding it again are compared by their likeness to a face
        minus this times the absolute log ratio of their size to the lost frame's (a doubling costs 0.21): a
        face does not change size between two frames, a frame over the whole head or over one eye may look
        like a face too (on a small face after a blink, a candidate twice its size scored 0.18 where the face
        itself scored less).
    """

    px: float = 48.0
    reestimate_every: int = 15
    follow_iterations: int = 2
    follow_scale: float = 0.35
    snake: SnakeConfig = field(default_factory=lambda: SnakeConfig(iterations=5, samples=10, offset=1.5, step=1.0))
    smoothing: bool = True
    curve_filter: OneEuroConfig = field(default_factory=lambda: OneEuroConfig(min_cutoff=0.3, beta=1.5, d_cutoff=1.0))
    lid_filter: OneEuroConfig = field(default_factory=lambda: OneEuroConfig(min_cutoff=0.3, beta=10.0, d_cutoff=4.0))
    shape_filter: OneEuroConfig | None = field(
        default_factory=lambda: OneEuroConfig(min_cutoff=1.0, beta=10.0, d_cutoff=4.0))
    frame_filter: OneEuroConfig = field(default_factory=lambda: OneEuroConfig(min_cutoff=1.0, beta=6.0, d_cutoff=1.0))
    frame_gain: float = 0.3
    max_misses: int = 15
    min_score: float = 0.05
    min_acquire_score: float = 0.15
    min_skinless_score: float = 0.3
    check_every: int = 4
    eye_window: tuple[float, float] = (0.3, 0.14)
    min_followed_score: float = 0.1
    landmark_acquire: bool = True
    landmark_model: str | None = None
    landmark_retry: int = 10
    min_landmark_score: float = -1.0
    anchor_calibration: float = 0.5
    anchor_scale_limits: tuple[float, float] = (0.85, 1.15)
    anchor_noise_floor: float = 0.03
    resize_cost: float = 0.3
    outline_parts: tuple[str, ...] = OUTLINE_PARTS

    def __post_init__(self):
        unknown = set(self.outline_parts) - set(OUTLINE_PARTS)
        if unknown:
            raise ValueError(f"outline_parts: unknown {sorted(unknown)}; known: {', '.join(OUTLINE_PARTS)}")


def _box_px(box, px):
    x0, y0 = CROP_EXTENT[0], CROP_EXTENT[1]
    return (int(round((box[0] - x0) * px)), int(round((box[1] - y0) * px)),
            int(round((box[2] - x0) * px)), int(round((box[3] - y0) * px)))


class ColorTracker:
    """The paper's colour tracker; a :class:`~facepuppet.capture.features.Tracker` backend.

    Parameters
    ----------
    profile : Profile, path or None
        The performer profile (a .npz of :func:`~facepuppet.capture.color.profile.save_profile`); default the
        built-in generic profile.
    config : ColorTrackerConfig
    """

    name = "color"

    def __init__(self, profile: Profile | str | os.PathLike | None = None, *,
                 config: ColorTrackerConfig = ColorTrackerConfig()):
        if profile is None:
            profile = default_profile()
        elif not isinstance(profile, Profile):
            profile = load_profile(profile)
        self.profile = profile
        self.config = config
        wait_pending()          # kernels being compiled in the background are not compiled here again
        self._hue = lip_hue_table(profile.lip_hue)
        self._weights = np.asarray(profile.weights, dtype=np.float32)
        self._net = None
        if profile.net:
            from facepuppet.capture.color.net import ColourNet

            self._net = ColourNet.from_arrays(profile.net)
        px = config.px
        self._size = (int(round((CROP_EXTENT[2] - CROP_EXTENT[0]) * px)),
                      int(round((CROP_EXTENT[3] - CROP_EXTENT[1]) * px)))
        shift = self._layout_shift(profile.layout)
        self._boxes = {k: _box_px(np.asarray(b) + np.r_[shift.get(k, (0, 0)), shift.get(k, (0, 0))], px)
                       for k, b in FEATURE_BOXES.items()}
        self._box_table = np.array([self._boxes[n] for n in BOX_NAMES], dtype=np.int64)
        self._cheek_boxes = self._box_table[[_CHEEK_L, _CHEEK_R]]
        self._eye_boxes = self._box_table[[_EYE_L, _EYE_R]]
        self._skin_table = profile.skin.table()
        self._light: np.ndarray | None = None       # colour transform evening out the light (set at acquisition)
        self._eye_window = (int(round(config.eye_window[0] * px)), int(round(config.eye_window[1] * px)))
        self._layout_px = (np.asarray(profile.layout) - CROP_EXTENT[:2]) * px
        self._origin_px = -_CROP_ORIGIN * px          # the face frame's origin in crop pixels
        self._set_anchors((np.asarray(profile.anchors) - CROP_EXTENT[:2]) * px)
        self._calibrated = config.anchor_calibration <= 0    # anchors calibrated on the landmark backend's eyes
        self._frame: FaceFrame | None = None
        self._dropped: FaceFrame | None = None     # the frame the likeness check just dropped
        self._ref: np.ndarray | None = None
        self._followed: np.ndarray | None = None      # crop matrix where the alignment last put the face
        self._misses = 0
        self._corr: np.ndarray | None = None
        self._unit_ref = 1.0
        self._score: float | None = None
        self._count_tracked = 0
        self._shift = np.zeros(2)
        #: (face crop, its crop matrix, the layout placed on it) of the last frame whose curves were measured:
        #: where the profile's shape models learn (capture._calibrate).
        self.seen: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._make_template()
        self._snakes = SnakeSolver(_SNAKE_SIDE, _UP, config.snake, fixed_ends=_SNAKE_FIXED)
        self._curve_filter = OneEuro(config.curve_filter)
        self._lid_filter = OneEuro(config.lid_filter)
        self._shape_filter = None if config.shape_filter is None else OneEuro(config.shape_filter)
        self._shaped = np.concatenate([FAMILIES[f] for f in sorted(self.profile.shapes)] or [np.zeros(0, int)])
        # The rules whose curves the shape models replace are not run.
        shaped = set(self.profile.shapes)
        replaced = {"mouth"} if "lips" in shaped else set()
        replaced |= {"brows"} if {"brow_left", "brow_right"} <= shaped else set()
        replaced |= {"eyes"} if {"eye_left", "eye_right"} <= shaped else set()
        self._parts = tuple(p for p in config.outline_parts if p not in replaced)
        # The eyelid model (and its filter) goes with the eyes' rules: where those are not run, it is not either.
        self._lids = ({k: np.ascontiguousarray(v, dtype=np.float64) for k, v in profile.lids.items()}
                      if "eyes" in self._parts else {})
        self._frame_filter = OneEuro(config.frame_filter)
        self._last_ms: int | None = None
        self._landmarker = None          # the shared landmark backend, once needed (False: not available)
        self._skinless_ok = False
        self._landmark_wait = 0
        self._mouth_offset = np.zeros(2)  # crop pixels the mouth sits off the layout (set by the landmark backend)
        self._pose = None
        self._count = 0

    def _set_anchors(self, anchors_px: np.ndarray) -> None:
        """The anchors (3, 2) in crop pixels, and what is derived from them."""
        self._anchors_px = np.asarray(anchors_px, dtype=float)
        self._anchor_mid = self._anchors_px[:2].mean(axis=0)

    @staticmethod
    def _layout_shift(layout: np.ndarray) -> dict[str, np.ndarray]:
        d = np.asarray(layout) - GENERIC_LAYOUT
        g = lambda *names: d[[_IDX[n] for n in names]].reshape(-1, 2).mean(0)  # noqa: E731
        return {
            "brow_left": g("brow_left"), "brow_right": g("brow_right"),
            "eye_left": g("eye_left_upper", "eye_left_lower"), "eye_right": g("eye_right_upper", "eye_right_lower"),
            "nose": g("nostril_left", "nostril_right"),
            "mouth": g("lip_upper_outer", "lip_lower_outer"),
        }

    # -- per frame -------------------------------------------------------------------------------------
    def track(self, rgb: np.ndarray, timestamp_ms: int) -> FrameFeatures:
        """Track one RGB frame (H, W, 3) uint8; see :class:`~facepuppet.capture.features.Tracker`."""
        rgb = np.asarray(rgb)
        if rgb.ndim == 2:
            rgb = cv2.cvtColor(rgb, cv2.COLOR_GRAY2RGB)
        if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
            raise ValueError(f"rgb must be an (H, W, 3) uint8 image, got shape {rgb.shape} dtype {rgb.dtype}")
        h, w = rgb.shape[:2]
        result = None
        if self._frame is not None:
            result = self._measure(rgb, self._frame, follow=True, gain=self.config.frame_gain)
            if result is not None:
                self._misses = 0 if result[2] else self._misses + 1
                if self._misses > self.config.max_misses or result[3] < self.config.min_score:
                    result = None
                elif not (0.65 < result[1].unit / self._unit_ref < 1.5):
                    result = None                   # the frame shrank or grew far too fast: start afresh
                else:
                    self._unit_ref += 0.05 * (result[1].unit - self._unit_ref)
        if result is None:
            # The frame the face was followed in until now (or until the likeness check dropped it) is a
            # candidate too: after a blink or a turn the face is usually still there.
            result = self._acquire(rgb, last=self._frame or self._dropped)
        self._dropped = None
        if result is None:
            self._frame = self.seen = None
            return FrameFeatures.lost(len(CURVE_NAMES), len(POINT_NAMES))
        curves, self._frame, self._corr, self.seen = result[0], result[1], result[5], result[6]
        self._count_tracked += 1
        if self._count_tracked % self.config.check_every == 0:
            self._check_score()
        curves = self._filter(curves, result[4], timestamp_ms)
        return self._features(curves, (w, h))

    def _acquire(self, rgb: np.ndarray, last: FaceFrame | None = None):
        """Find the face afresh: skin region and eye holes, then the candidate frame that looks most like a face.

        ``last``: the frame the face was followed in until now, if it was just lost (a candidate too, in the
        light it was followed in).
        """
        last_light = self._light
        self._curve_filter.reset()
        self._lid_filter.reset()
        if self._shape_filter is not None:
            self._shape_filter.reset()
        self._frame_filter.reset()
        self._pose = None
        self._mouth_offset = np.zeros(2)
        self._misses = 0
        self._ref = None
        self._corr = None
        # Skin regions of the frame as filmed and of the frame with its light's colour and level evened out
        # (a warm, cool or dim light moves skin out of the skin model, or other things into it). The light of
        # the hypothesis that looks most like a face is kept: the crops are evened out the same way until the
        # face is lost.
        best, light, seen = None, None, []
        hypotheses = [(None, None), (light_balance(rgb), None)]
        if last is not None:
            hypotheses.insert(0, (last_light, last))
        for M, frame in hypotheses:
            if frame is None:
                frame = find_face(rgb if M is None else cv2.transform(rgb, M), self.profile.skin)
            if frame is None or frame.unit < 6 or any(_same_frame(frame, f) for f in seen):
                continue
            seen.append(frame)
            self._light = M
            got = self._refine(rgb, [frame.compose(np.array([[s, 0.0, 0.0], [0.0, s, dy]]))
                                     for dy in (0.0, 0.35, -0.35) for s in (1.0, 0.8, 1.25)], last)
            if got is not None and (best is None or self._likeness(got, last) > self._likeness(best, last)):
                best, light = got, M
        self._light = light if light is None or best is None else self._fit_light(rgb, best[1], light)
        if best is None or best[3] < self.config.min_acquire_score:
            best = self._landmark_acquire(rgb)
        if best is None:
            return None
        if not self._calibrated:
            self._calibrated = True
            placed = self._calibrate_anchors(rgb, best[1])
            if placed is not None:
                best = self._settle(rgb, placed) or best
        self._followed = best[1].crop_matrix(self.config.px)
        self._ref = self._grey(rgb, self._followed)
        self._unit_ref = best[1].unit
        self._score = None
        return best

    def _fit_light(self, rgb: np.ndarray, frame: FaceFrame, M: np.ndarray) -> np.ndarray:
        """The light transform ``M`` scaled down where it would saturate the face: the crop's 99th percentile
        is kept at or below 230 (a stretch measured on the whole frame over-brightens a small face)."""
        crop = cv2.warpAffine(rgb, frame.crop_matrix(self.config.px), self._size, flags=cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_REPLICATE)
        top = float(np.percentile(cv2.transform(crop, M), 99.0))
        return M * min(1.0, 230.0 / max(top, 1.0))

    def _calibrate_anchors(self, rgb: np.ndarray, frame: FaceFrame) -> FaceFrame | None:
        """Move the eye anchors onto the eye blobs of a crop placed by the landmark backend's eyes (the layout's
        eyes on them); the face frame of that crop if they moved, else None. ``frame``: the frame acquired."""
        from facepuppet.capture.landmarks import MediaPipeConfig

        landmarker = shared_landmarker(self.config.landmark_model, MediaPipeConfig(refine_scales=(),
                                                                                   tile_fractions=()))
        curves = None if landmarker is None else landmark_curves(landmarker, rgb)
        if curves is None:
            return None
        S = similarity_from_points(eye_centres_of(np.asarray(self.profile.layout)), eye_centres_of(curves))
        placed = FaceFrame(S[:, 2].copy(), S[:, 0].copy())
        if not _same_frame(placed, frame, 0.25, 0.2):
            return None                     # the backend's face is not the one acquired
        px = self.config.px
        crop = cv2.warpAffine(rgb, placed.crop_matrix(px), self._size, flags=cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_REPLICATE)
        if self._light is not None:
            crop = cv2.transform(crop, self._light)
        C = self.intensity(crop)
        # The blobs' centres as a fixed point of the eye search (each search takes a few mean-shift steps).
        eyes = self._anchors_px[:2]
        for _ in range(4):
            ok, nxt = eye_centres(C, eyes, *self._eye_window)
            if not ok:
                return None
            eyes, step = nxt, np.abs(nxt - eyes).max()
            if step < 0.25:
                break
        cfg = self.config
        new = calibrated_anchors(self._anchors_px, eyes, px, scale_limits=cfg.anchor_scale_limits,
                                 noise_floor=cfg.anchor_noise_floor, gain=cfg.anchor_calibration)
        if new is None:
            return None
        log.debug("eye anchors calibrated: %s -> %s face units", (self._anchors_px[:2] / px).round(3).tolist(),
                  (new[:2] / px).round(3).tolist())
        self._set_anchors(new)
        return placed

    def _landmark_acquire(self, rgb: np.ndarray):
        """The face frame placed on the eyes the landmark backend finds (no skin needed), refined on §3's eyes."""
        if not self.config.landmark_acquire or self._landmarker is False:
            return None
        if self._landmark_wait > 0:
            self._landmark_wait -= 1
            return None
        if self._landmarker is None:
            self._landmarker = shared_landmarker(self.config.landmark_model) or False
            if self._landmarker is False:
                return None
        curves = landmark_curves(self._landmarker, rgb)
        if curves is None:
            self._landmark_wait = self.config.landmark_retry
            return None
        eyes = eye_centres_of(curves)
        S = similarity_from_points(np.asarray(self.profile.anchors)[:2], eyes)
        frame = FaceFrame(S[:, 2].copy(), S[:, 0].copy())
        if frame.unit < 6:
            return None
        # The mouth rectangle goes where the backend's mouth is (faces differ most in the eye-mouth distance).
        lips = [_IDX[n] for n in CURVE_NAMES if n.startswith("lip_")]
        M = frame.to_image()
        seen = (np.concatenate([bezier_points(c, 16) for c in curves[lips]]).mean(axis=0) - M[:, 2]) \
            @ np.linalg.inv(M[:, :2]).T
        drawn = np.concatenate([bezier_points(c, 16) for c in np.asarray(self.profile.layout)[lips]]).mean(axis=0)
        self._mouth_offset = np.clip(seen - drawn, -0.3, 0.3) * self.config.px
        best = self._settle(rgb, frame)
        if best is None or best[3] < self.config.min_landmark_score:
            return None
        return best

    def _settle(self, rgb: np.ndarray, frame: FaceFrame):
        """Measure in a face frame the landmark backend placed (no skin needed): §3's eye search may only
        nudge it (the backend's eyes are trusted); the measurement's tuple, or None."""
        self._skinless_ok = True
        try:
            best = self._refine(rgb, [frame])
            if best is None or not _same_frame(best[1], frame):
                self._corr = np.array([1.0, 0.0, 0.0, 0.0])
                best = self._measure(rgb, frame, follow=True, gain=0.0)
                if best is not None:
                    best = best[:3] + (self._face_score(self.intensity_last, np.eye(2, 3)),) + best[4:]
        finally:
            self._skinless_ok = False
        return best

    def _check_score(self) -> None:
        """Now and then, how much the followed crop still looks like a face (smoothed); drop the frame if not.

        Scored on the crop just measured, with the layout placed where the eyes put it.
        """
        score = self._face_score(*self._last_measured)
        self._score = score if self._score is None else 0.5 * (self._score + score)
        if self._score < self.config.min_followed_score:
            log.debug("face lost: the followed crop no longer looks like a face (score %.2f)", self._score)
            self._frame, self._dropped = None, self._frame

    def _likeness(self, result, last: FaceFrame | None) -> float:
        """How much a measurement's crop looks like a face, less ``resize_cost`` per unit of log size change
        from ``last``, the frame the face was just lost in (if any)."""
        if last is None:
            return result[3]
        return result[3] - self.config.resize_cost * abs(np.log(result[1].unit / last.unit))

    def _refine(self, rgb: np.ndarray, candidates: list[FaceFrame], last: FaceFrame | None = None):
        """Pull each candidate face frame onto the eyes; the result that looks most like a face (:meth:`_likeness`
        with ``last``), or None."""
        best = None
        for cand in candidates:
            result = None
            for step in range(3):
                result = self._measure(rgb, cand, follow=False, gain=1.0, outline=step == 2)
                if result is None:
                    break
                cand = result[1]
            if result is not None and result[2] and (best is None or
                                                     self._likeness(result, last) > self._likeness(best, last)):
                best = result
        return best

    def close(self) -> None:
        """Let go of the landmark backend (shared by the process's trackers: it stays open until exit)."""
        self._landmarker = None

    # -- internals -------------------------------------------------------------------------------------
    def _filter(self, curves: np.ndarray, measured: FaceFrame, timestamp_ms: int) -> np.ndarray:
        """Smooth the face frame and the curves (in face units) over time, each with a One-Euro filter.

        Still points are smoothed hard and fast ones followed at once (the cut-off frequency rises with the
        speed), so small noise is damped without visible lag on fast expressions.
        """
        last, self._last_ms = self._last_ms, timestamp_ms
        if not self.config.smoothing:
            return curves
        dt = (timestamp_ms - last) / 1000.0 if last is not None else 0.0
        if not dt > 0:
            self._curve_filter.reset()
            self._lid_filter.reset()
            if self._shape_filter is not None:
                self._shape_filter.reset()
            self._frame_filter.reset()
        # Image pixels -> face units: the inverse of the frame's similarity [[ax, -ay], [ay, ax]] is its
        # transpose over the squared unit.
        ax, ay = measured.axis.tolist()
        u2 = ax * ax + ay * ay
        units = (curves - measured.origin) @ np.array([[ax / u2, -ay / u2], [ay / u2, ax / u2]])
        fr = self._frame_filter(np.array([measured.origin, measured.axis]), dt, measured.unit)
        smooth = self._curve_filter(units, dt)
        if self._lids:
            smooth[_LIDS, 1:3] = self._lid_filter(units[_LIDS, 1:3], dt)
        if len(self._shaped):
            shaped = units[self._shaped]
            smooth[self._shaped] = shaped if self._shape_filter is None else self._shape_filter(shaped, dt)
        (ox, oy), (ax, ay) = fr.tolist()
        return smooth @ np.array([[ax, ay], [-ay, ax]]) + np.array([ox, oy])

    def _features(self, curves: np.ndarray, size: tuple[int, int]) -> FrameFeatures:
        # The stable landmarks are the layout's, placed by the face frame (a similarity): they show the head's
        # roll, size and place but not a turn, so the pose is solved upright (estimate_pose, out_of_plane).
        uv = curves[_POSE_POINTS]
        pose = estimate_pose(uv, size, previous=self._pose, out_of_plane=False)
        if not pose:
            pose = estimate_pose(uv, size, out_of_plane=False)
        self._pose = pose if pose else None
        if pose:
            points = points_in_head(curves, pose)
            return FrameFeatures(True, curves, pose.rotation, pose.translation, points)
        nan = np.nan
        return FrameFeatures(True, curves, np.full((3, 3), nan), np.full(3, nan), np.full((len(POINT_NAMES), 3), nan))

    def intensity(self, crop: np.ndarray) -> np.ndarray:
        """Eq. 1 and the contrast C on a face crop (H, W, 3) uint8 -> (H, W) float32 in [0, 1]."""
        if self._net is not None and (self._count % self.config.reestimate_every == 0):
            from facepuppet.capture.color.net import subarea_means

            self._weights = self._net.predict(subarea_means(crop, self.config.px))
        self._count += 1
        self._raw, self.intensity_last, self._value = feature_intensity(
            crop, self._weights.astype(np.float64), self._hue, self.profile.lip_hue.min_saturation,
            self._cheek_boxes, self._eye_boxes)
        return self.intensity_last

    def _measure(self, rgb: np.ndarray, frame: FaceFrame, *, follow: bool, gain: float, outline: bool = True):
        """Track one frame in the face frame ``frame``; without ``outline``, only re-align the frame (the
        curves are None: the steps that only move a candidate frame do not need them).

        Returns
        -------
        tuple or None
            (curves (C, 4, 2) image pixels, re-aligned face frame, eyes found, face score, the same frame,
            the eyes' smoothed correction (4,), what the curves were read on: (crop, crop matrix, layout
            placed on the crop) or None), or None when the crop shows no face (no skin on the cheeks and
            little likeness to a face).
        """
        px = self.config.px
        A = frame.crop_matrix(px)
        if follow and self._ref is not None:
            moved = self._follow(rgb, A)
            if moved is not None and 0.8 < moved.unit / frame.unit < 1.25:
                frame = moved
                A = frame.crop_matrix(px)
        crop = cv2.warpAffine(rgb, A, self._size, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        if self._light is not None:
            crop = cv2.transform(crop, self._light)
        skin = self._skin_ok(crop)
        C = self.intensity(crop)
        eyes = self._eye_centres(C)
        # The eyes' correction of the followed frame (a similarity in crop pixels, as a, b, tx, ty), smoothed
        # over frames: the alignment on the whole face is steady, the eye search noisier but unbiased.
        smooth = follow and self._corr is not None
        corr = self._corr if smooth else np.array([1.0, 0.0, 0.0, 0.0])
        if eyes is not None:
            S_eye = _similarity_of_pairs(self._anchors_px[:2], eyes)
            if 0.8 < float(np.hypot(S_eye[0, 0], S_eye[1, 0])) < 1.25:
                v = np.array([S_eye[0, 0], S_eye[1, 0], S_eye[0, 2], S_eye[1, 2]])
                corr = corr + gain * (v - corr) if smooth else v
            else:
                eyes = None
        a, b, tx, ty = corr.tolist()
        S_px = np.array([[a, -b, tx], [b, a, ty]])
        scale = float(np.hypot(a, b))
        self._shift = S_px[:, 2] + (S_px[:, :2] - _EYE2) @ self._anchor_mid
        self._last_measured = (C, S_px)
        boxes = self._boxes_now()
        # How much the crop looks like a face: needed to pick among candidates and when the skin is not seen.
        score = self._face_score(C, S_px) if (not follow or not skin) else 1.0
        if not skin and score < self.config.min_skinless_score and not self._skinless_ok:
            return None
        curves = None
        if outline:
            placed = self._layout_px @ S_px[:, :2].T + S_px[:, 2]
            curves_px = self._outlines(C, crop, placed, boxes, px * scale)
            Ainv = cv2.invertAffineTransform(A)
            curves = curves_px @ Ainv[:, :2].T + Ainv[:, 2]                 # back to image pixels
        S = np.empty((2, 3))                                                  # S_px in face units
        S[:, :2] = S_px[:, :2]
        S[:, 2] = -S_px[:, :2] @ _CROP_ORIGIN + S_px[:, 2] / px + _CROP_ORIGIN
        measured = frame.compose(S)
        return curves, measured, eyes is not None, score, measured, corr, (crop, A, placed) if outline else None

    def _outlines(self, C: np.ndarray, crop: np.ndarray, layout: np.ndarray, boxes: np.ndarray,
                  unit: float) -> np.ndarray:
        """The curves (C, 4, 2) in crop pixels: §3.2's rules from the layout placed on the crop (``layout``),
        the lips refined as snakes, the lids by the performer's eyelid model if any, the lips, brows and eyes
        by the performer's shape models if any (which make the rules, the snakes and the eyelid model they
        replace needless). ``unit``: crop pixels per face unit."""
        curves_px = outline_features(C, self._raw, self._value, layout, self._mouth_offset, boxes, _BLOB_PARAMS,
                                     unit, float(self.profile.mouth_reach), parts=self._parts)
        idx = _SNAKE_IDX
        if len(idx) and "mouth" in self._parts:
            # The snakes see the mouth rectangle and a margin (the fields are only computed there).
            h, w = C.shape
            m = _SNAKE_MARGIN
            x0, y0, x1, y1 = boxes[_MOUTH_BOX]
            x0, y0, x1, y1 = max(x0 - m, 0), max(y0 - m, 0), min(x1 + m, w), min(y1 + m, h)
            if x1 - x0 > 2 * m and y1 - y0 > 2 * m:
                o = np.array([x0, y0], dtype=float)
                curves_px[idx] = self._snakes(curves_px[idx] - o, snake_fields(C[y0:y1, x0:x1], 5)) + o
        if self._lids:
            # The performer's eyelid model reads the lids off the look of each eye (capture.lids).
            apply_lid_model(curves_px, crop, self._lids)
        if self.profile.shapes:
            apply_shape_models(curves_px, crop, layout, self.profile.shapes)
        return curves_px

    def _face_score(self, C: np.ndarray, S_px: np.ndarray) -> float:
        """Correlation of the feature intensity with the profile's layout drawn as a face (in [-1, 1])."""
        T = cv2.warpAffine(self._template, S_px.astype(np.float32), self._size, flags=cv2.INTER_LINEAR)
        x0, y0, x1, y1 = self._template_box
        a, t = C[y0:y1, x0:x1].ravel(), T[y0:y1, x0:x1].ravel()        # copies, row by row
        a = a - a.mean()
        t = t - t.mean()
        return float((a * t).sum() / max(np.sqrt((a * a).sum() * (t * t).sum()), 1e-9))

    def _make_template(self) -> None:
        """The layout drawn as bright features on dark skin: eyes, brows, mouth line and nostrils."""
        px = self.config.px
        T = np.zeros(self._size[::-1], np.float32)
        L = self._layout_px
        for name in CURVE_NAMES:
            pts = np.round(bezier_points(L[_IDX[name]], 16) * 4).astype(np.int32)
            cv2.polylines(T, [pts], False, 1.0, thickness=max(1, int(0.06 * px)), lineType=cv2.LINE_AA, shift=2)
        self._template = cv2.GaussianBlur(T, (0, 0), 0.05 * px)
        self._template_box = _box_px((-0.95, -0.6, 0.95, 1.7), px)      # the part of the crop scored

    def _eye_centres(self, C: np.ndarray) -> np.ndarray | None:
        """Eye centres (2, 2) in crop pixels near the expected anchors (:func:`~.outlines.eye_centres`), or None."""
        found, eyes = eye_centres(C, self._anchors_px, *self._eye_window)
        return eyes if found else None

    def _grey(self, rgb: np.ndarray, A: np.ndarray) -> np.ndarray:
        """The face crop of crop matrix ``A`` at ``follow_scale`` resolution, grey, float32 (for the alignment)."""
        w, h = self._size
        f = self.config.follow_scale
        small = cv2.warpAffine(rgb, A * f, (int(w * f), int(h * f)), flags=cv2.INTER_LINEAR,
                               borderMode=cv2.BORDER_REPLICATE)
        return cv2.cvtColor(small, cv2.COLOR_RGB2GRAY).astype(np.float32)

    def _follow(self, rgb: np.ndarray, A: np.ndarray) -> FaceFrame | None:
        """The face frame moved by aligning the face crop on the reference crop (ECC, affine).

        The search starts where the alignment put the face in the last frame, so a couple of steps suffice.
        """
        # First guess: the face where the alignment last put it (reference half-res crop -> current one).
        f = self.config.follow_scale
        guess = _then(cv2.invertAffineTransform(self._followed), A)
        guess[:, 2] *= f
        try:
            _, warp = cv2.findTransformECC(self._ref, self._grey(rgb, A), guess.astype(np.float32),
                                           cv2.MOTION_AFFINE, (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS,
                                                               self.config.follow_iterations, 1e-3), None, 3)
        except cv2.error:
            return None
        W = warp.astype(float)
        W[:, 2] /= f
        G = _then(W, cv2.invertAffineTransform(A))      # crop pixels -> image pixels, where the face is now
        self._followed = cv2.invertAffineTransform(G)
        px = self.config.px
        return FaceFrame(G[:, :2] @ self._origin_px + G[:, 2], G[:, 0] * px)

    def _skin_ok(self, crop: np.ndarray) -> bool:
        """Whether the cheeks of the crop look like skin (the profile's skin model, over 30 % of the pixels)."""
        return skin_fraction(crop, self._cheek_boxes, self._skin_table) > 0.3

    def _boxes_now(self) -> np.ndarray:
        """The feature rectangles (len(BOX_NAMES), 4) of this frame: moved with the layout's eyes (translation
        only; the mouth also by its offset), clipped to the crop. The cheeks stay where the frame puts them."""
        return move_boxes(self._box_table, _SHIFTED, _MOUTH_BOX, self._shift, self._mouth_offset, *self._size)


def _same_frame(a: FaceFrame, b: FaceFrame, move: float = 0.1, size: float = 0.1) -> bool:
    """Whether two face frames are within ``move`` face units and ``size`` in log size of each other."""
    return bool(np.hypot(*(a.origin - b.origin)) < move * a.unit and abs(np.log(a.unit / b.unit)) < size)


def _then(P: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """The affine map (2, 3) that applies ``P`` (2, 3), then ``Q`` (2, 3)."""
    out = np.empty((2, 3))
    out[:, :2] = Q[:, :2] @ P[:, :2]
    out[:, 2] = Q[:, :2] @ P[:, 2] + Q[:, 2]
    return out


def _similarity_of_pairs(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """The similarity (2, 3) taking the two points ``src`` (2, 2) exactly onto ``dst`` (2, 2)."""
    (sx0, sy0), (sx1, sy1) = np.asarray(src).tolist()
    (dx0, dy0), (dx1, dy1) = np.asarray(dst).tolist()
    ux, uy, vx, vy = sx1 - sx0, sy1 - sy0, dx1 - dx0, dy1 - dy0
    den = max(ux * ux + uy * uy, 1e-12)
    a, b = (ux * vx + uy * vy) / den, (ux * vy - uy * vx) / den
    mx, my = 0.5 * (sx0 + sx1), 0.5 * (sy0 + sy1)
    return np.array([[a, -b, 0.5 * (dx0 + dx1) - (a * mx - b * my)], [b, a, 0.5 * (dy0 + dy1) - (b * mx + a * my)]])
