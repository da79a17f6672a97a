"""Faces found by the arrangement of their dark features, not their colour: candidate face frames for acquisition.

A skin-coloured scene (a wooden wall, a beige room in warm light) is one large skin region to the skin model,
and the face a part of it. What only a face has is its pattern of darker and lighter areas: the eyes and brows
darker than the forehead and cheeks, the bridge of the nose lighter than the eyes beside it, the mouth a dark
line under them. OpenCV's boosted cascade of such rectangle contrasts (Viola and Jones; the frontal-face
cascade that comes with ``opencv-python`` in ``cv2.data``, nothing downloaded) finds windows with that pattern
on the grey image; each gives a first face frame from the average place of the eyes in its window, which the
tracker then pulls onto the eyes and scores like any other candidate
(:class:`~facepuppet.capture.color.acquire.Acquirer`).

Conventions: RGB uint8 frames; boxes (x, y, w, h) and face frames in image pixels.
"""

from __future__ import annotations

import logging
from functools import lru_cache
from pathlib import Path

import cv2
import numpy as np

from facepuppet.capture.color.face import FaceFrame

__all__ = ["CASCADE_FILE", "WINDOW", "FACE_SIZES", "EYE_PLACES", "face_boxes", "frames_of_boxes", "inside_box",
           "search_area"]

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


def face_boxes(rgb: np.ndarray, roi: tuple[int, int, int, int] | None = None) -> np.ndarray:
    """Windows (N, 4) float (x, y, w, h), image pixels, largest first, that show a frontal face's pattern of
    dark features, in the whole image or its part ``roi`` (x0, y0, x1, y1); (0, 4) when none is found or the
    cascade is not installed.

    The search runs coarse to fine (:data:`FACE_SIZES`): large faces on a small copy of the image first, the
    smaller ones on a larger copy only if none was found; its cost grows with the pixels searched.
    """
    cascade = _cascade()
    if cascade is None:
        return np.zeros((0, 4))
    h, w = rgb.shape[:2]
    x0, y0, x1, y1 = (0, 0, w, h) if roi is None else roi
    if x1 - x0 < WINDOW or y1 - y0 < WINDOW:
        return np.zeros((0, 4))
    grey = cv2.cvtColor(np.ascontiguousarray(rgb[y0:y1, x0:x1]), cv2.COLOR_RGB2GRAY)
    side = min(x1 - x0, y1 - y0)
    larger = None
    for share in FACE_SIZES:
        f = min(1.0, WINDOW / (share * side))
        g = grey if f >= 1.0 else cv2.resize(grey, (max(1, round((x1 - x0) * f)), max(1, round((y1 - y0) * f))),
                                             interpolation=cv2.INTER_AREA)
        g = cv2.equalizeHist(g)
        top = (int(larger * f * SCALE_STEP) + 1,) * 2 if larger else (0, 0)
        found = cascade.detectMultiScale(g, scaleFactor=SCALE_STEP, minNeighbors=NEIGHBOURS,
                                         minSize=(WINDOW, WINDOW), maxSize=top)
        if len(found):
            boxes = np.asarray(found, dtype=float) / f + [x0, y0, 0, 0]
            return boxes[np.argsort(-boxes[:, 2])][:MAX_FACES]
        larger = share * side          # image pixels: the faces the coarser passes looked for
    return np.zeros((0, 4))


def frames_of_boxes(boxes: np.ndarray) -> list[FaceFrame]:
    """The first face frame of each window (N, 4): its eyes at :data:`EYE_PLACES`."""
    out = []
    for x, y, w, h in np.asarray(boxes, dtype=float):
        (rx, ry), (lx, ly) = EYE_PLACES
        out.append(FaceFrame.from_eyes(np.array([x + rx * w, y + ry * h]), np.array([x + lx * w, y + ly * h])))
    return out


def inside_box(frame: FaceFrame, boxes: np.ndarray) -> bool:
    """Whether the face frame's origin (between the eyes) lies in one of the windows (N, 4) and its size fits
    it (eye-centre distance between a fifth and two thirds of the window's width)."""
    ox, oy = (float(v) for v in frame.origin)
    for x, y, w, h in np.asarray(boxes, dtype=float):
        if x <= ox <= x + w and y <= oy <= y + h and 0.2 * w <= frame.unit <= 0.67 * w:
            return True
    return False
