"""The paper's colour tracker (§3): Eq. 1 intensity, blobs in anthropometric rectangles, Bezier snakes.

Per frame: the face frame of the last frame (or, when the face is lost, a fresh one from the skin model,
:mod:`.acquire`) gives a small upright crop of the face (rectangles follow translation, scale and roll; the crop
is first aligned on the acquisition's, :mod:`.follow`); Eq. 1 and the contrast C turn it into feature intensity
(:mod:`.transform`); a blob is grown in each feature's rectangle and the layout's curves moved onto it
(:mod:`.rules`), the lips refined as snakes (Eqs. 2-4, :mod:`.snakes`) against the head's up-vector
(:mod:`.outliner`); the eye blobs re-align the face frame for the next frame; the curves are smoothed
(:mod:`.smoothing`) and the head pose comes from the stable curve ends (roll and position) and the head's turn
(yaw and pitch, :mod:`.turn`: with a trained profile the look of the crop, with the built-in one the nose's tip
against the eyes).

Conventions: RGB uint8 frames; curves in image pixels (x right, y down); left and right are the performer's.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass

import cv2
import numpy as np

from facepuppet.capture.color.acquire import NO_CORRECTION, Acquirer
from facepuppet.capture.color.config import ColorTrackerConfig
from facepuppet.capture.color.eye_anchors import (
    EYE_TALL,
    EYE_TALL_LEVEL,
    OPENING_TABLE,
    eye_centres,
    eye_opening_centres,
    without_tall_runs,
)
from facepuppet.capture.color.face import (
    CROP_EXTENT,
    FEATURE_BOXES,
    FaceFrame,
    SkinModel,
    box_in_crop,
    far_correction,
    same_frame,
    scaled_about,
    similarity_of_pairs,
    turned_and_shifted,
)
from facepuppet.capture.color.follow import OWN_CHECKS, Follower, FollowState
from facepuppet.capture.color.glare import without_glare
from facepuppet.capture.color.jobs import wait_pending
from facepuppet.capture.color.likeness import FaceTemplate
from facepuppet.capture.color.measure import Measurement, Placement
from facepuppet.capture.color.outliner import Outliner
from facepuppet.capture.color.profile import GENERIC_LAYOUT, Profile, default_profile, load_profile
from facepuppet.capture.color.refind import LostFace
from facepuppet.capture.color.resample import FaceCrops, noise_ratio, read_ahead
from facepuppet.capture.color.rims import Rims
from facepuppet.capture.color.rules import BOX_NAMES, move_boxes
from facepuppet.capture.color.shape_models import FAMILIES
from facepuppet.capture.color.sides import evened_colours, evened_sides
from facepuppet.capture.color.smoothing import CurveSmoother
from facepuppet.capture.color.transform import feature_intensity, lip_hue_table, skin_fraction
from facepuppet.capture.color.turn import HeadTurn
from facepuppet.capture.curves import CURVE_NAMES, POINT_NAMES
from facepuppet.capture.features import FrameFeatures
from facepuppet.capture.pose import STABLE_FEATURES, estimate_pose, points_in_head, pose_point_index

__all__ = ["ColorTrackerConfig", "ColorTracker", "Measurement", "WARMUP_PARTS"]

log = logging.getLogger(__name__)

_IDX = {n: i for i, n in enumerate(CURVE_NAMES)}
#: The parts of a frame's work :meth:`ColorTracker.warmup` runs: all but the outline rules, and the snakes.
WARMUP_PARTS = ("frame", "snakes")

# Tuning constants                 unit                  what it does
SKIN_CHEEKS = 0.3                  # fraction              of the cheeks' pixels that must look like skin
SCALE_STEP = (0.8, 1.25)           # ratio                 size change one frame's alignment or eye search may make

_SHIFTED = np.array([not n.startswith("cheek") for n in BOX_NAMES])     # rectangles that follow the eyes
_MOUTH_BOX = BOX_NAMES.index("mouth")
_POSE_POINTS = pose_point_index(STABLE_FEATURES)         # the stable landmarks among the curve ends
_EYE2 = np.eye(2)
_CROP_ORIGIN = np.asarray(CROP_EXTENT[:2], dtype=float)
_CHEEK_L, _CHEEK_R = BOX_NAMES.index("cheek_left"), BOX_NAMES.index("cheek_right")
_EYE_L, _EYE_R = BOX_NAMES.index("eye_left"), BOX_NAMES.index("eye_right")


@dataclass
class _Intensity:
    """Eq. 1's weights and the last frame's feature images."""

    weights: np.ndarray                     # (4,) float32 Eq. 1's weights (on skin of a high enough value)
    dark: np.ndarray | None = None          # (4,) their counterpart for skin of a low value (the generic profile)
    count: int = 0                          # followed crops transformed (the network re-estimates every few)
    raw: np.ndarray | None = None           # (H, W) float32 Eq. 1's intensity
    C: np.ndarray | None = None             # (H, W) float32 the contrast C
    eyes: np.ndarray | None = None          # (H, W) float32 C as the eye search reads it (feature_intensity)
    value: np.ndarray | None = None         # (H, W) uint8 HSV value
    crop: np.ndarray | None = None          # (H, W, 3) uint8 the crop they were computed on


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
        self._intensity = _Intensity(np.asarray(profile.weights, dtype=np.float32), profile.dark_weights)
        self._net = None
        if profile.net:
            from facepuppet.capture.color.net import ColourNet

            self._net = ColourNet.from_arrays(profile.net)
        px = config.measure.px
        self._size = (int(round((CROP_EXTENT[2] - CROP_EXTENT[0]) * px)),
                      int(round((CROP_EXTENT[3] - CROP_EXTENT[1]) * px)))
        shift = _layout_shift(profile.layout)
        boxes = {k: box_in_crop(np.asarray(b) + np.r_[shift.get(k, (0, 0)), shift.get(k, (0, 0))], px)
                 for k, b in FEATURE_BOXES.items()}
        self._box_table = np.array([boxes[n] for n in BOX_NAMES], dtype=np.int64)
        self._cheek_boxes = self._box_table[[_CHEEK_L, _CHEEK_R]]
        self._eye_boxes = self._box_table[[_EYE_L, _EYE_R]]
        self._skin_table = profile.skin.table()
        generic_skin = SkinModel()
        self._generic_skin = None if profile.skin == generic_skin else generic_skin.table()
        self._eye_window = (int(round(config.measure.eye_window[0] * px)),
                            int(round(config.measure.eye_window[1] * px)))
        # A trained profile's anchors are where the mean shift lands on the performer's own frames, which
        # calibrates its bias on that face out; the generic anchors are average ones, so there the eye's opening
        # places the centre along the eye (eye_anchors module notes).
        self._eye_opening = not profile.net
        self._layout_px = (np.asarray(profile.layout) - CROP_EXTENT[:2]) * px
        anchors_px = np.asarray((np.asarray(profile.anchors) - CROP_EXTENT[:2]) * px, dtype=float)
        self._place = Placement(anchors_px, anchors_px[:2].mean(axis=0),
                                calibrated=config.landmarks.anchor_calibration <= 0)
        self._follow = FollowState(check_in=config.follow.check_every)
        self._rims = Rims()
        self._crops = FaceCrops(self._size, self._cheek_boxes)
        #: Fresh searches for the face (acquisitions) since the tracker was made or reset.
        self.searches = 0
        self._follower = Follower(self._size, px, config.follow, both_axes=self._eye_opening)
        #: (face crop, its crop matrix, the layout placed on it) of the last frame whose curves were measured:
        #: where the profile's shape models learn (:func:`~facepuppet.capture.color.train.train_profile`).
        self.seen: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._last_measured: tuple[np.ndarray, np.ndarray] | None = None    # (C, S_px) of the last measurement
        self._template = FaceTemplate(self._layout_px, self._size, px)
        self._outliner = Outliner(profile, config.measure)
        # The eyelid filter goes with the eyelid model (run with the eyes' rules only).
        self._smoother = CurveSmoother(config.filters, lids=bool(self._outliner.lids), shaped=np.concatenate(
            [FAMILIES[f] for f in sorted(self.profile.shapes)] or [np.zeros(0, int)]))
        self._acquirer = Acquirer(self, self._place, self._template, self._eye_window)
        self._turn = HeadTurn(profile.head, self._layout_px, px)

    # -- what other modules read -----------------------------------------------------------------------
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

    @property
    def anchors_px(self) -> np.ndarray:
        """(3, 2) the eye and nose anchors the face frame is aligned on, crop pixels (a copy)."""
        return self._place.anchors_px.copy()

    @property
    def parts(self) -> tuple[str, ...]:
        """The parts of §3.2's rules this tracker runs (the configured ones less those shape models replace)."""
        return self._outliner.parts

    @property
    def smoother(self) -> CurveSmoother:
        """The filters over time."""
        return self._smoother

    @property
    def intensity_last(self) -> np.ndarray | None:
        """The contrast C (H, W) float32 of the last crop transformed (:meth:`intensity`)."""
        return self._intensity.C

    # -- per frame -------------------------------------------------------------------------------------
    def track(self, rgb: np.ndarray, timestamp_ms: int) -> FrameFeatures:
        """Track one RGB frame (H, W, 3) uint8; see :class:`~facepuppet.capture.features.Tracker`."""
        rgb = np.ascontiguousarray(rgb)        # the compiled kernels' layout (a view of a larger frame is copied)
        if rgb.ndim == 2:
            rgb = cv2.cvtColor(rgb, cv2.COLOR_GRAY2RGB)
        if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
            raise ValueError(f"rgb must be an (H, W, 3) uint8 image, got shape {rgb.shape} dtype {rgb.dtype}")
        h, w = rgb.shape[:2]
        fol, cfg = self._follow, self.config.follow
        result = None
        if fol.frame is not None:
            result = self.measure(rgb, fol.frame, follow=True, gain=cfg.frame_gain / self._place.light_gain)
            fol.misses = 0 if result.eyes_found else fol.misses + 1
            if not fol.still_the_face(result.frame, self._follower.correlation, cfg, timestamp_ms):
                result = None
        followed = result is not None
        if result is None:
            # The face followed until now (or, for a while after it was lost, last followed) is searched near
            # where it was, at the size it had: after a blink, a turn or a hand passing, it is usually still there.
            result = self._acquire(rgb, timestamp_ms, last=fol.lost_face(timestamp_ms))
        if result is None:
            fol.drop(timestamp_ms)
            self.seen = None
            return FrameFeatures.lost(len(CURVE_NAMES), len(POINT_NAMES))
        curves, fol.frame, self.seen = result.curves, result.frame, result.seen
        # A face just found: its reference crop was taken in the corrected frame, so the correction starts afresh.
        fol.correction = result.correction if followed else np.array(NO_CORRECTION)
        if not followed:
            self._rims.restart()
        # Now and then whether the crop still looks like a face; a face found again first at the next frame it is
        # followed in (it may sit off the face: the brows taken for its eyes, say).
        fol.check_in = 1 if fol.found_again and not followed else fol.check_in - 1
        if fol.check_in <= 0:
            fol.check_in = cfg.check_every
            if not fol.still_like_a_face(self._template.score(*self._last_measured), cfg):
                fol.drop(timestamp_ms, doubted=True)
                self.seen = None
                return FrameFeatures.lost(len(CURVE_NAMES), len(POINT_NAMES))
        curves = self._smoother(curves, result.frame, timestamp_ms)
        return self._features(curves, (w, h), self._turn(timestamp_ms, rgb, self.seen))

    def reset(self) -> None:
        """Start a new take: every state the tracker keeps from frame to frame is set up again as a new
        tracker's with the same profile and config (the profile is not read again); the next frame's
        features are those a new tracker would give."""
        self.__init__(self.profile, config=self.config)

    def close(self) -> None:
        """Let go of the landmark backend (shared by the process's trackers: it stays open until exit)."""
        self._acquirer.landmarker = None

    def warmup(self, part: str) -> None:
        """Run one part of a frame's compiled work on blank inputs of the tracking types (numba compiles or loads
        its kernels; :mod:`~facepuppet.capture.color.precompile`). ``part``: one of :data:`WARMUP_PARTS`."""
        if part not in WARMUP_PARTS:
            raise ValueError(f"unknown warm-up part {part!r}; known: {', '.join(WARMUP_PARTS)}")
        w, h = self._size
        crop = np.zeros((h, w, 3), np.uint8)
        curves = np.ascontiguousarray(self._layout_px, dtype=np.float64)
        if part == "snakes":
            self._outliner.warmup_snakes(curves, (w, h))
            return
        noise_ratio(crop, np.eye(2, 3), self._cheek_boxes)
        read_ahead(crop, np.eye(2, 3), w, h)
        C = self.intensity(crop)
        self.eye_centres(C)
        self._template.score(C, np.eye(2, 3))
        self._skin_ok(crop)
        self._boxes_now()
        self._outliner.warmup_lids(curves, crop)
        for _ in range(2):      # the smoother's first sample only starts its filter; the second pose starts on one
            self._smoother.curve(curves, 1 / 30)
            self._features(curves, (w, h))

    def intensity(self, crop: np.ndarray, *, followed: bool = False) -> np.ndarray:
        """Eq. 1 and the contrast C on a face crop (H, W, 3) uint8 -> (H, W) float32 in [0, 1].

        Eq. 1's weights start at the profile's; with a trained profile the colour network re-estimates them on every
        ``measure.reestimate_every``-th crop of a ``followed`` face, and they move ``reestimate_gain`` of the way to
        its estimate (the light changes slowly, one crop's estimate moves with the expression); the generic ones go
        over to the dark skin's by each crop's cheeks (:func:`~.transform.dark_skin_weights`). A candidate of the
        search for the face is seen with the weights in use (the light is the last frame's), whatever the order the
        candidates are tried in. On a followed crop without colour the eye search reads a stronger C (``.eyes``).
        """
        it = self._intensity
        if self._net is not None and followed:
            m = self.config.measure
            if it.count % m.reestimate_every == 0:
                from facepuppet.capture.color.net import subarea_means

                estimate = self._net.predict(subarea_means(crop, m.px))
                it.weights = (it.weights + m.reestimate_gain * (estimate - it.weights)).astype(np.float32)
            it.count += 1
        it.crop = crop
        it.raw, it.C, it.value, it.eyes = feature_intensity(
            crop, it.weights.astype(np.float64), self._hue, self.profile.lip_hue.min_saturation,
            self._cheek_boxes, self._eye_boxes, grey_contrast=followed, dark=it.dark)
        return it.C

    def eye_centres(self, C: np.ndarray, anchors: np.ndarray | None = None, *, dark: bool = False) -> np.ndarray | None:
        """Eye centres (2, 2) in crop pixels of the contrast C (H, W) of the crop last transformed
        (:meth:`intensity`), near ``anchors`` (>= 2, 2) (default the expected anchors), or None: by the eye's
        opening (:func:`~facepuppet.capture.color.eye_anchors.eye_opening_centres`, its height by the darkness
        with ``dark``) on C without its tall runs down a column
        (:func:`~facepuppet.capture.color.eye_anchors.without_tall_runs`) with the generic profile, by the mean
        shift its anchors were learnt with (:func:`~facepuppet.capture.color.eye_anchors.eye_centres`) with a
        trained one."""
        anchors = self._place.anchors_px if anchors is None else np.asarray(anchors, dtype=float)
        if self._eye_opening:
            # The generic network's C lights the hair and the background beside the face as well.
            C = without_tall_runs(C, EYE_TALL_LEVEL, int(round(EYE_TALL * self.config.measure.px)))
            found, eyes = eye_opening_centres(C, self._intensity.crop, self._cheek_boxes, anchors,
                                              *self._eye_window, float(self.config.measure.px), OPENING_TABLE, dark)
        else:
            found, eyes = eye_centres(C, anchors, *self._eye_window)
        return eyes if found else None

    def measure(self, rgb: np.ndarray, frame: FaceFrame, *, follow: bool, gain: float, outline: bool = True,
                correction: np.ndarray | None = None, largest: float | None = None) -> Measurement | None:
        """Measure one RGB frame in the face frame ``frame``: with ``follow``, first align the crop on the
        reference and smooth the eyes' correction (the last frame's, or ``correction`` (4,) if given) with
        ``gain``; without ``outline``, only re-align the frame (the curves are None: the steps that only move a
        candidate frame do not need them). ``largest``, image pixels: the largest face size (eye-centre distance)
        the eyes may pull a frame not followed to (its scale kept under it about the eyes' midpoint).

        Returns
        -------
        Measurement or None
            None when, not following, the crop shows no face (no skin on the cheeks and little likeness to a face);
            when following, never None (the tracker weighs the evidence, :meth:`~.follow.FollowState.still_the_face`).
        """
        px = self.config.measure.px
        place = self._place
        A = frame.crop_matrix(px)
        if follow and rgb.flags.c_contiguous:
            read_ahead(rgb, cv2.invertAffineTransform(A), *self._size)     # the warps below find it in cache
        if follow and self._follower.ref is not None:
            # The frame the alignment puts the face in, or where it last put it: the frame given holds the
            # last eye correction, which is applied below.
            units = (SCALE_STEP[0] * frame.unit, SCALE_STEP[1] * frame.unit)
            frame = self._follower.follow(rgb, A, units) or self._follower.aligned()
            A = frame.crop_matrix(px)
        crop = self._crops(rgb, A, follow)                                      # large and noisy: by area
        if place.light is not None:
            crop = cv2.transform(crop, place.light)
        crop = evened_colours(crop, self._cheek_boxes)                          # two lights' colours: evened
        crop = evened_sides(crop, self._cheek_boxes)                            # light from one side: evened
        crop = without_glare(crop, self._cheek_boxes, self._eye_boxes, px)      # a lens's reflection: unknown
        crop = self._rims(crop, self._eye_boxes, px, follow)                   # glasses' rims: filled in
        skin = self._follow.skin = self._skin_ok(crop) and not place.skin_doubted
        C = self.intensity(crop, followed=follow)
        # The eyes' correction of the followed frame (a similarity in crop pixels, as a, b, tx, ty), smoothed
        # over frames: the alignment on the whole face is steady, the eye search noisier but unbiased. With the
        # generic profile the search starts where the last correction's turn and shift put the eyes (its size
        # left to the alignment: an eye search pulled outward would grow it without end), on the anchors if it
        # is far from the alignment (:func:`.face.far_correction`); a trained profile's anchors are where its
        # search lands when started on them (:mod:`.eye_anchors`), so it starts there.
        last_corr = correction if correction is not None else self._follow.correction
        smooth = follow and last_corr is not None
        held = smooth and self._eye_opening and not far_correction(last_corr)
        start = turned_and_shifted(place.anchors_px, last_corr) if held else None
        eyes = self.eye_centres(self._intensity.eyes, start, dark=follow)
        corr = last_corr if smooth else np.array(NO_CORRECTION)
        held_back = False
        if eyes is not None:
            S_eye = similarity_of_pairs(place.anchors_px[:2], eyes)
            step = float(np.hypot(S_eye[0, 0], S_eye[1, 0]))
            if SCALE_STEP[0] < step < SCALE_STEP[1]:
                held_back = largest is not None and not smooth and step * frame.unit > largest
                if held_back:
                    S_eye = scaled_about(S_eye, place.anchor_mid, largest / (step * frame.unit))
                v = np.array([S_eye[0, 0], S_eye[1, 0], S_eye[0, 2], S_eye[1, 2]])
                corr = corr + gain * (v - corr) if smooth else v
            else:
                eyes = None
        a, b, tx, ty = corr.tolist()
        S_px = np.array([[a, -b, tx], [b, a, ty]])
        scale = float(np.hypot(a, b))
        place.shift, place.scale = S_px[:, 2] + (S_px[:, :2] - _EYE2) @ place.anchor_mid, scale
        self._last_measured = (C, S_px)
        boxes = self._boxes_now()
        # How much the crop looks like a face: needed to pick among candidates (a followed face is judged by
        # its match with its own reference crop instead).
        score = 1.0 if follow else self._template.score(C, S_px)
        if not follow and not skin and score < self.config.acquire.min_skinless_score and not place.skinless_ok:
            return None
        curves = None
        if outline:
            placed = self._layout_px @ S_px[:, :2].T + S_px[:, 2]
            it = self._intensity
            curves_px = self._outliner(C, raw=it.raw, value=it.value, crop=crop, layout=placed, boxes=boxes,
                                       unit=px * scale, mouth_offset=place.mouth_offset)
            Ainv = cv2.invertAffineTransform(A)
            curves = curves_px @ Ainv[:, :2].T + Ainv[:, 2]                 # back to image pixels
        S = np.empty((2, 3))                                                  # S_px in face units
        S[:, :2] = S_px[:, :2]
        S[:, 2] = -S_px[:, :2] @ _CROP_ORIGIN + S_px[:, 2] / px + _CROP_ORIGIN
        measured = frame.compose(S)
        return Measurement(curves=curves, frame=measured, eyes_found=eyes is not None, score=score, correction=corr,
                           seen=(crop, A, placed) if outline else None, held_back=held_back)

    # -- internals -------------------------------------------------------------------------------------
    def _features(self, curves: np.ndarray, size: tuple[int, int], turn: np.ndarray | None = None) -> FrameFeatures:
        # The stable landmarks are the layout's, placed by the face frame (a similarity): they show the head's
        # roll, size and place but not a turn, so the pose is solved upright (estimate_pose, out_of_plane); the
        # turn (yaw, pitch) read by the profile's head-turn model or measured on the nose is put on it (.turn).
        uv = curves[_POSE_POINTS]
        pose = estimate_pose(uv, size, previous=self._follow.pose, out_of_plane=False)
        if not pose:
            pose = estimate_pose(uv, size, out_of_plane=False)
        self._follow.pose = pose if pose else None
        if pose and turn is not None:
            pose = self._turn.posed(pose, turn, curves)
        if pose:
            points = points_in_head(curves, pose)
            return FrameFeatures(True, curves, pose.rotation, pose.translation, points)
        nan = np.nan
        return FrameFeatures(True, curves, np.full((3, 3), nan), np.full(3, nan), np.full((len(POINT_NAMES), 3), nan))

    def _skin_ok(self, crop: np.ndarray) -> bool:
        """Whether the cheeks of the crop look like skin (over :data:`SKIN_CHEEKS` of the pixels) to the profile's
        skin model or the generic one (a profile's model is one performer's skin in one light)."""
        if skin_fraction(crop, self._cheek_boxes, self._skin_table) > SKIN_CHEEKS:
            return True
        generic = self._generic_skin
        return generic is not None and skin_fraction(crop, self._cheek_boxes, generic) > SKIN_CHEEKS

    def _boxes_now(self) -> np.ndarray:
        """The feature rectangles (len(BOX_NAMES), 4) of this frame: moved with the layout's eyes (the mouth also
        by its offset, and grown with the eyes), clipped to the crop. The cheeks stay where the frame puts them."""
        return move_boxes(self._box_table, _SHIFTED, _MOUTH_BOX, self._place.shift, self._place.mouth_offset,
                          self._place.scale, self._place.anchor_mid, *self._size)

    def _acquire(self, rgb: np.ndarray, ms: int, last: LostFace | None = None) -> Measurement | None:
        """Find the face afresh in the frame of time ``ms`` (:meth:`~.acquire.Acquirer.find`; ``last``: the face
        just lost, if any), the filters and the alignment restarted. A face found again keeps its size reference
        (it was found at about that size, :mod:`.refind`), and until it has passed its first checks the last face
        that did stays the one to search near (:meth:`.FollowState.found`); one found where it was lost takes its
        likeness there as its own, unless it was lost because it no longer looked like a face."""
        fol = self._follow
        self.searches += 1
        self._smoother.reset()
        fol.pose = None
        self._turn.restart()
        self._place.mouth_offset, fol.misses, fol.correction = np.zeros(2), 0, None
        self._follower.reset()
        best = self._acquirer.find(rgb, last)
        if best is None:
            return None
        fol.found_again = OWN_CHECKS if last is not None else 0
        fol.found(last, ms)
        if last is not None and fol.score_ref is not None and same_frame(best.frame, last.frame) and not fol.doubted:
            fol.score_ref = min(fol.score_ref, best.score)      # found where it was: that is how it looks now
        fol.doubted = False
        self._follower.start(rgb, best.frame)
        fol.unit_ref = best.frame.unit if last is None else fol.unit_ref
        fol.skin_found = self._skin_ok(best.seen[0])
        fol.score = None
        return best


def _layout_shift(layout: np.ndarray) -> dict[str, np.ndarray]:
    """How far (face units) each feature of ``layout`` sits off the generic layout's, per rectangle name."""
    d = np.asarray(layout) - GENERIC_LAYOUT
    g = lambda *names: d[[_IDX[n] for n in names]].reshape(-1, 2).mean(0)  # noqa: E731
    return {
        "brow_left": g("brow_left"), "brow_right": g("brow_right"),
        "eye_left": g("eye_left_upper", "eye_left_lower"), "eye_right": g("eye_right_upper", "eye_right_lower"),
        "nose": g("nostril_left", "nostril_right"),
        "mouth": g("lip_upper_outer", "lip_lower_outer"),
    }
