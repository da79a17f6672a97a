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

__all__ = ["CASCADE_FILE", "WORK_WIDTH", "EYE_PLACES", "face_boxes", "frames_of_boxes", "inside_box"]

log = logging.getLogger(__name__)

CASCADE_FILE = "haarcascade_frontalface_default.xml"

# Tuning constants              unit          what it does
WORK_WIDTH = 320                # pixels        width the frame is shrunk to for the search
MIN_FACE = 0.08                 # fraction      smallest face window, of the shrunk frame's smaller side
NEIGHBOURS = 4                  # windows       overlapping detections needed for a face (the cascade's minNeighbors)
SCALE_STEP = 1.15               # ratio         between the window sizes tried
MAX_FACES = 3                   # faces         largest windows kept
#: Where the eye centres sit in a detection window, (x, y) shares of its width and height (right eye, left eye).
EYE_PLACES = ((0.31, 0.40), (0.69, 0.40))


@lru_cache(maxsize=1)
def _cascade() -> cv2.CascadeClassifier | None:
    data = getattr(cv2, "data", None)
    path = Path(getattr(data, "haarcascades", "")) / CASCADE_FILE if data is not None else None
    if path is None or not path.is_file():
        log.debug("OpenCV's face cascade %s is not installed: faces are found by skin only", CASCADE_FILE)
        return None
    cascade = cv2.CascadeClassifier(str(path))
    return None if cascade.empty() else cascade


def face_boxes(rgb: np.ndarray) -> np.ndarray:
    """Windows (N, 4) float (x, y, w, h), image pixels, largest first, that show a frontal face's pattern of
    dark features; (0, 4) when none is found or the cascade is not installed."""
    cascade = _cascade()
    if cascade is None:
        return np.zeros((0, 4))
    h, w = rgb.shape[:2]
    f = min(1.0, WORK_WIDTH / float(w))
    grey = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
    if f < 1.0:
        grey = cv2.resize(grey, (max(1, round(w * f)), max(1, round(h * f))), interpolation=cv2.INTER_AREA)
    grey = cv2.equalizeHist(grey)
    side = max(12, int(MIN_FACE * min(grey.shape)))
    found = cascade.detectMultiScale(grey, scaleFactor=SCALE_STEP, minNeighbors=NEIGHBOURS, minSize=(side, side))
    if len(found) == 0:
        return np.zeros((0, 4))
    boxes = np.asarray(found, dtype=float) / f
    return boxes[np.argsort(-boxes[:, 2])][:MAX_FACES]


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
