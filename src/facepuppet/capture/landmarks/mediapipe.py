"""The landmark backend: MediaPipe Face Landmarker (Tasks API), fully offline, as a :class:`Tracker`.

The 478-point face mesh is turned into the curve vocabulary of DESIGN.md by fitting a cubic Bezier
(:func:`~facepuppet.capture.curves.fit_bezier`) to the mesh vertices along each contour; the head pose comes
from the same generic face and solver as the colour tracker (:mod:`facepuppet.capture.pose`), so both backends
write feature points in the same head coordinates. The 52 blendshape scores go into the track as extras.

The model file is never downloaded: its path comes from the ``model_path`` argument or the environment
variable ``FACEPUPPET_FACE_LANDMARKER``. Small faces the detector misses on the whole frame (it wants a face
that fills a good part of the image) are searched for in overlapping tiles and then followed in a crop around
the last face.
"""

from __future__ import annotations

import atexit
import contextlib
import logging
import os
import sys
import weakref
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from facepuppet.capture.curves import CURVE_NAMES, POINT_NAMES, fit_bezier
from facepuppet.capture.features import FrameFeatures
from facepuppet.capture.pose import HeadPose, estimate_pose, points_in_head, pose_points_from_curves
from facepuppet.errors import FacepuppetError

__all__ = ["MediaPipeTracker", "MediaPipeConfig", "MP_CURVES", "MP_POSE_LANDMARKS", "BLENDSHAPE_NAMES",
           "MODEL_ENV", "curves_from_landmarks", "resolve_model_path"]

log = logging.getLogger(__name__)

#: Trackers not yet closed: closed at interpreter exit, while MediaPipe can still release its graphs (its own
#: finaliser fails noisily once the interpreter is being torn down).
_OPEN: weakref.WeakSet = weakref.WeakSet()

#: Environment variable holding the path of ``face_landmarker.task``.
MODEL_ENV = "FACEPUPPET_FACE_LANDMARKER"

_MODEL_HELP = (f"set {MODEL_ENV} or pass --model PATH to face_landmarker.task (MediaPipe's published "
               "Face Landmarker model bundle, listed on the MediaPipe Face Landmarker page of "
               "ai.google.dev under 'Models'); it is never downloaded at run time")

#: Face-mesh vertex indices along each curve, in the curve's direction (DESIGN.md). A pair of index lists
#: is averaged point by point: the brows are the centre line between their upper and lower outline.
MP_CURVES: dict[str, tuple[int, ...] | tuple[tuple[int, ...], tuple[int, ...]]] = {
    "brow_left": ((336, 296, 334, 293, 300), (285, 295, 282, 283, 276)),
    "brow_right": ((107, 66, 105, 63, 70), (55, 65, 52, 53, 46)),
    "eye_left_upper": (362, 398, 384, 385, 386, 387, 388, 466, 263),
    "eye_left_lower": (362, 382, 381, 380, 374, 373, 390, 249, 263),
    "eye_right_upper": (133, 173, 157, 158, 159, 160, 161, 246, 33),
    "eye_right_lower": (133, 155, 154, 153, 145, 144, 163, 7, 33),
    "lip_upper_outer": (61, 185, 40, 39, 37, 0, 267, 269, 270, 409, 291),
    "lip_lower_outer": (61, 146, 91, 181, 84, 17, 314, 405, 321, 375, 291),
    "lip_upper_inner": (78, 191, 80, 81, 82, 13, 312, 311, 310, 415, 308),
    "lip_lower_inner": (78, 95, 88, 178, 87, 14, 317, 402, 318, 324, 308),
    "nostril_left": (2, 326, 327),
    "nostril_right": (98, 97, 2),
}

#: Face-mesh vertices of generic-face landmarks used for the head pose besides the curve ends.
MP_POSE_LANDMARKS: dict[str, int] = {"nose_tip": 1}

#: Names of the 52 blendshape scores, in the order of the ``blendshapes`` extra (MediaPipe's order; its
#: ``Left``/``Right`` are the performer's own sides).
BLENDSHAPE_NAMES: tuple[str, ...] = (
    "_neutral", "browDownLeft", "browDownRight", "browInnerUp", "browOuterUpLeft", "browOuterUpRight",
    "cheekPuff", "cheekSquintLeft", "cheekSquintRight", "eyeBlinkLeft", "eyeBlinkRight", "eyeLookDownLeft",
    "eyeLookDownRight", "eyeLookInLeft", "eyeLookInRight", "eyeLookOutLeft", "eyeLookOutRight", "eyeLookUpLeft",
    "eyeLookUpRight", "eyeSquintLeft", "eyeSquintRight", "eyeWideLeft", "eyeWideRight", "jawForward", "jawLeft",
    "jawOpen", "jawRight", "mouthClose", "mouthDimpleLeft", "mouthDimpleRight", "mouthFrownLeft",
    "mouthFrownRight", "mouthFunnel", "mouthLeft", "mouthLowerDownLeft", "mouthLowerDownRight", "mouthPressLeft",
    "mouthPressRight", "mouthPucker", "mouthRight", "mouthRollLower", "mouthRollUpper", "mouthShrugLower",
    "mouthShrugUpper", "mouthSmileLeft", "mouthSmileRight", "mouthStretchLeft", "mouthStretchRight",
    "mouthUpperUpLeft", "mouthUpperUpRight", "noseSneerLeft", "noseSneerRight",
)


@dataclass(frozen=True)
class MediaPipeConfig:
    """Options of :class:`MediaPipeTracker`.

    Attributes
    ----------
    max_faces : int
        Faces the landmarker looks for; the one nearest the last tracked face (or the largest) is kept.
        Keep 1 for video: with more, MediaPipe runs its face detector on every frame that holds fewer faces,
        which makes the landmarks jitter and costs time.
    min_detection_confidence, min_presence_confidence, min_tracking_confidence : float
        MediaPipe's thresholds.
    tile_fractions : tuple of float
        Tile sizes, as fractions of the shorter frame side, for the search for faces the whole-frame
        detector misses; empty to disable.
    search_interval : int
        In a video, frames between two tile searches while the face is lost (the search costs several
        landmarker calls).
    refine_scales : tuple of float
        For still images: the landmarker is run again on square crops around the face found, of these sizes
        relative to the face's extent, and the landmarks averaged (steadier on turned or small faces); empty
        to disable.
    focal : float or None
        Focal length in pixels of the camera for the head pose (default: the larger frame side).
    """

    max_faces: int = 1
    min_detection_confidence: float = 0.5
    min_presence_confidence: float = 0.5
    min_tracking_confidence: float = 0.5
    tile_fractions: tuple[float, ...] = (0.5, 0.33)
    search_interval: int = 15
    refine_scales: tuple[float, ...] = (1.6, 1.8, 2.0)
    focal: float | None = None


def resolve_model_path(model_path: str | os.PathLike | None) -> Path:
    """The Face Landmarker model file from the argument or ``$FACEPUPPET_FACE_LANDMARKER``; checked to exist."""
    raw = model_path if model_path is not None else os.environ.get(MODEL_ENV)
    if not raw:
        raise FacepuppetError(f"no MediaPipe face landmarker model given: {_MODEL_HELP}")
    path = Path(raw).expanduser()
    if not path.is_file():
        source = "--model" if model_path is not None else MODEL_ENV
        raise FacepuppetError(f"{path}: face landmarker model not found (from {source}); {_MODEL_HELP}")
    return path


def _import_mediapipe():
    try:
        import mediapipe as mp
        from mediapipe.tasks.python import BaseOptions, vision
    except ImportError as e:
        raise FacepuppetError("the mediapipe backend needs the optional package: "
                              "pip install 'facepuppet[mediapipe]'") from e
    return mp, BaseOptions, vision


def curves_from_landmarks(lm: np.ndarray) -> np.ndarray:
    """Fit the vocabulary's curves to face-mesh landmarks.

    Parameters
    ----------
    lm : (478, 2) or (468, 2) float
        Landmarks in image pixels.

    Returns
    -------
    (C, 4, 2) float
        Bezier control points in CURVE_NAMES order.
    """
    out = np.empty((len(CURVE_NAMES), 4, 2))
    for c, name in enumerate(CURVE_NAMES):
        idx = MP_CURVES[name]
        pts = (lm[list(idx[0])] + lm[list(idx[1])]) / 2.0 if isinstance(idx[0], tuple) else lm[list(idx)]
        out[c] = fit_bezier(pts)
    return out


class MediaPipeTracker:
    """Face Landmarker as a tracker backend (``name = "mediapipe"``).

    Parameters
    ----------
    model_path : str or PathLike, optional
        ``face_landmarker.task``; default ``$FACEPUPPET_FACE_LANDMARKER``. Never downloaded.
    running_mode : {"video", "image"}
        "video" follows the face from frame to frame (frames in time order); "image" treats every frame
        on its own (still photographs).
    config : MediaPipeConfig, optional

    Raises
    ------
    FacepuppetError
        If mediapipe is not installed, or the model path is not given or not a readable model.
    """

    name = "mediapipe"

    def __init__(self, model_path: str | os.PathLike | None = None, *, running_mode: str = "video",
                 config: MediaPipeConfig | None = None):
        if running_mode not in ("video", "image"):
            raise ValueError(f"running_mode must be 'video' or 'image', got {running_mode!r}")
        self.config = config or MediaPipeConfig()
        self.model_path = resolve_model_path(model_path)
        self._mp, self._BaseOptions, self._vision = _import_mediapipe()
        self.running_mode = running_mode
        self._video = running_mode == "video"
        self._main = self._create(video=self._video)
        self._searcher = None  # IMAGE-mode landmarker for tiles and crops, made on first need
        self._last_ts = -1
        self._previous_pose: HeadPose | None = None
        self._last_box: np.ndarray | None = None  # (x0, y0, x1, y1) of the last face
        self._crop_mode = False  # following a small face in a crop
        self._since_search = 10**9
        #: Per-track extras the track file carries besides the per-frame ones.
        self.static_extras = {"blendshape_names": np.asarray(BLENDSHAPE_NAMES, dtype=str)}
        _OPEN.add(self)

    # -- MediaPipe plumbing -------------------------------------------------------------------------------
    def _create(self, *, video: bool):
        v = self._vision
        cfg = self.config
        opts = v.FaceLandmarkerOptions(
            base_options=self._BaseOptions(model_asset_path=str(self.model_path)),
            running_mode=v.RunningMode.VIDEO if video else v.RunningMode.IMAGE,
            num_faces=cfg.max_faces,
            min_face_detection_confidence=cfg.min_detection_confidence,
            min_face_presence_confidence=cfg.min_presence_confidence,
            min_tracking_confidence=cfg.min_tracking_confidence,
            output_face_blendshapes=True,
        )
        try:
            with _native_stderr_quiet(not log.isEnabledFor(logging.DEBUG)):
                return v.FaceLandmarker.create_from_options(opts)
        except (RuntimeError, ValueError) as e:
            raise FacepuppetError(f"{self.model_path}: cannot load the face landmarker model "
                                  f"({str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__})"
                                  ) from e

    def _image(self, rgb: np.ndarray):
        return self._mp.Image(image_format=self._mp.ImageFormat.SRGB, data=np.ascontiguousarray(rgb))

    def _detect_in(self, rgb: np.ndarray, x0: int, y0: int):
        """Run the IMAGE-mode landmarker on a crop; faces as (landmarks (N, 2) in frame pixels, scores)."""
        if self._searcher is None:
            self._searcher = self._create(video=False)
        r = self._searcher.detect(self._image(rgb))
        return self._faces(r, rgb.shape[1], rgb.shape[0], x0, y0)

    @staticmethod
    def _faces(result, w: int, h: int, x0: int = 0, y0: int = 0):
        faces = []
        for i, f in enumerate(result.face_landmarks):
            lm = np.array([(p.x, p.y) for p in f]) * (w, h) + (x0, y0)
            bs = (np.array([c.score for c in result.face_blendshapes[i]], dtype=np.float32)
                  if result.face_blendshapes else np.full(len(BLENDSHAPE_NAMES), np.nan, np.float32))
            faces.append((lm, bs))
        return faces

    # -- finding the face ---------------------------------------------------------------------------------
    def _choose(self, faces):
        if not faces:
            return None
        if self._last_box is not None and len(faces) > 1:
            centre = (self._last_box[:2] + self._last_box[2:]) / 2
            return min(faces, key=lambda f: np.linalg.norm(f[0].mean(0) - centre))
        return max(faces, key=lambda f: np.prod(np.ptp(f[0], axis=0)))

    def _tile_search(self, rgb: np.ndarray):
        h, w = rgb.shape[:2]
        found = []
        for frac in self.config.tile_fractions:
            side = max(int(min(w, h) * frac), 32)
            step = max(side // 2, 1)
            xs = sorted({*range(0, max(w - side, 0) + 1, step), max(w - side, 0)})
            ys = sorted({*range(0, max(h - side, 0) + 1, step), max(h - side, 0)})
            for y0 in ys:
                for x0 in xs:
                    found += self._detect_in(rgb[y0:y0 + side, x0:x0 + side], x0, y0)
            if found:
                break
        return self._choose(_unique_faces(found))

    def _crop_around(self, rgb: np.ndarray, box: np.ndarray, scale: float):
        """Landmark the face nearest ``box`` (x0, y0, x1, y1) in a square crop ``scale`` times its size."""
        h, w = rgb.shape[:2]
        x0, y0, x1, y1 = box
        side = max(int(scale * max(x1 - x0, y1 - y0)), 16)
        cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
        ax, ay = int(np.clip(cx - side / 2, 0, max(w - side, 0))), int(np.clip(cy - side / 2, 0, max(h - side, 0)))
        faces = self._detect_in(rgb[ay:ay + side, ax:ax + side], ax, ay)
        if not faces:
            return None
        centre = np.array([cx, cy])
        return min(faces, key=lambda f: np.linalg.norm(f[0].mean(0) - centre))

    def _crop_follow(self, rgb: np.ndarray):
        return self._crop_around(rgb, self._last_box, 2.2)

    def _refine(self, rgb: np.ndarray, face):
        """Average the landmarks of crops around ``face`` (stills only; see ``refine_scales``)."""
        box = np.r_[face[0].min(0), face[0].max(0)]
        found = [f for f in (self._crop_around(rgb, box, s) for s in self.config.refine_scales) if f is not None]
        size = np.ptp(face[0], axis=0).max()
        found = [f for f in found if np.linalg.norm(f[0].mean(0) - face[0].mean(0)) < 0.25 * size]
        if not found:
            return face
        return np.mean([f[0] for f in found], axis=0), np.mean([f[1] for f in found], axis=0)

    def _find(self, rgb: np.ndarray, timestamp_ms: int):
        h, w = rgb.shape[:2]
        if self._crop_mode and self._last_box is not None:
            face = self._crop_follow(rgb)
            if face is not None:
                return face
            self._crop_mode = False
        if self._video:
            ts = max(int(timestamp_ms), self._last_ts + 1)
            self._last_ts = ts
            r = self._main.detect_for_video(self._image(rgb), ts)
        else:
            r = self._main.detect(self._image(rgb))
        face = self._choose(self._faces(r, w, h))
        if face is None and self.config.tile_fractions:
            face = self._search(rgb)
        if face is not None and not self._video and self.config.refine_scales:
            face = self._refine(rgb, face)
        return face

    def _search(self, rgb: np.ndarray):
        if self._video and self._since_search < self.config.search_interval:
            self._since_search += 1
            return None
        self._since_search = 0
        face = self._tile_search(rgb)
        if face is not None and self._video:
            self._crop_mode = True
        return face

    # -- the Tracker interface ----------------------------------------------------------------------------
    def track(self, rgb: np.ndarray, timestamp_ms: int) -> FrameFeatures:
        """Track one RGB frame (H, W, 3) uint8; a frame without a face gives ``FrameFeatures.lost``."""
        rgb = np.asarray(rgb)
        if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
            raise ValueError(f"rgb must be an (H, W, 3) uint8 array, got {rgb.dtype} {rgb.shape}")
        face = self._find(rgb, timestamp_ms)
        lost = FrameFeatures.lost(len(CURVE_NAMES), len(POINT_NAMES),
                                  extras={"blendshapes": np.full(len(BLENDSHAPE_NAMES), np.nan, np.float32)})
        if face is None:
            self._previous_pose, self._last_box, self._crop_mode = None, None, False
            return lost
        lm, blendshapes = face
        self._last_box = np.r_[lm.min(0), lm.max(0)]
        frame_size = (rgb.shape[1], rgb.shape[0])
        curves = curves_from_landmarks(lm)
        image_points = pose_points_from_curves(curves)
        for n, i in MP_POSE_LANDMARKS.items():
            image_points[n] = lm[i]
        pose = estimate_pose(image_points, frame_size, focal=self.config.focal,
                             previous=self._previous_pose if self._video else None)
        if not pose:
            log.debug("face found but head pose failed: %s", pose.reason)
            self._previous_pose = None
            return lost
        self._previous_pose = pose
        return FrameFeatures(valid=True, curves=curves, rotation=pose.rotation, translation=pose.translation,
                             points=points_in_head(curves, pose), extras={"blendshapes": blendshapes})

    def reset(self) -> None:
        """Forget the face followed: the next frame is searched on its own (an unrelated image)."""
        self._previous_pose, self._last_box, self._crop_mode = None, None, False
        self._since_search = 10**9

    def close(self) -> None:
        """Release the landmarkers."""
        _OPEN.discard(self)
        for attr in ("_main", "_searcher"):
            lm = getattr(self, attr, None)
            if lm is not None:
                setattr(self, attr, None)
                lm.close()

    def __enter__(self) -> MediaPipeTracker:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:  # noqa: BLE001 - interpreter shutdown may have torn mediapipe down already
            pass


@contextlib.contextmanager
def _native_stderr_quiet(quiet: bool):
    """Silence file descriptor 2 for the block: MediaPipe's C++ side logs several lines to it while a graph is
    built, which would bury the command's own output (kept when debug logging is on)."""
    if not quiet:
        yield
        return
    sys.stderr.flush()
    try:
        saved = os.dup(2)
    except OSError:  # no usable stderr to silence
        yield
        return
    null = os.open(os.devnull, os.O_WRONLY)
    os.dup2(null, 2)
    os.close(null)
    try:
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


@atexit.register
def _close_open_trackers() -> None:
    for tracker in list(_OPEN):
        tracker.close()


def _unique_faces(faces):
    """Drop duplicate detections of one face from overlapping tiles (keep the first of each)."""
    kept = []
    for f in faces:
        c = f[0].mean(0)
        size = np.ptp(f[0], axis=0).max()
        if all(np.linalg.norm(c - k[0].mean(0)) > 0.3 * size for k in kept):
            kept.append(f)
    return kept
