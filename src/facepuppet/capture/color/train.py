"""Training a performer profile of the colour tracker from labelled frames (§3.1): :func:`train_profile`.

Labels are feature curves in image pixels (CURVE_NAMES order), for example from the MediaPipe backend. From
them: the face frame of each frame (eye centres = midpoints of the eye corners), the performer's mean layout in
face units, the skin colour, the lips' hue, and for the colour network (inputs: :func:`subarea_means`) its
training targets, the Fisher weights that best separate the labelled feature pixels from skin
(:func:`~facepuppet.capture.color.net.separating_weights`), on the frames as filmed and on copies relit darker,
brighter, warmer and cooler, so the network learns how the best weights move with the light.
"""

from __future__ import annotations

import logging
from dataclasses import replace

import cv2
import numpy as np

from facepuppet.capture.color import head_turn
from facepuppet.capture.color.config import ColorTrackerConfig
from facepuppet.capture.color.face import CROP_EXTENT, FaceFrame, SkinModel, similarity_of_pairs
from facepuppet.capture.color.net import SUBAREAS, ColourNet, separating_weights, subarea_means
from facepuppet.capture.color.profile import Profile, default_profile
from facepuppet.capture.color.shape_models import FAMILIES, JITTER, fit_shape_model, training_pairs
from facepuppet.capture.color.tracker import ColorTracker
from facepuppet.capture.color.transform import LipHue, channels, lip_hue_table
from facepuppet.capture.curves import CURVE_NAMES, bezier_points
from facepuppet.errors import FacepuppetError

__all__ = ["train_profile", "label_frame", "to_face_units", "relight", "feature_and_skin_masks", "face_crop",
           "mouth_reach_of"]

log = logging.getLogger(__name__)

_IDX = {n: i for i, n in enumerate(CURVE_NAMES)}

#: Ranges of the training copies' gain, warmth t (R scaled by 1 + t, B by 1 - t) and gamma.
RELIGHT = ((0.45, 1.3), (-0.3, 0.3), (0.8, 1.25))

# Tuning constants                          unit          what it does
TRAIN_PX = 48.0                             # crop px/unit  resolution of the training crops
MIN_LABEL_UNIT = 6                          # image pixels  smallest labelled face (eye-centre distance) used
MIN_MASK_PIXELS = 10                        # pixels        fewest feature and skin pixels of a usable frame
BROW_LINE = 0.08                            # face units    thickness of a labelled brow as feature pixels
LID_LINE = 0.05                             # face units    thickness of a labelled upper lid as feature pixels
MASK_SAMPLES = 16                           # points        along each labelled curve drawn into the masks
SKIN_COV_GAIN = 2.0                         # ratio         widening of the skin colour's covariance
SKIN_COV_FLOOR = 9.0                        # (8-bit)^2     added to the covariance's diagonal
SKIN_THRESHOLD = 6.0                        # Mahalanobis^2 the skin model's threshold
MIN_LIP_PIXELS = 20                         # pixels        fewest saturated lip pixels to learn the lips' hue
LIP_HUE_SPREAD = 1.5                        # ratio         the hue bump's width, times the lips' circular spread
LIP_HUE_WIDTH = (10.0, 30.0)                # degrees       bounds of the hue bump's width
REACH_MARGIN = 0.03                         # face units    added to the mouth corners' largest offset
REACH_MAX = 0.35                            # face units    largest mouth reach learned
ANCHOR_PASSES = 2                           # passes        of the eye anchors' fixed point on the labelled frames


def label_frame(curves: np.ndarray) -> FaceFrame:
    """The face frame of labelled curves (C, 4, 2) in image pixels (eye centres from the eye corners)."""
    right = (curves[_IDX["eye_right_upper"], 0] + curves[_IDX["eye_right_upper"], 3]) / 2.0
    left = (curves[_IDX["eye_left_upper"], 0] + curves[_IDX["eye_left_upper"], 3]) / 2.0
    return FaceFrame.from_eyes(right, left)


def to_face_units(curves: np.ndarray, frame: FaceFrame) -> np.ndarray:
    """Curves (..., 2) from image pixels to face units of ``frame``."""
    M = frame.to_image()
    return (np.asarray(curves, dtype=float) - M[:, 2]) @ np.linalg.inv(M[:, :2]).T


def relight(rgb: np.ndarray, gain: float, warmth: float, gamma: float) -> np.ndarray:
    """A copy of ``rgb`` under other light: ``255 (gain c (rgb / 255))^gamma`` with c = (1 + t, 1, 1 - t).

    Each channel's 256 levels are mapped once and the image looked up (the same numbers as mapping every pixel).
    """
    x = np.arange(256, dtype=np.float32)[:, None] / np.float32(255.0)
    x = x * (np.float32(gain) * np.array([1 + warmth, 1.0, 1 - warmth], dtype=np.float32))
    x = np.clip(x, 0.0, 1.0) ** np.float32(gamma)
    table = (x * 255.0 + 0.5).astype(np.uint8)
    return cv2.LUT(np.ascontiguousarray(rgb, dtype=np.uint8), table.reshape(256, 1, 3))


def feature_and_skin_masks(curves_px: np.ndarray, size: tuple[int, int], px: float = TRAIN_PX):
    """Masks (H, W) bool of labelled feature pixels and of skin pixels in a crop.

    Features: brows and upper lids as thick lines, the lips and mouth opening as the area between the outer
    lip curves. Skin: the cheek and forehead sub-areas, away from any feature.
    """
    w, h = size
    feat = np.zeros((h, w), np.uint8)
    for name, thick in (("brow_left", BROW_LINE), ("brow_right", BROW_LINE), ("eye_left_upper", LID_LINE),
                        ("eye_right_upper", LID_LINE)):
        pts = np.round(bezier_points(curves_px[_IDX[name]], MASK_SAMPLES)).astype(np.int32)
        cv2.polylines(feat, [pts], False, 1, thickness=max(1, int(round(thick * px))))
    lips = np.concatenate([bezier_points(curves_px[_IDX["lip_upper_outer"]], MASK_SAMPLES),
                           bezier_points(curves_px[_IDX["lip_lower_outer"]], MASK_SAMPLES)[::-1]])
    cv2.fillPoly(feat, [np.round(lips).astype(np.int32)], 1)
    skin = np.zeros((h, w), bool)
    for name in ("cheek_left", "cheek_right", "forehead"):
        b = SUBAREAS[name]
        x0, y0 = int(round((b[0] - CROP_EXTENT[0]) * px)), int(round((b[1] - CROP_EXTENT[1]) * px))
        x1, y1 = int(round((b[2] - CROP_EXTENT[0]) * px)), int(round((b[3] - CROP_EXTENT[1]) * px))
        skin[max(y0, 0):max(y1, 0), max(x0, 0):max(x1, 0)] = True
    grown = cv2.dilate(feat, np.ones((3, 3), np.uint8)).astype(bool)
    return feat.astype(bool), skin & ~grown


def face_crop(rgb: np.ndarray, frame: FaceFrame, px: float = TRAIN_PX):
    """The upright face crop of ``frame`` in the RGB frame, with its crop matrix (2, 3) and size (w, h)."""
    A = frame.crop_matrix(px)
    size = frame.crop_size(px)
    return cv2.warpAffine(rgb, A, size, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE), A, size


def _skin_model(crops, skins) -> SkinModel:
    cc = []
    for crop, skin in zip(crops, skins, strict=True):
        ycc = cv2.cvtColor(crop, cv2.COLOR_RGB2YCrCb)
        cc.append(ycc[skin][:, 1:].astype(float))
    cc = np.concatenate(cc)
    mean = cc.mean(axis=0)
    cov = np.cov(cc.T) * SKIN_COV_GAIN + SKIN_COV_FLOOR * np.eye(2)
    return SkinModel((float(mean[0]), float(mean[1])), tuple(tuple(map(float, r)) for r in cov), SKIN_THRESHOLD)


def _lip_hue(crops, curves_px, base: LipHue) -> LipHue:
    hues = []
    for crop, cur in zip(crops, curves_px, strict=True):
        m = np.zeros(crop.shape[:2], np.uint8)
        poly = np.concatenate([bezier_points(cur[_IDX["lip_upper_outer"]], MASK_SAMPLES),
                               bezier_points(cur[_IDX["lip_upper_inner"]], MASK_SAMPLES)[::-1]])
        cv2.fillPoly(m, [np.round(poly).astype(np.int32)], 1)
        hsv = cv2.cvtColor(crop, cv2.COLOR_RGB2HSV)
        sel = (m > 0) & (hsv[..., 1] >= base.min_saturation * 255)
        hues.append(hsv[..., 0][sel].astype(float) * 2.0)
    h = np.radians(np.concatenate(hues)) if hues else np.zeros(0)
    if len(h) < MIN_LIP_PIXELS:
        return base
    c, s = np.cos(h).mean(), np.sin(h).mean()
    centre = float(np.degrees(np.arctan2(s, c)) % 360.0)
    spread = float(np.degrees(np.sqrt(max(-2.0 * np.log(max(np.hypot(c, s), 1e-6)), 0.0))))
    return LipHue(centre, float(np.clip(LIP_HUE_SPREAD * spread, *LIP_HUE_WIDTH)), base.min_saturation)


def mouth_reach_of(layouts: np.ndarray, layout: np.ndarray, least: float) -> float:
    """How far the mouth corners move from the mean layout in the labelled frames (F, C, 4, 2), face units:
    their largest offset on either axis plus :data:`REACH_MARGIN`, at least ``least`` and at most
    :data:`REACH_MAX`."""
    c = _IDX["lip_upper_outer"]
    offsets = np.abs(layouts[:, c, [0, 3]] - layout[c, [0, 3]])
    return float(np.clip(offsets.max() + REACH_MARGIN, least, REACH_MAX))


def train_profile(frames, curves, *, base: Profile | None = None, name: str = "performer", augment: int = 6,
                  seed: int = 0, progress: bool = False, config: ColorTrackerConfig | None = None,
                  rotations: np.ndarray | None = None) -> Profile:
    """Learn a performer profile from labelled frames (§3.1).

    Parameters
    ----------
    frames : sequence of (H, W, 3) uint8
        RGB frames of the performer (a short calibration clip).
    curves : (F, C, 4, 2) float
        The feature curves of each frame in image pixels (CURVE_NAMES order; NaN rows for unlabelled frames),
        for example from the MediaPipe backend, or a synthetic performer's ground truth.
    base : Profile, optional
        Starting point (default :func:`~facepuppet.capture.color.profile.default_profile`).
    name : str
    augment : int
        Lighting variants per frame for the network's training set.
    seed : int
        Seed of the lighting variants.
    progress : bool
    config : ColorTrackerConfig, optional
        The options of the colour tracker run over the labelled frames (the eye anchors, the eyelid and shape
        models learn where it looks); give the ones it will track with.
    rotations : (F, 3, 3) float, optional
        The labels' head rotations (head to camera, :mod:`facepuppet.capture.pose`; NaN for none), the targets
        of the head-turn model; default the full pose solved from the labelled curves' stable points.

    Returns
    -------
    Profile
        With the performer's layout and anchors, skin model, lip hue and the trained colour network.

    BLAS runs on one thread throughout (its sums' last bits depend on the thread count, and a fit can carry
    them into another minimum): the profile is the same whatever threads the process allows.
    """
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        return _train_profile(frames, curves, base=base, name=name, augment=augment, seed=seed, progress=progress,
                              config=config, rotations=rotations)


def _train_profile(frames, curves, *, base: Profile | None, name: str, augment: int, seed: int, progress: bool,
                   config: ColorTrackerConfig | None, rotations: np.ndarray | None) -> Profile:
    """:func:`train_profile`'s work."""
    from tqdm import tqdm

    base = base or default_profile()
    options = config if config is not None else ColorTrackerConfig()
    curves = np.asarray(curves, dtype=float)
    if curves.ndim != 4 or curves.shape[1:] != (len(CURVE_NAMES), 4, 2):
        raise ValueError(f"curves must be (F, {len(CURVE_NAMES)}, 4, 2), got shape {curves.shape}")
    frames = list(frames)
    if len(frames) != len(curves):
        raise ValueError(f"frames and curves must have the same length, got {len(frames)} and {len(curves)}")
    keep = [k for k in range(len(curves)) if np.isfinite(curves[k]).all()]
    if len(keep) < 1:
        raise FacepuppetError("no labelled frame to calibrate the colour tracker on")
    rng = np.random.default_rng(seed)
    layouts, crops, curves_px, feats, skins, labels, turns = [], [], [], [], [], [], []
    if rotations is not None and np.shape(rotations) != (len(curves), 3, 3):
        raise ValueError(f"rotations must be ({len(curves)}, 3, 3), got shape {np.shape(rotations)}")
    for k in keep:
        rgb = np.asarray(frames[k])
        if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
            raise ValueError(f"frames[{k}] must be an (H, W, 3) uint8 image, got {rgb.shape} {rgb.dtype}")
        frame = label_frame(curves[k])
        if frame.unit < MIN_LABEL_UNIT:
            continue
        layouts.append(to_face_units(curves[k], frame))
        crop, A, size = face_crop(rgb, frame)
        cpx = curves[k] @ A[:, :2].T + A[:, 2]
        feat, skin = feature_and_skin_masks(cpx, size)
        if feat.sum() < MIN_MASK_PIXELS or skin.sum() < MIN_MASK_PIXELS:
            continue
        crops.append((rgb, frame))
        turns.append(_label_turn(curves[k], rgb.shape, None if rotations is None else rotations[k]))
        labels.append(curves[k])
        curves_px.append(cpx)
        feats.append(feat)
        skins.append(skin)
    if not crops:
        raise FacepuppetError("no labelled frame shows a face large enough to calibrate on")
    layout = np.median(np.stack(layouts), axis=0)
    reach = mouth_reach_of(np.stack(layouts), layout, base.mouth_reach)
    plain = [face_crop(rgb, fr)[0] for rgb, fr in crops]
    skin_model = _skin_model(plain, skins)
    lip = _lip_hue(plain, curves_px, base.lip_hue)
    table = lip_hue_table(lip)
    xs, ys = [], []
    work = [(i, None) for i in range(len(crops))] + [(i, j) for i in range(len(crops)) for j in range(augment)]
    for i, j in tqdm(work, desc="profile", unit="frame", disable=not progress):
        rgb, fr = crops[i]
        if j is not None:
            (g0, g1), (t0, t1), (c0, c1) = RELIGHT
            rgb = relight(rgb, rng.uniform(g0, g1), rng.uniform(t0, t1), rng.uniform(c0, c1))
        crop = face_crop(rgb, fr)[0]
        ch = channels(crop, table, lip.min_saturation)
        ys.append(separating_weights(ch[:, feats[i]].T, ch[:, skins[i]].T))
        xs.append(subarea_means(crop, TRAIN_PX))
    xs, ys = np.array(xs), np.array(ys)
    net = ColourNet.fit(xs, ys, seed=seed)
    weights = ys[:len(crops)].mean(axis=0)
    profile = replace(base, layout=layout, skin=skin_model, lip_hue=lip, weights=weights.astype(np.float64),
                      net=net.to_arrays(), name=name, mouth_reach=reach)
    # The eye anchors: where the tracker's eye search lands, in face units, on the labelled frames.
    anchors = np.asarray(profile.anchors, dtype=float).copy()
    for _ in range(ANCHOR_PASSES):
        tracker = ColorTracker(replace(profile, anchors=anchors), config=options)
        got = []
        for rgb, fr in crops:
            crop = face_crop(rgb, fr, tracker.config.measure.px)[0]
            eyes = tracker.eye_centres(tracker.intensity(crop))
            if eyes is not None:
                got.append(eyes / tracker.config.measure.px + CROP_EXTENT[:2])
        if not got:
            break
        anchors[:2] = np.median(np.stack(got), axis=0)
    # Where the tracker itself puts the eyes' corners on the labelled frames (the eyelid model's patches are
    # cut there at run time), and the crops and placed layouts the shape models read (the lips' and brows'
    # rules are not needed for either).
    eyes_only = replace(options, measure=replace(options.measure, outline_parts=("eyes",)))
    tracker = ColorTracker(replace(profile, anchors=anchors), config=eyes_only)
    tracked = []
    pairs: dict[str, tuple[list, list]] = {family: ([], []) for family in FAMILIES}
    # the head-turn model's jitter draws from a stream of its own, so that its count does not move the others'
    turn_x, turn_y, turn_rng = [], [], np.random.default_rng([seed, 1])
    (c0, k0), (c1, k1) = (_IDX["eye_right_upper"], 3), (_IDX["eye_left_upper"], 3)
    for i, (rgb, fr) in enumerate(crops):
        got = tracker.track(rgb, 100 * i)
        A = fr.crop_matrix(TRAIN_PX)
        tracked.append(got.curves @ A[:, :2].T + A[:, 2] if got.valid else None)
        if got.valid and tracker.seen is not None:
            crop, A_seen, placed = tracker.seen
            seen_labels = labels[i] @ A_seen[:, :2].T + A_seen[:, 2]
            for family, (xs, ys) in pairs.items():
                x, y = training_pairs(crop, placed, seen_labels, family, rng)
                xs += x
                ys += y
            if turns[i] is not None:
                layout_px = tracker.layout_in_crop
                S = similarity_of_pairs(layout_px[[c0, c1], [k0, k1]], placed[[c0, c1], [k0, k1]])
                x, y = head_turn.training_pairs(crop, S, tracker.config.measure.px, turns[i], turn_rng)
                turn_x += x
                turn_y += y
    lids = _lid_model(plain, curves_px, tracked, rng)
    shapes = {family: fit_shape_model(np.array(xs), np.array(ys)) for family, (xs, ys) in pairs.items()
              if len(xs) >= _MIN_SHAPE_PATCHES}
    head = (head_turn.fit_turn_model(np.array(turn_x), np.array(turn_y)) if len(turn_x) >= _MIN_SHAPE_PATCHES
            else {})
    log.info("profile %s: %d frames (%d relit), lip hue %.0f deg, weights %s, eyelid model %s, shape models %s, "
             "head-turn model %s", name, len(crops), len(crops) * augment, lip.centre, np.round(weights, 2),
             "yes" if lids else "no", ", ".join(shapes) or "none", "yes" if head else "no")
    return replace(profile, anchors=anchors, lids=lids, shapes=shapes, head=head)


def _label_turn(curves: np.ndarray, shape: tuple[int, ...], rotation: np.ndarray | None) -> np.ndarray | None:
    """(yaw, pitch, roll) radians of a labelled frame (of ``rotation`` if given, else of the full pose solved
    from the labelled curves' stable points with the generic face), the yaw and pitch less the share
    :data:`~.head_turn.RAY_SHARE` of the direction of the inner eye corners' midpoint (:func:`~.head_turn.ray_angles`,
    what the head-turn model reads); None where there is none."""
    from facepuppet.capture.pose import STABLE_FEATURES, HeadPose, camera_matrix, estimate_pose, pose_points_from_curves

    K = camera_matrix(float(shape[1]), float(shape[0]), None)
    if rotation is None:
        pose = estimate_pose(pose_points_from_curves(curves, STABLE_FEATURES), (shape[1], shape[0]))
        angles = pose.angles() if pose else None
    else:
        R = np.asarray(rotation, dtype=float)
        angles = HeadPose(R, np.zeros(3), K).angles() if np.isfinite(R).all() else None
    if angles is None:
        return None
    inner = 0.5 * (curves[_IDX["eye_right_upper"], 0] + curves[_IDX["eye_left_upper"], 0])
    angles[:2] -= np.asarray(head_turn.RAY_SHARE) * head_turn.ray_angles(inner, K)
    return angles


#: Fewest training patches (jittered copies included) for a shape model: fewer labelled frames than this
#: over the jitter copies leave the rules alone.
_MIN_SHAPE_PATCHES = 20 * (JITTER[0] + 1)


#: Jittered copies of each labelled eye for the eyelid model: the tracker's eye corners are not the labels'.
_LID_JITTER = 4
#: Largest jitter of the eye's centre (spans) and of its span (ratio) in those copies.
_LID_SHIFT, _LID_SCALE = 0.04, 0.06
#: Fewest eye patches (jittered copies included) for an eyelid model.
MIN_LID_PATCHES = 20


def _lid_model(crops, curves_px, tracked, rng) -> dict:
    """The eyelid model (:mod:`facepuppet.capture.color.lids`) learnt on the labelled crops; empty with too few eyes.

    Patches are cut around the eyes' corners as the tracker found them (``tracked``, crop pixels, None where it
    lost the face), and jittered copies of them; targets are the labelled lids seen from there.
    """
    from facepuppet.capture.color.lids import EYES, eye_geometry, eye_patch, fit_lid_model

    xs, ys = [], []
    for crop, cpx, tpx in zip(crops, curves_px, tracked, strict=True):
        if tpx is None:
            continue
        for eye in (0, 1):
            m, span, n = eye_geometry(tpx, eye)
            target = np.array([(0.5 * (cpx[k, 1] + cpx[k, 2]) - m) @ n / span for k in EYES[eye]])
            for j in range(_LID_JITTER + 1):
                dm = rng.uniform(-_LID_SHIFT, _LID_SHIFT, 2) * span if j else np.zeros(2)
                ds = rng.uniform(1 - _LID_SCALE, 1 + _LID_SCALE) if j else 1.0
                x = eye_patch(crop, m + dm, span * ds, mirror=eye == 1)
                if x is not None:
                    # The same lids seen from the shifted centre, in the changed span.
                    xs.append(x)
                    ys.append((target * span - dm @ n) / (span * ds))
    if len(xs) < MIN_LID_PATCHES:
        return {}
    return fit_lid_model(np.array(xs), np.array(ys))
