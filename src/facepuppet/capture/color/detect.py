"""Faces found by the arrangement of their dark features, not their colour: candidate face frames for acquisition.

A skin-coloured scene (a wooden wall, a beige room in warm light) is one large skin region to the skin model,
and the face a part of it. What only a face has is its pattern of darker and lighter areas: the eyes and brows
darker than the forehead and cheeks, the bridge of the nose lighter than the eyes beside it, the mouth a dark
line under them. OpenCV's boosted cascade of such rectangle contrasts (Viola and Jones; the frontal-face
cascade that comes with ``opencv-python`` in ``cv2.data``, nothing downloaded) finds windows with that pattern
on the grey image; each gives a first face frame from the average place of the eyes in its window, which the
tracker then pulls onto the eyes and scores like any other candidate
(:class:`~facepuppet.capture.color.acquire.Acquirer`).

The cascade finds upright faces, give or take some 15 degrees of roll; a tilted head is found on copies of the
image turned by :data:`TILTS` (:func:`face_windows`), each window then a turned box (:class:`FaceWindow`). A window
also says how large the face in it is: the eye-centre distance is :data:`BOX_UNIT` of its width, so a candidate
pulled onto the brows and chin of a face is not supported by the window of that face (:func:`supported`).

Conventions: RGB uint8 frames; boxes (x, y, w, h) and face frames in image pixels; tilts in degrees,
counter-clockwise in the image (OpenCV's :func:`cv2.getRotationMatrix2D`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import cv2
import numpy as np

from facepuppet.capture.color.face import FaceFrame

__all__ = ["CASCADE_FILE", "WINDOW", "FACE_SIZES", "EYE_PLACES", "TILTS", "TILTED_PASSES", "BOX_UNIT", "BOX_EYES",
           "FaceWindow", "face_boxes", "face_windows", "supported", "search_area"]

log = logging.getLogger(__name__)

CASCADE_FILE = "haarcascade_frontalface_default.xml"

# Tuning constants              unit          what it does
WINDOW = 24                     # pixels        the cascade's own window: the smallest face it finds
#: Passes of the search, coarse to fine: each finds faces from this share of the searched area's smaller side up
#: (the area shrunk so that such a face spans :data:`WINDOW` pixels); a pass runs only if those before found none.
FACE_SIZES = (0.2, 0.08, 0.04)
NEIGHBOURS = 4                  # windows       overlapping detections needed for a face (the cascade's minNeighbors)
SCALE_STEP = 1.15               # ratio         between the window sizes tried
MAX_FACES = 3                   # faces         largest windows kept
#: Where the eye centres sit in a detection window, (x, y) shares of its width and height (right eye, left eye).
EYE_PLACES = ((0.31, 0.40), (0.69, 0.40))
#: Turns of the image the cascade searches (degrees): upright, and tilted heads either way.
TILTS = (0.0, 25.0, -25.0)
TILTED_PASSES = 2               # passes        of FACE_SIZES the turned copies run when the upright finds no face
#: A window's face size: its eye-centre distance from this share of the window's width to that (the cascade's
#: windows of the shared performers: 0.32-0.43) ...
BOX_UNIT = (0.28, 0.46)
BOX_EYES = 0.35                 # share         ... most likely this share (EYE_PLACES seed the eye search wider)
#: The area searched around a face frame, in face units (x0, y0, x1, y1): the face and its own size around it.
AROUND = (-3.2, -3.0, 3.2, 4.2)


@lru_cache(maxsize=1)
def _cascade() -> cv2.CascadeClassifier | None:
    data = getattr(cv2, "data", None)
    path = Path(getattr(data, "haarcascades", "")) / CASCADE_FILE if data is not None else None
    if path is None or not path.is_file():
        log.debug("OpenCV's face cascade %s is not installed: faces are found by skin only", CASCADE_FILE)
        return None
    cascade = cv2.CascadeClassifier(str(path))
    return None if cascade.empty() else cascade


def search_area(frame: FaceFrame, shape: tuple[int, ...]) -> tuple[int, int, int, int]:
    """The part of an image of ``shape`` (H, W, ...) searched around face frame ``frame``: its box of
    :data:`AROUND` (upright, whatever the roll), (x0, y0, x1, y1) pixels clipped to the image."""
    h, w = shape[:2]
    u = frame.unit
    ox, oy = (float(v) for v in frame.origin)
    return (max(0, int(ox + AROUND[0] * u)), max(0, int(oy + AROUND[1] * u)),
            min(w, int(ox + AROUND[2] * u) + 1), min(h, int(oy + AROUND[3] * u) + 1))


def _passes(grey: np.ndarray, passes: int = len(FACE_SIZES)) -> tuple[np.ndarray, int]:
    """Windows (N, 4) float (x, y, w, h) of the grey image (H, W) uint8, largest first, by the first ``passes``
    of :data:`FACE_SIZES`; and the passes run."""
    cascade = _cascade()
    h, w = grey.shape[:2]
    if cascade is None or w < WINDOW or h < WINDOW:
        return np.zeros((0, 4)), 0
    side = min(w, h)
    larger = None
    for k, share in enumerate(FACE_SIZES[:passes]):
        f = min(1.0, WINDOW / (share * side))
        g = grey if f >= 1.0 else cv2.resize(grey, (max(1, round(w * f)), max(1, round(h * f))),
                                             interpolation=cv2.INTER_AREA)
        top = (int(larger * f * SCALE_STEP) + 1,) * 2 if larger else (0, 0)
        found = ()
        # Equalised first (a dim or hazy face's contrast spread out), then as filmed: in a frame mostly of a
        # bright, busy scene (wooden boards, a poster) the equalisation spends the grey levels on the scene and
        # flattens the face.
        for shown in (cv2.equalizeHist(g), g):
            found = cascade.detectMultiScale(shown, scaleFactor=SCALE_STEP, minNeighbors=NEIGHBOURS,
                                             minSize=(WINDOW, WINDOW), maxSize=top)
            if len(found):
                break
        if len(found):
            boxes = np.asarray(found, dtype=float) / f
            return boxes[np.argsort(-boxes[:, 2])][:MAX_FACES], k + 1
        larger = share * side          # pixels: the faces the coarser passes looked for
    return np.zeros((0, 4)), min(passes, len(FACE_SIZES))


def _area(rgb: np.ndarray, roi: tuple[int, int, int, int] | None) -> tuple[int, int, int, int]:
    h, w = rgb.shape[:2]
    return (0, 0, w, h) if roi is None else roi


def face_boxes(rgb: np.ndarray, roi: tuple[int, int, int, int] | None = None) -> np.ndarray:
    """Windows (N, 4) float (x, y, w, h), image pixels, largest first, that show an upright frontal face's pattern
    of dark features, in the whole image or its part ``roi`` (x0, y0, x1, y1); (0, 4) when none is found or the
    cascade is not installed.

    The search runs coarse to fine (:data:`FACE_SIZES`): large faces on a small copy of the image first, the
    smaller ones on a larger copy only if none was found; its cost grows with the pixels searched.
    """
    x0, y0, x1, y1 = _area(rgb, roi)
    if _cascade() is None or x1 - x0 < WINDOW or y1 - y0 < WINDOW:
        return np.zeros((0, 4))
    grey = cv2.cvtColor(np.ascontiguousarray(rgb[y0:y1, x0:x1]), cv2.COLOR_RGB2GRAY)
    boxes, _ = _passes(grey)
    return boxes + [x0, y0, 0, 0] if len(boxes) else boxes


@dataclass(frozen=True)
class FaceWindow:
    """A cascade window found on a turned copy of the image.

    Attributes
    ----------
    box : (4,) float
        (x, y, w, h) in the turned copy's pixels.
    to_box : (2, 3) float
        Affine map from image pixels to the turned copy's pixels.
    """

    box: np.ndarray
    to_box: np.ndarray

    @property
    def width(self) -> float:
        """The window's width, pixels (the image's and the copy's are the same size)."""
        return float(self.box[2])

    @property
    def unit(self) -> float:
        """The most likely eye-centre distance of the window's face (:data:`BOX_EYES` of its width), pixels."""
        return BOX_EYES * float(self.box[2])

    def frame(self) -> FaceFrame:
        """The first face frame of the window: its eyes at :data:`EYE_PLACES`, in image pixels."""
        x, y, w, h = (float(v) for v in self.box)
        back = cv2.invertAffineTransform(self.to_box)
        (rx, ry), (lx, ly) = EYE_PLACES
        eyes = np.array([[x + rx * w, y + ry * h], [x + lx * w, y + ly * h]]) @ back[:, :2].T + back[:, 2]
        return FaceFrame.from_eyes(eyes[0], eyes[1])

    def contains(self, frame: FaceFrame) -> bool:
        """Whether the face frame's origin lies in the window (whatever the frame's size)."""
        ox, oy = self.to_box[:, :2] @ frame.origin + self.to_box[:, 2]
        x, y, w, h = (float(v) for v in self.box)
        return bool(x <= ox <= x + w and y <= oy <= y + h)

    def holds(self, frame: FaceFrame) -> bool:
        """Whether the face frame's origin lies in the window and its eye-centre distance is :data:`BOX_UNIT` of
        the window's width."""
        w = float(self.box[2])
        return self.contains(frame) and BOX_UNIT[0] * w <= frame.unit <= BOX_UNIT[1] * w


def face_windows(rgb: np.ndarray, roi: tuple[int, int, int, int] | None = None,
                 tilts: tuple[float, ...] = TILTS) -> list[FaceWindow]:
    """The cascade's windows (:func:`face_boxes`) on copies of the image, or of its part ``roi`` (x0, y0, x1, y1),
    turned by each of ``tilts`` (degrees) about the part's centre: faces upright and tilted either way, each
    tilt's largest first; [] when none is found or the cascade is not installed.

    The first tilt's copy is searched like the upright image (:func:`face_boxes`); the others (each grown to hold
    the whole part) only for faces as large as those the first found, or, if it found none, as large as
    :data:`TILTED_PASSES` of :data:`FACE_SIZES` look for (the finest pass costs most: it runs on the full-size
    copy).
    """
    x0, y0, x1, y1 = _area(rgb, roi)
    if _cascade() is None or x1 - x0 < WINDOW or y1 - y0 < WINDOW:
        return []
    grey = cv2.cvtColor(np.ascontiguousarray(rgb[y0:y1, x0:x1]), cv2.COLOR_RGB2GRAY)
    h, w = grey.shape
    out, passes = [], len(FACE_SIZES)
    for i, tilt in enumerate(tilts):
        T = cv2.getRotationMatrix2D((w / 2.0, h / 2.0), float(tilt), 1.0)
        c, s = abs(T[0, 0]), abs(T[0, 1])
        W, H = int(np.ceil(w * c + h * s)), int(np.ceil(w * s + h * c))
        T[:, 2] += [(W - w) / 2.0, (H - h) / 2.0]
        if tilt == 0:
            T = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
            boxes, ran = _passes(grey, passes)
        else:
            # The passes run search copies no larger than the finest of them needs: the part is shrunk to that
            # size first and the small copy turned (turning the full-size part costs more than the search).
            f = min(1.0, WINDOW / (FACE_SIZES[passes - 1] * min(W, H)))
            small = grey if f >= 1.0 else cv2.resize(grey, (max(1, round(w * f)), max(1, round(h * f))),
                                                     interpolation=cv2.INTER_AREA)
            fx, fy = small.shape[1] / w, small.shape[0] / h
            S = np.diag([fx, fy])                      # the part's pixels -> the small copy's
            Ts = np.column_stack([S @ T[:, :2] @ np.linalg.inv(S), S @ T[:, 2]])
            turned = cv2.warpAffine(small, Ts, (max(1, round(W * fx)), max(1, round(H * fy))),
                                    flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
            boxes, ran = _passes(turned, passes)
            boxes = boxes / [fx, fy, fx, fy] if len(boxes) else boxes
        to_box = T.copy()
        to_box[:, 2] -= T[:, :2] @ [x0, y0]           # image pixels -> the turned copy's pixels
        if i == 0:
            passes = ran if len(boxes) else min(ran, TILTED_PASSES)
        out += [FaceWindow(b, to_box) for b in boxes]
    return out


def supported(frame: FaceFrame, windows: list[FaceWindow]) -> bool:
    """Whether one of the windows holds the face frame (:meth:`FaceWindow.holds`)."""
    return any(win.holds(frame) for win in windows)
