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
from dataclasses import replace

import cv2
import numpy as np

from facepuppet.capture.color.config import ColorTrackerConfig
from facepuppet.capture.color.eye_anchors import (
    calibrated_anchors,
    eye_centres,
    eye_centres_of,
    landmark_curves,
    shared_landmarker,
)
from facepuppet.capture.color.face import (
    CROP_EXTENT,
    FEATURE_BOXES,
    FaceFrame,
    find_face,
    light_balance,
    same_frame,
    similarity_from_points,
    similarity_of_pairs,
    then_affine,
)
from facepuppet.capture.color.jobs import wait_pending
from facepuppet.capture.color.lids import EYES, PATCH_SIZE, apply_lid_model
from facepuppet.capture.color.measure import Measurement
from facepuppet.capture.color.profile import GENERIC_LAYOUT, Profile, default_profile, load_profile
from facepuppet.capture.color.rules import BLOB_PARAMS, BOX_NAMES, move_boxes, outline_features
from facepuppet.capture.color.shape_models import FAMILIES, apply_shape_models
from facepuppet.capture.color.snakes import LOWER, UPPER, SnakeSolver, snake_fields
from facepuppet.capture.color.transform import feature_intensity, lip_hue_table, skin_fraction
from facepuppet.capture.curves import CURVE_NAMES, POINT_NAMES, bezier_points
from facepuppet.capture.features import FrameFeatures
from facepuppet.capture.pose import STABLE_FEATURES, estimate_pose, points_in_head, pose_point_index
from facepuppet.filters import OneEuro

__all__ = ["ColorTrackerConfig", "ColorTracker", "Measurement", "WARMUP_PARTS"]

log = logging.getLogger(__name__)

_IDX = {n: i for i, n in enumerate(CURVE_NAMES)}
#: The parts of a frame's work :meth:`ColorTracker.warmup` runs: all but the outline rules, and the snakes.
WARMUP_PARTS = ("frame", "snakes")

# Tuning constants                           unit            what it does
SNAKE_MARGIN = 8                             # crop pixels     around the mouth rectangle the snakes see
SNAKE_BLUR = 5                               # crop pixels     blur of the snakes' fields (:func:`.snakes.snake_fields`)
SKIN_CHEEKS = 0.3                            # fraction        of the cheeks' pixels that must look like skin
MIN_UNIT = 6                                 # image pixels    smallest face (eye distance) tracked
SCALE_STEP = (0.8, 1.25)                     # ratio           size change of the face frame one frame's step may make
UNIT_JUMP = (0.65, 1.5)                      # ratio           size change from the slow reference that loses the face
UNIT_GAIN = 0.05                             # per frame       gain of the slow reference size
CANDIDATE_SHIFTS = (0.0, 0.35, -0.35)        # face units      vertical shifts of a skin region's candidate frames
CANDIDATE_SCALES = (1.0, 0.8, 1.25)          # ratio           sizes of a skin region's candidate frames
REFINE_STEPS = 3                             # steps           eye-search steps pulling a candidate onto the eyes
LIGHT_PERCENTILE = 99.0                      # percentile      of the face crop kept at or below LIGHT_TOP ...
LIGHT_TOP = 230.0                            # 8-bit level     ... by the light transform (no saturated face)
SAME_FACE = (0.25, 0.2)                      # face units, log size   the landmark backend's face is the one acquired
ANCHOR_STEPS = 4                             # steps           most eye searches to find the eye blobs' fixed point
ANCHOR_TOLERANCE = 0.25                      # crop pixels     step below which the eye blobs' fixed point is found
MOUTH_OFFSET_LIMIT = 0.3                     # face units      farthest the backend's mouth moves the mouth rectangle
CURVE_SAMPLES = 16                           # points          along a curve where it is drawn or averaged
TEMPLATE_LINE = 0.06                         # face units      thickness of the face template's lines
TEMPLATE_BLUR = 0.05                         # face units      blur of the face template
TEMPLATE_BOX = (-0.95, -0.6, 0.95, 1.7)      # face units      part of the crop the face likeness is scored on
ECC_EPS = 1e-3                               # correlation     the alignment's convergence tolerance (ECC)
ECC_BLUR = 3                                 # pixels          Gaussian blur of the alignment's images (ECC)
_SHIFTED = np.array([not n.startswith("cheek") for n in BOX_NAMES])     # rectangles that follow the eyes
_MOUTH_BOX = BOX_NAMES.index("mouth")
_POSE_POINTS = pose_point_index(STABLE_FEATURES)         # the stable landmarks among the curve ends
_LIDS = np.ravel(EYES)                                     # the eyelids' curves
_UP = np.array([0.0, -1.0])                                # the head's up-vector in the upright crop
_EYE2 = np.eye(2)
_CROP_ORIGIN = np.asarray(CROP_EXTENT[:2], dtype=float)
_CHEEK_L, _CHEEK_R = BOX_NAMES.index("cheek_left"), BOX_NAMES.index("cheek_right")
_EYE_L, _EYE_R = BOX_NAMES.index("eye_left"), BOX_NAMES.index("eye_right")

#: Curves refined as snakes, with the side their feature lies on (Fig. 3).
_SNAKE_CURVES = (("lip_upper_outer", UPPER),
                 ("lip_lower_outer", LOWER))
_SNAKE_IDX = np.array([_IDX[n] for n, _ in _SNAKE_CURVES], dtype=np.int64)
_SNAKE_SIDE = np.array([s for _, s in _SNAKE_CURVES])
_SNAKE_FIXED = np.ones(len(_SNAKE_CURVES), bool)


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
    config : ColorTrackerConfig, optional
    """

    name = "color"

    def __init__(self, profile: Profile | str | os.PathLike | None = None, *,
                 config: ColorTrackerConfig | None = None):
        if profile is None:
            profile = default_profile()
        elif not isinstance(profile, Profile):
            profile = load_profile(profile)
        self.profile = profile
        config = config if config is not None else ColorTrackerConfig()
        self.config = config
        wait_pending()          # kernels being compiled in the background are not compiled here again
        self._hue = lip_hue_table(profile.lip_hue)
        self._weights = np.asarray(profile.weights, dtype=np.float32)
        self._net = None
        if profile.net:
            from facepuppet.capture.color.net import ColourNet

            self._net = ColourNet.from_arrays(profile.net)
        px = config.measure.px
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
        self._eye_window = (int(round(config.measure.eye_window[0] * px)),
                            int(round(config.measure.eye_window[1] * px)))
        self._layout_px = (np.asarray(profile.layout) - CROP_EXTENT[:2]) * px
        self._origin_px = -_CROP_ORIGIN * px          # the face frame's origin in crop pixels
        self._set_anchors((np.asarray(profile.anchors) - CROP_EXTENT[:2]) * px)
        # Whether the anchors are calibrated on the landmark backend's eyes.
        self._calibrated = config.landmarks.anchor_calibration <= 0
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
        #: where the profile's shape models learn (:func:`~facepuppet.capture.color.train.train_profile`).
        self.seen: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._make_template()
        self._snakes = SnakeSolver(_SNAKE_SIDE, _UP, config.measure.snake, fixed_ends=_SNAKE_FIXED)
        self._curve_filter = OneEuro(config.filters.curve)
        self._lid_filter = OneEuro(config.filters.lid)
        self._shape_filter = None if config.filters.shape is None else OneEuro(config.filters.shape)
        self._shaped = np.concatenate([FAMILIES[f] for f in sorted(self.profile.shapes)] or [np.zeros(0, int)])
        # The rules whose curves the shape models replace are not run.
        shaped = set(self.profile.shapes)
        replaced = {"mouth"} if "lips" in shaped else set()
        replaced |= {"brows"} if {"brow_left", "brow_right"} <= shaped else set()
        replaced |= {"eyes"} if {"eye_left", "eye_right"} <= shaped else set()
        self._parts = tuple(p for p in config.measure.outline_parts if p not in replaced)
        # The eyelid model (and its filter) goes with the eyes' rules: where those are not run, it is not either.
        self._lids = ({k: np.ascontiguousarray(v, dtype=np.float64) for k, v in profile.lids.items()}
                      if "eyes" in self._parts else {})
        self._frame_filter = OneEuro(config.filters.frame)
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
            result = self._measure(rgb, self._frame, follow=True, gain=self.config.follow.frame_gain)
            if result is not None:
                self._misses = 0 if result.eyes_found else self._misses + 1
                if self._misses > self.config.follow.max_misses or result.score < self.config.follow.min_score:
                    result = None
                elif not (UNIT_JUMP[0] < result.frame.unit / self._unit_ref < UNIT_JUMP[1]):
                    result = None                   # the frame shrank or grew far too fast: start afresh
                else:
                    self._unit_ref += UNIT_GAIN * (result.frame.unit - self._unit_ref)
        if result is None:
            # The frame the face was followed in until now (or until the likeness check dropped it) is a
            # candidate too: after a blink or a turn the face is usually still there.
            result = self._acquire(rgb, last=self._frame or self._dropped)
        self._dropped = None
        if result is None:
            self._frame = self.seen = None
            return FrameFeatures.lost(len(CURVE_NAMES), len(POINT_NAMES))
        curves, self._frame, self._corr, self.seen = result.curves, result.frame, result.correction, result.seen
        self._count_tracked += 1
        if self._count_tracked % self.config.follow.check_every == 0:
            self._check_score()
        curves = self._filter(curves, result.frame, timestamp_ms)
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
            if frame is None or frame.unit < MIN_UNIT or any(same_frame(frame, f) for f in seen):
                continue
            seen.append(frame)
            self._light = M
            got = self._refine(rgb, [frame.compose(np.array([[s, 0.0, 0.0], [0.0, s, dy]]))
                                     for dy in CANDIDATE_SHIFTS for s in CANDIDATE_SCALES], last)
            if got is not None and (best is None or self._likeness(got, last) > self._likeness(best, last)):
                best, light = got, M
        self._light = light if light is None or best is None else self._fit_light(rgb, best.frame, light)
        if best is None or best.score < self.config.acquire.min_score:
            best = self._landmark_acquire(rgb)
        if best is None:
            return None
        if not self._calibrated:
            self._calibrated = True
            placed = self._calibrate_anchors(rgb, best.frame)
            if placed is not None:
                best = self._settle(rgb, placed) or best
        self._followed = best.frame.crop_matrix(self.config.measure.px)
        self._ref = self._grey(rgb, self._followed)
        self._unit_ref = best.frame.unit
        self._score = None
        return best

    def _fit_light(self, rgb: np.ndarray, frame: FaceFrame, M: np.ndarray) -> np.ndarray:
        """The light transform ``M`` scaled down where it would saturate the face: the crop's 99th percentile
        is kept at or below 230 (a stretch measured on the whole frame over-brightens a small face)."""
        crop = cv2.warpAffine(rgb, frame.crop_matrix(self.config.measure.px), self._size, flags=cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_REPLICATE)
        top = float(np.percentile(cv2.transform(crop, M), LIGHT_PERCENTILE))
        return M * min(1.0, LIGHT_TOP / max(top, 1.0))

    def _calibrate_anchors(self, rgb: np.ndarray, frame: FaceFrame) -> FaceFrame | None:
        """Move the eye anchors onto the eye blobs of a crop placed by the landmark backend's eyes (the layout's
        eyes on them); the face frame of that crop if they moved, else None. ``frame``: the frame acquired."""
        from facepuppet.capture.landmarks import MediaPipeConfig

        landmarker = shared_landmarker(self.config.landmarks.model, MediaPipeConfig(refine_scales=(),
                                                                                   tile_fractions=()))
        curves = None if landmarker is None else landmark_curves(landmarker, rgb)
        if curves is None:
            return None
        S = similarity_from_points(eye_centres_of(np.asarray(self.profile.layout)), eye_centres_of(curves))
        placed = FaceFrame(S[:, 2].copy(), S[:, 0].copy())
        if not same_frame(placed, frame, *SAME_FACE):
            return None                     # the backend's face is not the one acquired
        px = self.config.measure.px
        crop = cv2.warpAffine(rgb, placed.crop_matrix(px), self._size, flags=cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_REPLICATE)
        if self._light is not None:
            crop = cv2.transform(crop, self._light)
        C = self.intensity(crop)
        # The blobs' centres as a fixed point of the eye search (each search takes a few mean-shift steps).
        eyes = self._anchors_px[:2]
        for _ in range(ANCHOR_STEPS):
            ok, nxt = eye_centres(C, eyes, *self._eye_window)
            if not ok:
                return None
            eyes, step = nxt, np.abs(nxt - eyes).max()
            if step < ANCHOR_TOLERANCE:
                break
        cfg = self.config
        new = calibrated_anchors(self._anchors_px, eyes, px, scale_limits=cfg.landmarks.anchor_scale_limits,
                                 noise_floor=cfg.landmarks.anchor_noise_floor, gain=cfg.landmarks.anchor_calibration)
        if new is None:
            return None
        log.debug("eye anchors calibrated: %s -> %s face units", (self._anchors_px[:2] / px).round(3).tolist(),
                  (new[:2] / px).round(3).tolist())
        self._set_anchors(new)
        return placed

    def _landmark_acquire(self, rgb: np.ndarray):
        """The face frame placed on the eyes the landmark backend finds (no skin needed), refined on §3's eyes."""
        if not self.config.landmarks.enabled or self._landmarker is False:
            return None
        if self._landmark_wait > 0:
            self._landmark_wait -= 1
            return None
        if self._landmarker is None:
            self._landmarker = shared_landmarker(self.config.landmarks.model) or False
            if self._landmarker is False:
                return None
        curves = landmark_curves(self._landmarker, rgb)
        if curves is None:
            self._landmark_wait = self.config.landmarks.retry
            return None
        eyes = eye_centres_of(curves)
        S = similarity_from_points(np.asarray(self.profile.anchors)[:2], eyes)
        frame = FaceFrame(S[:, 2].copy(), S[:, 0].copy())
        if frame.unit < MIN_UNIT:
            return None
        # The mouth rectangle goes where the backend's mouth is (faces differ most in the eye-mouth distance).
        lips = [_IDX[n] for n in CURVE_NAMES if n.startswith("lip_")]
        M = frame.to_image()
        seen = (np.concatenate([bezier_points(c, CURVE_SAMPLES) for c in curves[lips]]).mean(axis=0) - M[:, 2]) \
            @ np.linalg.inv(M[:, :2]).T
        drawn = np.concatenate([bezier_points(c, CURVE_SAMPLES)
                                for c in np.asarray(self.profile.layout)[lips]]).mean(axis=0)
        self._mouth_offset = np.clip(seen - drawn, -MOUTH_OFFSET_LIMIT, MOUTH_OFFSET_LIMIT) * self.config.measure.px
        best = self._settle(rgb, frame)
        if best is None or best.score < self.config.landmarks.min_score:
            return None
        return best

    def _settle(self, rgb: np.ndarray, frame: FaceFrame):
        """Measure in a face frame the landmark backend placed (no skin needed): §3's eye search may only
        nudge it (the backend's eyes are trusted); the measurement's tuple, or None."""
        self._skinless_ok = True
        try:
            best = self._refine(rgb, [frame])
            if best is None or not same_frame(best.frame, frame):
                self._corr = np.array([1.0, 0.0, 0.0, 0.0])
                best = self._measure(rgb, frame, follow=True, gain=0.0)
                if best is not None:
                    best = replace(best, score=self._face_score(self.intensity_last, np.eye(2, 3)))
        finally:
            self._skinless_ok = False
        return best

    def _check_score(self) -> None:
        """Now and then, how much the followed crop still looks like a face (smoothed); drop the frame if not.

        Scored on the crop just measured, with the layout placed where the eyes put it.
        """
        score = self._face_score(*self._last_measured)
        self._score = score if self._score is None else 0.5 * (self._score + score)
        if self._score < self.config.follow.min_followed_score:
            log.debug("face lost: the followed crop no longer looks like a face (score %.2f)", self._score)
            self._frame, self._dropped = None, self._frame

    def _likeness(self, result, last: FaceFrame | None) -> float:
        """How much a measurement's crop looks like a face, less ``resize_cost`` per unit of log size change
        from ``last``, the frame the face was just lost in (if any)."""
        if last is None:
            return result.score
        return result.score - self.config.acquire.resize_cost * abs(np.log(result.frame.unit / last.unit))

    def _refine(self, rgb: np.ndarray, candidates: list[FaceFrame], last: FaceFrame | None = None):
        """Pull each candidate face frame onto the eyes; the result that looks most like a face (:meth:`_likeness`
        with ``last``), or None."""
        best = None
        for cand in candidates:
            result = None
            for step in range(REFINE_STEPS):
                result = self._measure(rgb, cand, follow=False, gain=1.0, outline=step == REFINE_STEPS - 1)
                if result is None:
                    break
                cand = result.frame
            if result is not None and result.eyes_found and (best is None or
                                                     self._likeness(result, last) > self._likeness(best, last)):
                best = result
        return best

    @property
    def crop_size(self) -> tuple[int, int]:
        """Width and height of the face crop, pixels."""
        return self._size

    @property
    def layout_in_crop(self) -> np.ndarray:
        """(C, 4, 2) the profile's layout placed on an unmoved face crop, crop pixels (a copy)."""
        return self._layout_px.copy()

    @property
    def feature_boxes(self) -> np.ndarray:
        """(len(BOX_NAMES), 4) int64 the feature rectangles of an unmoved face crop, crop pixels (a copy)."""
        return self._box_table.copy()

    def warmup(self, part: str) -> None:
        """Run one part of a frame's compiled work on blank inputs of the tracking types (numba compiles or loads
        its kernels; :mod:`~facepuppet.capture.color.precompile`). ``part``: one of :data:`WARMUP_PARTS`."""
        if part not in WARMUP_PARTS:
            raise ValueError(f"unknown warm-up part {part!r}; known: {', '.join(WARMUP_PARTS)}")
        w, h = self._size
        crop = np.zeros((h, w, 3), np.uint8)
        curves = np.ascontiguousarray(self._layout_px, dtype=np.float64)
        if part == "snakes":
            self._snakes(curves[_SNAKE_IDX], snake_fields(np.zeros((h, w), np.float32), SNAKE_BLUR))
            return
        C = self.intensity(crop)
        self.eye_centres(C)
        self._skin_ok(crop)
        self._boxes_now()
        lids = {"coef": np.zeros((2, PATCH_SIZE[0] * PATCH_SIZE[1])), "intercept": np.zeros(2)}
        apply_lid_model(curves.copy(), crop, lids)
        self._curve_filter(curves, 1 / 30)
        self._curve_filter(curves, 1 / 30)          # the first sample only starts the filter
        self._features(curves, (w, h))
        self._features(curves, (w, h))               # from the previous frame's pose

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
        if not self.config.filters.enabled:
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
        if self._net is not None and (self._count % self.config.measure.reestimate_every == 0):
            from facepuppet.capture.color.net import subarea_means

            self._weights = self._net.predict(subarea_means(crop, self.config.measure.px))
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
        Measurement or None
            None when the crop shows no face (no skin on the cheeks and little likeness to a face).
        """
        px = self.config.measure.px
        A = frame.crop_matrix(px)
        if follow and self._ref is not None:
            moved = self._follow(rgb, A)
            if moved is not None and SCALE_STEP[0] < moved.unit / frame.unit < SCALE_STEP[1]:
                frame = moved
                A = frame.crop_matrix(px)
        crop = cv2.warpAffine(rgb, A, self._size, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        if self._light is not None:
            crop = cv2.transform(crop, self._light)
        skin = self._skin_ok(crop)
        C = self.intensity(crop)
        eyes = self.eye_centres(C)
        # The eyes' correction of the followed frame (a similarity in crop pixels, as a, b, tx, ty), smoothed
        # over frames: the alignment on the whole face is steady, the eye search noisier but unbiased.
        smooth = follow and self._corr is not None
        corr = self._corr if smooth else np.array([1.0, 0.0, 0.0, 0.0])
        if eyes is not None:
            S_eye = similarity_of_pairs(self._anchors_px[:2], eyes)
            if SCALE_STEP[0] < float(np.hypot(S_eye[0, 0], S_eye[1, 0])) < SCALE_STEP[1]:
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
        if not skin and score < self.config.acquire.min_skinless_score and not self._skinless_ok:
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
        return Measurement(curves=curves, frame=measured, eyes_found=eyes is not None, score=score, correction=corr,
                           seen=(crop, A, placed) if outline else None)

    def _outlines(self, C: np.ndarray, crop: np.ndarray, layout: np.ndarray, boxes: np.ndarray,
                  unit: float) -> np.ndarray:
        """The curves (C, 4, 2) in crop pixels: §3.2's rules from the layout placed on the crop (``layout``),
        the lips refined as snakes, the lids by the performer's eyelid model if any, the lips, brows and eyes
        by the performer's shape models if any (which make the rules, the snakes and the eyelid model they
        replace needless). ``unit``: crop pixels per face unit."""
        curves_px = outline_features(C, raw=self._raw, value=self._value, layout=layout, boxes=boxes,
                                     blob_params=BLOB_PARAMS, unit=unit, mouth_reach=float(self.profile.mouth_reach),
                                     mouth_offset=self._mouth_offset, parts=self._parts)
        idx = _SNAKE_IDX
        if len(idx) and "mouth" in self._parts:
            # The snakes see the mouth rectangle and a margin (the fields are only computed there).
            h, w = C.shape
            m = SNAKE_MARGIN
            x0, y0, x1, y1 = boxes[_MOUTH_BOX]
            x0, y0, x1, y1 = max(x0 - m, 0), max(y0 - m, 0), min(x1 + m, w), min(y1 + m, h)
            if x1 - x0 > 2 * m and y1 - y0 > 2 * m:
                o = np.array([x0, y0], dtype=float)
                curves_px[idx] = self._snakes(curves_px[idx] - o, snake_fields(C[y0:y1, x0:x1], SNAKE_BLUR)) + o
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
        px = self.config.measure.px
        T = np.zeros(self._size[::-1], np.float32)
        L = self._layout_px
        for name in CURVE_NAMES:
            pts = np.round(bezier_points(L[_IDX[name]], CURVE_SAMPLES) * 4).astype(np.int32)
            cv2.polylines(T, [pts], False, 1.0, thickness=max(1, int(TEMPLATE_LINE * px)), lineType=cv2.LINE_AA,
                          shift=2)
        self._template = cv2.GaussianBlur(T, (0, 0), TEMPLATE_BLUR * px)
        self._template_box = _box_px(TEMPLATE_BOX, px)

    def eye_centres(self, C: np.ndarray) -> np.ndarray | None:
        """Eye centres (2, 2) in crop pixels of the contrast C (H, W) of a face crop, near the expected anchors
        (:func:`~facepuppet.capture.color.eye_anchors.eye_centres`), or None."""
        found, eyes = eye_centres(C, self._anchors_px, *self._eye_window)
        return eyes if found else None

    def _grey(self, rgb: np.ndarray, A: np.ndarray) -> np.ndarray:
        """The face crop of crop matrix ``A`` at ``follow_scale`` resolution, grey, float32 (for the alignment)."""
        w, h = self._size
        f = self.config.follow.scale
        small = cv2.warpAffine(rgb, A * f, (int(w * f), int(h * f)), flags=cv2.INTER_LINEAR,
                               borderMode=cv2.BORDER_REPLICATE)
        return cv2.cvtColor(small, cv2.COLOR_RGB2GRAY).astype(np.float32)

    def _follow(self, rgb: np.ndarray, A: np.ndarray) -> FaceFrame | None:
        """The face frame moved by aligning the face crop on the reference crop (ECC, affine).

        The search starts where the alignment put the face in the last frame, so a couple of steps suffice.
        """
        # First guess: the face where the alignment last put it (reference half-res crop -> current one).
        f = self.config.follow.scale
        guess = then_affine(cv2.invertAffineTransform(self._followed), A)
        guess[:, 2] *= f
        try:
            _, warp = cv2.findTransformECC(self._ref, self._grey(rgb, A), guess.astype(np.float32),
                                           cv2.MOTION_AFFINE, (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS,
                                                               self.config.follow.iterations, ECC_EPS), None, ECC_BLUR)
        except cv2.error:
            return None
        W = warp.astype(float)
        W[:, 2] /= f
        G = then_affine(W, cv2.invertAffineTransform(A))      # crop pixels -> image pixels, where the face is now
        self._followed = cv2.invertAffineTransform(G)
        px = self.config.measure.px
        return FaceFrame(G[:, :2] @ self._origin_px + G[:, 2], G[:, 0] * px)

    def _skin_ok(self, crop: np.ndarray) -> bool:
        """Whether the cheeks of the crop look like skin (the profile's skin model, over 30 % of the pixels)."""
        return skin_fraction(crop, self._cheek_boxes, self._skin_table) > SKIN_CHEEKS

    def _boxes_now(self) -> np.ndarray:
        """The feature rectangles (len(BOX_NAMES), 4) of this frame: moved with the layout's eyes (translation
        only; the mouth also by its offset), clipped to the crop. The cheeks stay where the frame puts them."""
        return move_boxes(self._box_table, _SHIFTED, _MOUTH_BOX, self._shift, self._mouth_offset, *self._size)
