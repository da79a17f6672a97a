"""Real performers turning their heads: a clip's face re-posed by a known sweep of yaw and pitch.

The shared clips' heads barely turn (MediaPipe's yaw spreads 1.3-4.2 degrees), and the digital performer's
drawn face turns but has a flat, painted nose. Here each frame of a real clip is re-posed instead: MediaPipe's
478 face landmarks in 3-D (x, y in image pixels; z, depth away from the camera, in pixels of the same scale)
are rotated about the centre of their face oval by the frame's yaw and pitch of :func:`sweep`, projected
orthographically, and every triangle of the face's mesh (the Delaunay triangles of the first face's landmarks
in the image, so the eye and mouth openings are covered too) has its pixels warped from where it was to where
it goes, the farthest first. Outside the face's outline the frame is as filmed: hair, ears and background stay
while the face turns within them. A frame without a face is left as it is.

The sweep is the digital performer's (:mod:`eval_head_turns`): yaw ``Y sin(2 pi 0.11 t + phase)``, pitch
``P sin(2 pi 0.17 t + 1)``, eased in over the first second.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np

YAW_HZ, PITCH_HZ = 0.11, 0.17    # the sweeps' frequencies, as the digital performer's
MIN_AREA = 0.5                   # image pixels²: a triangle drawn smaller than this (edge-on) is not drawn
#: MediaPipe's landmark depths are multiplied by this before the face is turned. As given they are about half
#: of the depths its head poses read a turn with (its own transformation matrix and the backend's PnP on the
#: generic face alike read the copies' turns at 0.53-0.64 of the angles put in, performer_a and c); doubled,
#: they read them at 0.92-1.20, but the noses then stand out twice as far as the faces filmed show them (a
#: beak at 25 degrees). The faces are kept as MediaPipe shapes them: the angles put in are the mesh's, and the
#: benchmarks score against MediaPipe's pose of the copy.
DEPTH_SCALE = 1.0


def sweep(frames: np.ndarray, fps: float, yaw_deg: float, pitch_deg: float, phase: float = 0.0) -> np.ndarray:
    """(F, 2) radians: the yaw and pitch added to the frames of indices ``frames`` (F,) at ``fps``."""
    t = np.asarray(frames, dtype=float) / fps
    ease = np.clip(t, 0.0, 1.0)
    return np.stack([ease * np.radians(yaw_deg) * np.sin(2 * np.pi * YAW_HZ * t + phase),
                     ease * np.radians(pitch_deg) * np.sin(2 * np.pi * PITCH_HZ * t + 1.0)], axis=1)


def rotation(yaw: float, pitch: float) -> np.ndarray:
    """(3, 3) the rotation by ``yaw`` about the image's vertical axis, then ``pitch`` about its horizontal one
    (x right, y down, z away from the camera), signed as :meth:`~facepuppet.capture.pose.HeadPose.angles`: a
    positive yaw turns the nose to the image's right, a positive pitch turns it down."""
    cy, sy, cp, sp = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch)
    Ry = np.array([[cy, 0.0, -sy], [0.0, 1.0, 0.0], [sy, 0.0, cy]])
    Rx = np.array([[1.0, 0.0, 0.0], [0.0, cp, -sp], [0.0, sp, cp]])
    return Rx @ Ry


def mesh(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(triangles (T, 3) int, outline (K,) int) of a face's landmarks (N, >= 2): the Delaunay triangles of their
    image positions and the indices of their convex hull (the face's outline)."""
    from scipy.spatial import Delaunay

    d = Delaunay(np.asarray(points, dtype=float)[:, :2])
    return d.simplices.astype(np.int64), np.unique(d.convex_hull)


def _twice_area(t: np.ndarray) -> float:
    """Twice the signed area of the triangle ``t`` (3, 2) (positive: its corners run counter-clockwise on the
    image, y down)."""
    return float((t[1, 0] - t[0, 0]) * (t[2, 1] - t[0, 1]) - (t[2, 0] - t[0, 0]) * (t[1, 1] - t[0, 1]))


def turn(rgb: np.ndarray, P: np.ndarray, triangles: np.ndarray, outline: np.ndarray, yaw: float,
         pitch: float) -> np.ndarray:
    """``rgb`` (H, W, 3) uint8 with the face of landmarks ``P`` (N, 3: x, y, depth, image pixels) turned by
    ``yaw`` and ``pitch`` radians about the centre of its outline's points; a new array."""
    import cv2

    c = P[outline].mean(axis=0)
    Q = (P - c) @ rotation(yaw, pitch).T + c
    out = rgb.copy()
    h, w = rgb.shape[:2]
    order = np.argsort(-Q[triangles, 2].mean(axis=1), kind="stable")     # the farthest first
    for t in triangles[order]:
        src, dst = P[t, :2].astype(np.float32), Q[t, :2].astype(np.float32)
        area = _twice_area(dst)
        if abs(area) < 2 * MIN_AREA or area * _twice_area(src) <= 0:      # edge-on or turned away
            continue
        x0, y0 = np.floor(dst.min(axis=0)).astype(int)
        x1, y1 = np.ceil(dst.max(axis=0)).astype(int) + 1
        x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
        if x1 <= x0 or y1 <= y0:
            continue
        A = cv2.getAffineTransform(dst - np.float32([x0, y0]), src)
        patch = cv2.warpAffine(rgb, A, (x1 - x0, y1 - y0), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                               borderMode=cv2.BORDER_REFLECT)
        mask = np.zeros((y1 - y0, x1 - x0), np.uint8)
        cv2.fillConvexPoly(mask, np.round((dst - [x0, y0]) * 16).astype(np.int32), 1, cv2.LINE_8, 4)
        region = out[y0:y1, x0:x1]
        region[mask > 0] = patch[mask > 0]
    return out


def face_points(src: Path, model: str) -> Iterator[tuple[np.ndarray, np.ndarray | None, float]]:
    """Each frame of ``src`` (RGB uint8) with MediaPipe's landmarks of its face (478, 3) in image pixels (the
    depth times :data:`DEPTH_SCALE`), or None where it finds none (MediaPipe's model file ``model``, video mode),
    and the clip's frame rate."""
    import mediapipe as mp
    from mediapipe.tasks.python import BaseOptions, vision

    from facepuppet.io.frames import open_media

    opts = vision.FaceLandmarkerOptions(base_options=BaseOptions(model_asset_path=str(model)),
                                        running_mode=vision.RunningMode.VIDEO, num_faces=1)
    with vision.FaceLandmarker.create_from_options(opts) as lm, open_media(src) as frames:
        for i, rgb in enumerate(frames):
            r = lm.detect_for_video(mp.Image(image_format=mp.ImageFormat.SRGB, data=np.ascontiguousarray(rgb)),
                                    int(round(i * 1000 / frames.fps)))
            if not r.face_landmarks:
                yield rgb, None, frames.fps
                continue
            h, w = rgb.shape[:2]
            yield rgb, np.array([(p.x * w, p.y * h, p.z * w * DEPTH_SCALE) for p in r.face_landmarks[0]]), frames.fps


def turned_frames(src: Path, model: str, yaw_deg: float, pitch_deg: float, phase: float = 0.0
                  ) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """Each frame of ``src`` turned by :func:`sweep` (``yaw_deg``, ``pitch_deg`` either way, at the clip's frame
    rate), with the (2,) radians of yaw and pitch added to it (zeros where no face was found and the frame is as
    filmed)."""
    triangles = outline = None
    for i, (rgb, P, fps) in enumerate(face_points(src, model)):
        if P is None:
            yield rgb, np.zeros(2)
            continue
        if triangles is None:
            triangles, outline = mesh(P)
        a = sweep(np.array([i]), fps, yaw_deg, pitch_deg, phase)[0]
        yield turn(rgb, P, triangles, outline, float(a[0]), float(a[1])), a
