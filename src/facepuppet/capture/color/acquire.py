"""Finding the face afresh (§3.1): skin regions and eye holes and the face cascade's windows, candidate face frames
pulled onto the eyes, the light they are seen in; where no skin is seen, the cascade's windows alone, and where
they fail too, the landmark backend's eyes; once, the eye anchors calibrated on them.

:class:`Acquirer` does it for a :class:`~facepuppet.capture.color.tracker.ColorTracker` through the tracker's
public measurement (:class:`Measurer`) and the :class:`~facepuppet.capture.color.measure.Placement` they share.

Conventions: face frames in image pixels (:class:`~facepuppet.capture.color.face.FaceFrame`); a face unit is
the eye-centre distance; crop pixels are ``px`` per face unit.
"""

from __future__ import annotations

import logging
from dataclasses import replace
from typing import Protocol

import cv2
import numpy as np

from facepuppet.capture.color.config import ColorTrackerConfig
from facepuppet.capture.color.detect import FaceWindow, face_windows, search_area
from facepuppet.capture.color.eye_anchors import eye_centres_of
from facepuppet.capture.color.eye_calibration import calibrated_anchors, landmark_curves, shared_landmarker
from facepuppet.capture.color.face import (
    FaceFrame,
    SkinModel,
    box_in_crop,
    find_face,
    light_balance,
    same_frame,
    similarity_from_points,
    skin_probability,
)
from facepuppet.capture.color.likeness import FaceTemplate
from facepuppet.capture.color.measure import Measurement, Placement
from facepuppet.capture.color.profile import Profile
from facepuppet.capture.color.refind import LOST_REACH, LostFace, likeness
from facepuppet.capture.color.transform import skin_fraction
from facepuppet.capture.color.white_lit import skin_light
from facepuppet.capture.curves import CURVE_NAMES, bezier_points

__all__ = ["Acquirer", "Measurer", "CANDIDATE_SHIFTS", "CANDIDATE_SCALES", "LIGHT_PERCENTILE", "LIGHT_TOP",
           "MOUTH_OFFSET_LIMIT", "MIN_UNIT", "LOST_REACH", "GLABELLA", "GLABELLA_SKIN", "REFINE_STEPS", "REFINE_SIZES",
           "REFINE_TURN", "WINDOW_REACH",
           "SAME_FACE", "SAME_ROLL", "WINDOW_SIZE_COST", "ANCHOR_STEPS", "ANCHOR_TOLERANCE",
           "candidate_frames", "fit_light", "likeness", "mouth_offset", "skin_between_brows"]

log = logging.getLogger(__name__)

# Tuning constants                      unit          what it does
CANDIDATE_SHIFTS = (0.0, 0.35, -0.35)   # face units    vertical shifts of a skin region's candidate frames
CANDIDATE_SCALES = (1.0, 0.8, 1.25)     # ratio         sizes of a skin region's candidate frames
LIGHT_PERCENTILE = 99.0                 # percentile    of the face crop the light transform keeps ...
LIGHT_TOP = 230.0                       # 8-bit level   ... at or below this (no saturated face)
MOUTH_OFFSET_LIMIT = 0.3                # face units    farthest the backend's mouth moves the mouth rectangle
MOUTH_SAMPLES = 16                      # points        along each lip curve averaged for the mouth's place
MIN_UNIT = 6                            # image pixels  smallest face (eye-centre distance) tracked
REFINE_STEPS = 3                        # steps         eye-search steps pulling a candidate onto the eyes
REFINE_SIZES = (0.8, 1.25)              # ratio         sizes the eye search may pull a candidate to, of its own
REFINE_TURN = np.radians(20.0)          # radians       most the eye search may turn a candidate no window holds
#: Largest size (ratio of the window's face size, :attr:`~.detect.FaceWindow.unit`) the eye search may pull a
#: candidate a cascade window holds to: the windows of the shared performers' first frames, as filmed and in the
#: light of a lamp above, beside or of two colours, put the face at 0.85-1.15 of MediaPipe's eye distance. The eye
#: search's runaway pull is outward (lashes' tails, an eyeliner's wing, the hair beside an eye lit against the
#: face); on its way to the eyes it may pass under a window's size (performer_c in glasses: 0.78 of it, then 0.92).
WINDOW_REACH = 1.15
SAME_FACE = (0.25, 0.2)                 # face units, log size: the landmark backend's face is the one acquired
ANCHOR_STEPS = 4                        # steps         most eye searches to find the eye blobs' fixed point
ANCHOR_TOLERANCE = 0.25                 # crop pixels   step below which the fixed point is found
WINDOW_SIZE_COST = 0.6                  # per log size  likeness a candidate loses off the size of its window's face
SAME_ROLL = 0.1                         # radians       candidates closer in roll (and in place and size) are one
WINDOW_SKIN = 0.3                       # fraction      of a window's middle looking like skin (below: likeness decides)
#: Between the brows, above the eyes (face units x0, y0, x1, y1): skin on every face, never on a skin-coloured
#: object whose dark surroundings the eye search took for eyes.
GLABELLA = (-0.1, -0.5, 0.1, -0.1)
GLABELLA_SKIN = 0.3                     # fraction      of the glabella's pixels that must look like skin
CASCADE_EVERY = 5                       # frames        while no face is found, the whole frame's cascade runs once in
#: The eyes' correction of a frame that keeps it as it is (a, b, tx, ty).
NO_CORRECTION = (1.0, 0.0, 0.0, 0.0)

_LIPS = [i for i, n in enumerate(CURVE_NAMES) if n.startswith("lip_")]


def candidate_frames(frame: FaceFrame) -> list[FaceFrame]:
    """The face frames tried on a skin region's frame: shifted up and down, smaller and larger."""
    return [frame.compose(np.array([[s, 0.0, 0.0], [0.0, s, dy]]))
            for dy in CANDIDATE_SHIFTS for s in CANDIDATE_SCALES]


def fit_light(rgb: np.ndarray, frame: FaceFrame, M: np.ndarray, px: float, size: tuple[int, int]) -> np.ndarray:
    """The light transform ``M`` (3, 3) scaled down where it would saturate the face: the face crop's
    :data:`LIGHT_PERCENTILE` is kept at or below :data:`LIGHT_TOP` (a stretch measured on the whole frame
    over-brightens a small face)."""
    crop = cv2.warpAffine(rgb, frame.crop_matrix(px), size, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    top = float(np.percentile(cv2.transform(crop, M), LIGHT_PERCENTILE))
    return M * min(1.0, LIGHT_TOP / max(top, 1.0))


def mouth_offset(curves: np.ndarray, frame: FaceFrame, layout: np.ndarray, px: float) -> np.ndarray:
    """Crop pixels (2,) the mouth of the landmark backend's curves (C, 4, 2, image pixels) sits off the layout's
    (C, 4, 2, face units) in face frame ``frame``, each axis at most :data:`MOUTH_OFFSET_LIMIT` face units (faces
    differ most in the eye-mouth distance)."""
    M = frame.to_image()
    seen = (np.concatenate([bezier_points(c, MOUTH_SAMPLES) for c in curves[_LIPS]]).mean(axis=0) - M[:, 2]) \
        @ np.linalg.inv(M[:, :2]).T
    drawn = np.concatenate([bezier_points(c, MOUTH_SAMPLES) for c in np.asarray(layout)[_LIPS]]).mean(axis=0)
    return np.clip(seen - drawn, -MOUTH_OFFSET_LIMIT, MOUTH_OFFSET_LIMIT) * px


def skin_between_brows(crop: np.ndarray, skins: list[SkinModel], px: float) -> bool:
    """Whether a face crop (H, W, 3) uint8 of ``px`` pixels per face unit shows skin between the brows
    (:data:`GLABELLA`, over :data:`GLABELLA_SKIN` of its pixels) to any of the skin models ``skins``.

    An acquisition candidate without it is judged as one whose cheeks show no skin (it needs the likeness
    ``acquire.min_skinless_score``): the eye search may take the dark scene above a skin-coloured object's edge
    for a pair of eyes, with the object's skin below them where the cheeks are.
    """
    box = np.array([box_in_crop(GLABELLA, px)], dtype=np.int64)
    return any(skin_fraction(crop, box, s.table()) > GLABELLA_SKIN for s in skins)


def _middle(rgb: np.ndarray, win: FaceWindow) -> np.ndarray:
    """The middle half (each way, upright) of a window, (h, w, 3) (empty where it lies outside the frame)."""
    w = h = win.width
    back = cv2.invertAffineTransform(win.to_box)
    bx, by, bw, bh = (float(v) for v in win.box)
    cx, cy = back[:, :2] @ [bx + bw / 2.0, by + bh / 2.0] + back[:, 2]
    x, y = cx - w / 2.0, cy - h / 2.0
    H, W = rgb.shape[:2]
    x0, x1 = int(max(0, x + 0.25 * w)), int(min(W, x + 0.75 * w))
    y0, y1 = int(max(0, y + 0.25 * h)), int(min(H, y + 0.75 * h))
    return np.ascontiguousarray(rgb[y0:max(y1, y0), x0:max(x1, x0)])


def _skin_share(rgb: np.ndarray, win: FaceWindow, skin) -> float:
    """Share of the middle half (each way, upright) of a window the skin model takes for skin."""
    middle = _middle(rgb, win)
    return float((skin_probability(middle, skin) > 0).mean()) if middle.size else 0.0


def _same_roll(a: FaceFrame, b: FaceFrame) -> bool:
    """Whether two face frames' rolls are within :data:`SAME_ROLL` of each other."""
    return abs(b.turn_to(a)) < SAME_ROLL


class Measurer(Protocol):
    """What :class:`Acquirer` needs of the tracker."""

    profile: Profile
    config: ColorTrackerConfig

    @property
    def crop_size(self) -> tuple[int, int]: ...

    @property
    def intensity_last(self) -> np.ndarray | None: ...

    def intensity(self, crop: np.ndarray, *, followed: bool = False) -> np.ndarray: ...

    def eye_centres(self, C: np.ndarray, anchors: np.ndarray | None = None) -> np.ndarray | None: ...

    def measure(self, rgb: np.ndarray, frame: FaceFrame, *, follow: bool, gain: float, outline: bool = True,
                correction: np.ndarray | None = None, largest: float | None = None) -> Measurement | None: ...


class Acquirer:
    """Finds the face afresh for one tracker.

    Parameters
    ----------
    tracker : Measurer
        The tracker whose measurement scores the candidates.
    place : Placement
        The placement the tracker measures with (its light, mouth offset and anchors are set here).
    template : FaceTemplate
        The layout drawn as a face (the likeness of a frame the landmark backend placed).
    eye_window : (int, int)
        Half width and half height (crop pixels) of the eye search's window.
    """

    def __init__(self, tracker: Measurer, place: Placement, template: FaceTemplate, eye_window: tuple[int, int]):
        self.tracker = tracker
        self.place = place
        self.template = template
        self.eye_window = eye_window
        self.landmarker = None          # the shared landmark backend, once needed (False: not available)
        self.landmark_wait = 0          # frames to wait before asking the landmark backend again
        self.cascade_wait = 0           # frames to wait before the whole frame's cascade runs again

    def find(self, rgb: np.ndarray, last: LostFace | None = None) -> Measurement | None:
        """The measurement of the candidate frame that looks most like a face, or None.

        ``last``: the face, if it was just lost. Its last frame, and that frame at the size the face had, are
        candidates too, in the light it was followed in; a candidate where it cannot be now is none
        (:func:`~.refind.likeness`). The search runs near it first (:func:`~.detect.search_area`: the skin
        regions and the cascade's windows there), and over the whole frame only if no face is found near it.
        """
        cfg = self.tracker.config
        last_light = self.place.light
        best = None
        if last is not None:
            best = self._search(rgb, last, last_light, search_area(last.frame, rgb.shape))
            if best is None or best.score < cfg.acquire.min_score:
                best = None
                self.place.light = last_light
        if best is None:
            best = self._search(rgb, last, last_light, None)
            found = best is not None and best.score >= cfg.acquire.min_score
            self.cascade_wait = 0 if found else (self.cascade_wait or CASCADE_EVERY - 1)
        if best is None or best.score < cfg.acquire.min_score:
            best = self._landmark_acquire(rgb)
        if best is None:
            return None
        if not self.place.calibrated:
            self.place.calibrated = True
            placed = self._calibrate_anchors(rgb, best.frame)
            if placed is not None:
                best = self._settle(rgb, placed) or best
        return best

    def _search(self, rgb: np.ndarray, last: LostFace | None, last_light: np.ndarray | None,
                roi: tuple[int, int, int, int] | None) -> Measurement | None:
        """The best candidate of the whole frame or of its part ``roi`` (x0, y0, x1, y1), the light it is seen
        in left in the placement; or None."""
        place, cfg = self.place, self.tracker.config
        # Skin regions of the frame as filmed and of the frame with its light's colour and level evened out
        # (a warm, cool or dim light moves skin out of the skin model, or other things into it), by the profile's
        # skin model and by the generic one (the profile's is one performer's skin in one light). The light of
        # the hypothesis that looks most like a face is kept: the crops are evened out the same way until the
        # face is lost.
        best, light, seen = None, None, []
        skins = [self.tracker.profile.skin]
        skins += [SkinModel()] if skins[0] != SkinModel() else []
        hypotheses, lights = [], []
        for M in (None, light_balance(rgb)):
            shown = rgb if M is None else cv2.transform(rgb, M)
            lights.append((M, shown))
            for skin in skins:
                frame = find_face(shown, skin, roi=roi)
                if frame is not None:
                    hypotheses.append((M, frame, False))
        # Windows with a face's pattern of dark features, upright or tilted: candidates of their own, and the
        # support a candidate needs in a scene the skin model cannot tell from skin. Where a skin model finds some
        # skin region (skin-coloured scenes included), a window whose middle looks like skin (in the frame as
        # filmed or with its light evened out: a cool or dim light moves a face's skin out of the skin model) is
        # tried in the light its skin shows most in. One whose middle looks like skin in neither (a face and a wall
        # of its colour in one strongly coloured light: as filmed the face lies outside the skin model, evened out
        # over the frame it turns grey with the wall) is tried in both and in the light that gives its middle an
        # average skin's colour (:func:`~.white_lit.skin_light`), and its candidates are crops without skin in all
        # three (the made light gives their cheeks skin's colour by construction): they need the likeness of a crop
        # without skin (``acquire.min_skinless_score``) at each step of the eye search. Where no skin model finds
        # any skin (a monochrome or infrared camera, black-and-white footage), every window is taken in the
        # evened-out light (a grey frame's levels stretched), and its candidates need that likeness like any
        # other. Not when a landmark model is given explicitly (it places the faces the skin model misses).
        skinless = not hypotheses
        use = cfg.acquire.cascade and cfg.landmarks.model is None
        if use and roi is None:
            # Over the whole frame the cascade costs most (all its passes run where it finds no face): while no
            # face is found it runs every CASCADE_EVERY frames only.
            use, self.cascade_wait = self.cascade_wait <= 0, max(self.cascade_wait - 1, 0)
        windows = []
        for win in face_windows(rgb, roi) if use else []:
            windows.append(win)
            if skinless:
                hypotheses.append((lights[-1][0], win.frame(), False))
                continue
            share, M = max(((max(_skin_share(x, win, k) for k in skins), i) for i, (_, x) in enumerate(lights)))
            if share >= WINDOW_SKIN:
                hypotheses.append((lights[M][0], win.frame(), False))
                continue
            own = skin_light(_middle(rgb, win))
            hypotheses += [(m, win.frame(), True) for m, _ in lights]
            hypotheses += [(own, win.frame(), True)] if own is not None else []
        if last is not None:
            hypotheses[:0] = [(last_light, last.frame, False), (last_light, last.at_its_size(), False)]

        def value(result: Measurement) -> float:
            return self.value(result, last, windows)

        # A place already tried is not tried again, unless it is a window without skin's in another light.
        for M, frame, unlit in hypotheses:
            if frame.unit < MIN_UNIT or any(same_frame(frame, f) and _same_roll(frame, f) and (m is M or not unlit)
                                            for m, f in seen):
                continue
            seen.append((M, frame))
            place.light, place.skin_doubted = M, unlit
            try:
                got = self.refine(rgb, candidate_frames(frame), last, windows)
            finally:
                place.skin_doubted = False
            if got is None or (unlit and got.score < cfg.acquire.min_skinless_score):
                continue
            if best is None or value(got) > value(best):
                best, light = got, M
        place.light = (light if light is None or best is None
                       else fit_light(rgb, best.frame, light, cfg.measure.px, self.tracker.crop_size))
        return best

    def value(self, result: Measurement, last: LostFace | None = None, windows: list[FaceWindow] = ()) -> float:
        """How much a candidate looks like the face sought: :func:`likeness` with ``last`` (a face just lost found
        again larger only where a window holds it), less
        ``acquire.unsupported_cost`` when the cascade found windows but none holds it
        (:meth:`~.detect.FaceWindow.holds`: it is not where a window's face is, or not of its size) or its eyes
        pulled it past the window's reach (:attr:`~.measure.Measurement.held_back`: its eyes are not the window
        face's), else less
        :data:`WINDOW_SIZE_COST` per unit of absolute log size change from the face of the window holding it that
        fits best (:attr:`~.detect.FaceWindow.unit`: the window's size is the surest size of a face just found,
        the eye search may take the brows or nostrils for the eyes); a candidate no window holds pays that too
        for the windows its middle lies in (:meth:`~.detect.FaceWindow.contains`: a face a window sees, found at
        another size)."""
        cfg = self.tracker.config.acquire
        held = [w for w in windows if w.holds(result.frame)]
        near = held or [w for w in windows if w.contains(result.frame)]
        off = min((abs(np.log(result.frame.unit / w.unit)) for w in near), default=0.0)
        lost = bool(windows) and (not held or result.held_back)
        return (likeness(result, last, cfg.resize_cost, held=bool(held))
                - (cfg.unsupported_cost if lost else 0.0) - WINDOW_SIZE_COST * off)

    def refine(self, rgb: np.ndarray, candidates: list[FaceFrame], last: LostFace | None = None,
               windows: list[FaceWindow] = ()) -> Measurement | None:
        """Pull each candidate face frame onto the eyes; the result of most :meth:`value` (with ``last`` and the
        cascade's ``windows``; none a face just lost cannot move to, none the eye search pulled outside
        :data:`REFINE_SIZES` of the candidate's size: a face's brows and mouth taken for its eyes, nor turned by more
        than :data:`REFINE_TURN` unless a cascade window holds it: an eye and a brow, an ear or the hair beside a
        turned head; a window's face is a face, and a window of a copy turned the other way may hold an upright
        one; none under ``acquire.min_skinless_score`` without skin between the brows (:func:`skin_between_brows`)
        unless a window holds it: a face in a dim or cool light shows the skin models none, and a pair of glasses'
        rims lower its likeness), or None. Where no face was just lost, the eye search pulls a candidate a window
        holds to at most :data:`WINDOW_REACH` times the window's face size: an eyeliner's wing or the hair's edge
        beside an eye, taken for the eye's outer side, draws the eyes apart at each step, and the frame would grow
        past the face."""
        skinless = self.tracker.config.acquire.min_skinless_score

        def held(result: Measurement) -> bool:
            return any(w.holds(result.frame) for w in windows)

        best = None
        for cand in candidates:
            result, start = None, cand
            # A face found afresh: within reach of every window holding it (a face just lost is found again near
            # its own size, :func:`likeness`).
            units = [w.unit for w in windows if w.holds(cand)] if last is None else []
            largest = WINDOW_REACH * min(units) if units else None
            for step in range(REFINE_STEPS):
                result = self.tracker.measure(rgb, cand, follow=False, gain=1.0, outline=step == REFINE_STEPS - 1,
                                              largest=largest)
                if result is None or not result.eyes_found:
                    break               # without eyes the frame stays put: each further step would repeat this one
                cand = result.frame
            if result is None or not result.eyes_found or not np.isfinite(self.value(result, last, windows)):
                continue
            if not REFINE_SIZES[0] <= result.frame.unit / start.unit <= REFINE_SIZES[1]:
                continue
            if abs(start.turn_to(result.frame)) > REFINE_TURN and not held(result):
                continue
            if not self.place.skinless_ok and result.score < skinless and not held(result) and \
                    not skin_between_brows(result.seen[0], [self.tracker.profile.skin, SkinModel()],
                                           self.tracker.config.measure.px):
                continue
            if best is None or self.value(result, last, windows) > self.value(best, last, windows):
                best = result
        return best

    def _calibrate_anchors(self, rgb: np.ndarray, frame: FaceFrame) -> FaceFrame | None:
        """Move the eye anchors onto the eye blobs of a crop placed by the landmark backend's eyes (the layout's
        eyes on them); the face frame of that crop if they moved, else None. ``frame``: the frame acquired."""
        from facepuppet.capture.landmarks import MediaPipeConfig

        cfg = self.tracker.config
        lm = cfg.landmarks
        landmarker = shared_landmarker(lm.model, MediaPipeConfig(refine_scales=(), tile_fractions=()))
        curves = None if landmarker is None else landmark_curves(landmarker, rgb)
        if curves is None:
            return None
        S = similarity_from_points(eye_centres_of(np.asarray(self.tracker.profile.layout)), eye_centres_of(curves))
        placed = FaceFrame(S[:, 2].copy(), S[:, 0].copy())
        if not same_frame(placed, frame, *SAME_FACE):
            return None                     # the backend's face is not the one acquired
        px = cfg.measure.px
        crop = cv2.warpAffine(rgb, placed.crop_matrix(px), self.tracker.crop_size, flags=cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_REPLICATE)
        if self.place.light is not None:
            crop = cv2.transform(crop, self.place.light)
        C = self.tracker.intensity(crop)
        # The blobs' centres as a fixed point of the eye search (each search takes a few mean-shift steps).
        old = self.place.anchors_px
        eyes = old[:2]
        for _ in range(ANCHOR_STEPS):
            nxt = self.tracker.eye_centres(C, eyes)
            if nxt is None:
                return None
            eyes, step = nxt, np.abs(nxt - eyes).max()
            if step < ANCHOR_TOLERANCE:
                break
        new = calibrated_anchors(old, eyes, px, scale_limits=lm.anchor_scale_limits,
                                 noise_floor=lm.anchor_noise_floor, gain=lm.anchor_calibration)
        if new is None:
            return None
        log.debug("eye anchors calibrated: %s -> %s face units", (old[:2] / px).round(3).tolist(),
                  (new[:2] / px).round(3).tolist())
        self.place.set_anchors(new)
        return placed

    def _landmark_acquire(self, rgb: np.ndarray) -> Measurement | None:
        """The face frame placed on the eyes the landmark backend finds (no skin needed), refined on §3's eyes."""
        cfg = self.tracker.config
        lm = cfg.landmarks
        if not lm.enabled or self.landmarker is False:
            return None
        if self.landmark_wait > 0:
            self.landmark_wait -= 1
            return None
        if self.landmarker is None:
            self.landmarker = shared_landmarker(lm.model) or False
            if self.landmarker is False:
                return None
        curves = landmark_curves(self.landmarker, rgb)
        if curves is None:
            self.landmark_wait = lm.retry
            return None
        eyes = eye_centres_of(curves)
        S = similarity_from_points(np.asarray(self.tracker.profile.anchors)[:2], eyes)
        frame = FaceFrame(S[:, 2].copy(), S[:, 0].copy())
        if frame.unit < MIN_UNIT:
            return None
        # The mouth rectangle goes where the backend's mouth is.
        self.place.mouth_offset = mouth_offset(curves, frame, self.tracker.profile.layout, cfg.measure.px)
        best = self._settle(rgb, frame)
        if best is None or best.score < lm.min_score:
            return None
        return best

    def _settle(self, rgb: np.ndarray, frame: FaceFrame) -> Measurement | None:
        """Measure in a face frame the landmark backend placed (no skin needed): §3's eye search may only
        nudge it (the backend's eyes are trusted); the measurement, or None."""
        self.place.skinless_ok = True
        try:
            best = self.refine(rgb, [frame])
            if best is None or not same_frame(best.frame, frame):
                best = self.tracker.measure(rgb, frame, follow=True, gain=0.0, correction=np.array(NO_CORRECTION))
                if best is not None:
                    best = replace(best, score=self.template.score(self.tracker.intensity_last, np.eye(2, 3)))
        finally:
            self.place.skinless_ok = False
        return best
