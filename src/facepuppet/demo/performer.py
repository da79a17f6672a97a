"""The digital performer: a human head made by code, with ground truth for every feature curve.

Its face is the generic face of :mod:`facepuppet.capture.pose` (same landmarks, same head coordinates: cm,
origin midway between the inner eye corners, x to the performer's left, y up, z out of the face). Each feature
curve of :data:`~facepuppet.capture.curves.CURVE_NAMES` is a cubic Bezier in 3D whose four control points are
the neutral ones plus a weighted sum of one displacement per key expression of
:data:`~facepuppet.demo.script.KEY_NAMES` (:data:`KEY_MOTIONS`), so every feature point is *exactly linear* in
the weights. The eye corners, nose base and alae never move, as on a person, so the head pose solved from them
is the true one.

It is filmed by the pinhole camera :func:`facepuppet.capture.pose.default_camera` of the frame size; the head
sits :data:`DISTANCE` cm in front of it. Head motion ``(yaw, pitch, roll, x, y, z)`` turns the head about the
pivot :data:`PIVOT` (near the top of the neck) by ``Ry(yaw) Rx(pitch) Rz(roll)`` in head coordinates and then
moves it by ``(x, y, z)`` cm along the neutral head's axes (:func:`head_pose`).

The pictures are painted by :mod:`facepuppet.demo._paint`: a shaded skin head with hair and ears, thick dark
brows, eyes (white sclera, dark iris, a dark lash line on the upper lid margin, a lower lid line), red lips
with a dark mouth opening, dark nostrils, and mild camera noise.
"""

from __future__ import annotations

from collections.abc import Iterator
from functools import lru_cache

import numpy as np

from facepuppet.capture.curves import CURVE_NAMES, bernstein, curve_points
from facepuppet.capture.pose import FRONTAL_ROTATION, HeadPose, default_camera, generic_curves
from facepuppet.demo.script import KEY_NAMES, Script

__all__ = [
    "DISTANCE",
    "PIVOT",
    "KEY_MOTIONS",
    "head_pose",
    "performer_curves_3d",
    "performer_curves",
    "performer_points",
    "render_performer",
    "render_performance",
]

#: Distance of the head origin from the camera at rest, cm.
DISTANCE = 32.0
#: Head point that lands in the middle of the image at rest (between the eyes and the mouth), cm.
_AIM = np.array([0.0, -3.0, 0.0])
#: Centre of the head's rotations, head coordinates, cm.
PIVOT = np.array([0.0, -6.0, -8.0])

_C = {name: i for i, name in enumerate(CURVE_NAMES)}

# ------------------------------------------------------------------ key motions
# Mouth: per key, displacements (dx, dy, dz) in cm of the performer's LEFT corner of the outer and inner lip
# outlines ("co", "ci") and of the middle of each lip outline ("uo", "lo", "ui", "li": upper/lower, outer/inner).
# A control point at u = x / x_corner (-1 right corner .. 1 left corner) moves by
# (cx u, cy u^2 + my (1 - u^2), cz u^2 + mz (1 - u^2)): symmetric, exact at the corners, smooth between.
_MOUTH: dict[str, dict[str, tuple[float, float, float]]] = {
    "jawOpen": {"co": (-0.25, -0.55, -0.10), "ci": (-0.30, -0.60, -0.10), "uo": (0, 0.05, 0), "lo": (0, -1.75, -0.2),
                "ui": (0, 0.10, 0), "li": (0, -1.85, -0.3)},
    "mouthSmile": {"co": (0.55, 0.75, -0.45), "ci": (0.50, 0.70, -0.40), "uo": (0, 0.15, -0.05),
                   "lo": (0, 0.15, -0.05), "ui": (0, 0.15, 0), "li": (0, 0.02, 0)},
    "mouthFrown": {"co": (-0.05, -0.55, -0.05), "ci": (-0.05, -0.50, -0.05), "uo": (0, -0.05, 0),
                   "lo": (0, 0.10, 0.10), "ui": (0, -0.05, 0), "li": (0, -0.05, 0)},
    "mouthPucker": {"co": (-1.00, 0.05, 0.50), "ci": (-0.90, 0.05, 0.50), "uo": (0, 0.05, 0.75),
                    "lo": (0, 0.05, 0.75), "ui": (0, 0.0, 0.70), "li": (0, 0.0, 0.70)},
    "mouthFunnel": {"co": (-0.45, 0.0, 0.45), "ci": (-0.60, 0.0, 0.45), "uo": (0, 0.55, 0.60),
                    "lo": (0, -0.60, 0.60), "ui": (0, 0.60, 0.50), "li": (0, -0.75, 0.50)},
    "mouthStretch": {"co": (0.60, -0.40, -0.25), "ci": (0.60, -0.40, -0.25), "uo": (0, -0.08, 0),
                     "lo": (0, -0.25, 0), "ui": (0, 0.0, 0), "li": (0, -0.45, 0)},
    "mouthRollLower": {"co": (0, 0, 0), "ci": (0, 0, 0), "uo": (0, 0, 0), "lo": (0, 0.65, -0.35),
                       "ui": (0, 0, 0), "li": (0, 0.05, -0.20)},
    "cheekPuff": {"co": (0.30, 0.10, 0.15), "ci": (0.30, 0.10, 0.15), "uo": (0, -0.30, 0.25),
                  "lo": (0, 0.30, 0.25), "ui": (0, -0.02, 0.20), "li": (0, 0.02, 0.20)},
}
_MOUTH_CURVES = {"lip_upper_outer": ("co", "uo"), "lip_lower_outer": ("co", "lo"),
                 "lip_upper_inner": ("ci", "ui"), "lip_lower_inner": ("ci", "li")}

# Left brow, control points inner -> outer: (dx, dy, dz) per control point, dx towards the left ear.
_BROW: dict[str, np.ndarray] = {
    "browInnerUp": np.array([[-0.10, 0.90, 0.0], [-0.05, 0.60, 0.0], [0.0, 0.25, 0.0], [0.0, 0.05, 0.0]]),
    "browDown": np.array([[-0.30, -0.55, 0.1], [-0.20, -0.50, 0.1], [-0.10, -0.40, 0.05], [0.0, -0.30, 0.0]]),
    "browOuterUp": np.array([[0.0, 0.10, 0.0], [0.0, 0.30, 0.0], [0.05, 0.60, 0.0], [0.10, 0.80, 0.0]]),
    "eyeWide": np.tile([0.0, 0.15, 0.0], (4, 1)),
    "eyeBlink": np.tile([0.0, -0.10, 0.0], (4, 1)),
}

# Left eye lids: (dy, dz) of the two middle control points of the upper and lower lid (the corners stay put);
# eyeBlink is built apart (the upper lid meets the raised lower lid).
_LIDS: dict[str, tuple[tuple[float, float], tuple[float, float]]] = {
    "eyeWide": ((0.30, 0.05), (-0.08, 0.0)),
    "browDown": ((-0.08, 0.0), (0.0, 0.0)),
    "mouthSmile": ((0.0, 0.0), (0.10, 0.02)),
    "cheekPuff": ((0.0, 0.0), (0.12, 0.02)),
}
_BLINK_LOWER = 0.06  # cm the lower lid rises in a blink


def _mirror(ctrl: np.ndarray) -> np.ndarray:
    return ctrl * np.array([-1.0, 1.0, 1.0])


@lru_cache(maxsize=1)
def _model() -> tuple[np.ndarray, np.ndarray]:
    """Neutral control points (C, 4, 3) and key displacements (K, C, 4, 3), head coordinates, cm."""
    neutral = generic_curves()
    deltas = np.zeros((len(KEY_NAMES), *neutral.shape))
    for k, key in enumerate(KEY_NAMES):
        d = deltas[k]
        if key in _MOUTH:
            m = _MOUTH[key]
            for curve, (corner, mid) in _MOUTH_CURVES.items():
                ctrl = neutral[_C[curve]]
                u = ctrl[:, 0] / abs(ctrl[0, 0])
                c, mm = np.asarray(m[corner], float), np.asarray(m[mid], float)
                d[_C[curve], :, 0] = c[0] * u
                d[_C[curve], :, 1] = c[1] * u**2 + mm[1] * (1 - u**2)
                d[_C[curve], :, 2] = c[2] * u**2 + mm[2] * (1 - u**2)
        if key in _BROW:
            d[_C["brow_left"]] = _BROW[key]
            d[_C["brow_right"]] = _mirror(_BROW[key])
        for side in ("left", "right"):
            up, lo = _C[f"eye_{side}_upper"], _C[f"eye_{side}_lower"]
            if key in _LIDS:
                (uy, uz), (ly, lz) = _LIDS[key]
                d[up, 1:3, 1:] = (uy, uz)
                d[lo, 1:3, 1:] = (ly, lz)
            if key == "eyeBlink":
                d[lo, 1:3, 1] = _BLINK_LOWER
                d[up, 1:3] = neutral[lo, 1:3] + d[lo, 1:3] - neutral[up, 1:3]
    neutral.setflags(write=False)
    deltas.setflags(write=False)
    return neutral, deltas


KEY_MOTIONS: dict[str, str] = {
    "jawOpen": "lower lip and inner lower lip drop about 1.8 cm, mouth corners drop and narrow, the jaw drops",
    "mouthSmile": "mouth corners 0.75 cm up, 0.55 cm out and back; lips rise a little; lower lids rise",
    "mouthFrown": "mouth corners 0.55 cm down; lower lip pushed up and forward",
    "mouthPucker": "mouth narrows by 2 cm, lips forward 0.75 cm, closed",
    "mouthFunnel": "mouth narrows by 0.9 cm, lips forward and flared, a round opening",
    "mouthStretch": "mouth corners 0.6 cm out and 0.4 cm down, lower lip drops a little",
    "mouthRollLower": "the lower lip's red rolls in, its outline rises 0.65 cm",
    "cheekPuff": "closed lips pressed together and forward, corners out and up, lower lids pushed up, the lower "
                 "face widens",
    "browInnerUp": "inner brow ends 0.9 cm up, outer ends still",
    "browDown": "brows down 0.3-0.55 cm and knitted towards the nose, upper lids lower a little",
    "browOuterUp": "outer brow ends 0.8 cm up, inner ends nearly still",
    "eyeBlink": "upper lids close onto the lower lids, brows slightly down",
    "eyeWide": "upper lids 0.3 cm up, lower lids a little down, brows slightly up",
}
"""What each key expression of the performer moves (the displacements are in this module's tables)."""


def _check_weights(weights) -> np.ndarray:
    w = np.asarray(weights, dtype=float)
    if w.shape != (len(KEY_NAMES),) or not np.isfinite(w).all():
        raise ValueError(f"weights must be {len(KEY_NAMES)} finite numbers (KEY_NAMES order), got shape {w.shape}")
    return w


def _check_motion(head_motion) -> np.ndarray:
    if head_motion is None:
        return np.zeros(6)
    m = np.asarray(head_motion, dtype=float)
    if m.shape != (6,) or not np.isfinite(m).all():
        raise ValueError(f"head_motion must be 6 finite numbers (yaw, pitch, roll, x, y, z), got shape {m.shape}")
    return m


def performer_curves_3d(weights: np.ndarray) -> np.ndarray:
    """The performer's feature curves for ``weights`` (13,), head coordinates: (C, 4, 3) control points, cm."""
    neutral, deltas = _model()
    return neutral + np.einsum("k,kcjd->cjd", _check_weights(weights), deltas)


def _rot(axis: int, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    r = np.eye(3)
    r[i, i], r[i, j], r[j, i], r[j, j] = c, -s, s, c
    return r


def head_pose(head_motion: np.ndarray | None = None, size: tuple[int, int] = (480, 480)) -> HeadPose:
    """The true head pose of the performer for one frame's head motion.

    Parameters
    ----------
    head_motion : (6,) float, optional
        Yaw, pitch, roll (radians, about the head's y, x, z axes) and x, y, z translation (cm, along the
        neutral head's axes); default the rest pose.
    size : (int, int)
        Frame width and height; the camera is :func:`~facepuppet.capture.pose.default_camera` of it.

    Returns
    -------
    HeadPose
        ``rotation = FRONTAL_ROTATION @ Ry(yaw) @ Rx(pitch) @ Rz(roll)`` (so :meth:`HeadPose.angles` gives
        the yaw, pitch and roll back) and the translation that keeps :data:`PIVOT` fixed under rotation.
    """
    yaw, pitch, roll, *d = _check_motion(head_motion)
    turn = _rot(1, yaw) @ _rot(0, pitch) @ _rot(2, roll)
    rest = np.array([0.0, 0.0, DISTANCE]) - FRONTAL_ROTATION @ _AIM
    # x_cam = F (turn (x - pivot) + pivot + d) + rest
    t = FRONTAL_ROTATION @ (PIVOT - turn @ PIVOT + np.asarray(d)) + rest
    return HeadPose(FRONTAL_ROTATION @ turn, t, default_camera(size))


_FIT_S = np.linspace(0.0, 1.0, 16)
_FIT_B = bernstein(_FIT_S)
_FIT_PINV = np.linalg.pinv(_FIT_B[:, 1:3])


def _project_curves(ctrl3: np.ndarray, pose: HeadPose) -> tuple[np.ndarray, np.ndarray]:
    """Dense projected samples (C, 16, 2) of 3D curves and their best image Bezier (C, 4, 2), ends exact."""
    pts3 = np.einsum("sj,cjd->csd", _FIT_B, ctrl3)
    uv = pose.project(pts3.reshape(-1, 3)).reshape(len(ctrl3), len(_FIT_S), 2)
    p0, p3 = uv[:, 0], uv[:, -1]
    rhs = uv - _FIT_B[None, :, :1] * p0[:, None] - _FIT_B[None, :, 3:] * p3[:, None]
    mid = np.einsum("js,csd->cjd", _FIT_PINV, rhs)
    return uv, np.concatenate([p0[:, None], mid, p3[:, None]], axis=1)


def performer_curves(weights: np.ndarray, head_motion: np.ndarray | None = None,
                     size: tuple[int, int] = (480, 480)) -> np.ndarray:
    """The true image curves of the performer: (C, 4, 2) Bezier control points in pixels, CURVE_NAMES order.

    Each curve is the performer's 3D curve projected by the true :func:`head_pose` (samples at 16 parameters)
    and fitted by the image cubic with the same parameters and the projected end points (perspective makes
    the image curve a rational cubic; the fit is within a hundredth of a pixel). Left and right are the
    performer's own, so the performer's left features appear on the image's right.
    """
    return _project_curves(performer_curves_3d(weights), head_pose(head_motion, size))[1]


def performer_points(weights: np.ndarray, head_motion: np.ndarray | None = None) -> np.ndarray:
    """The performer's true 3D feature points, (P, 3) in POINT_NAMES order, cm; linear in ``weights``.

    In head coordinates when ``head_motion`` is None, else in the camera coordinates of :func:`head_pose`
    (OpenCV axes: x right, y down, z forward).
    """
    pts = curve_points(performer_curves_3d(weights))
    if head_motion is None:
        return pts
    pose = head_pose(head_motion)
    return pts @ pose.rotation.T + pose.translation


def _render_one(weights, head_motion, size, rng) -> tuple[np.ndarray, np.ndarray]:
    from facepuppet.demo import _paint

    w = _check_weights(weights)
    m = _check_motion(head_motion)
    size = _size(size)
    pose = head_pose(m, size)
    ctrl3 = performer_curves_3d(w)
    return _paint.paint(w, ctrl3, pose, size, rng), _project_curves(ctrl3, pose)[1]


def _size(size) -> tuple[int, int]:
    try:
        w, h = (int(s) for s in size)
    except (TypeError, ValueError) as err:
        raise ValueError(f"size must be (width, height), got {size!r}") from err
    if w < 64 or h < 64:
        raise ValueError(f"size must be at least 64 x 64 pixels, got {size!r}")
    return w, h


def render_performer(weights: np.ndarray | Script, head_motion: np.ndarray | None = None,
                     size: tuple[int, int] = (480, 480),
                     rng: np.random.Generator | None = None) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Paint the performer showing ``weights`` with ``head_motion``.

    Parameters
    ----------
    weights : (13,) float or Script
        Key-expression weights in KEY_NAMES order. A whole :class:`~facepuppet.demo.script.Script` renders
        every frame (camera noise from ``np.random.default_rng(0)`` unless ``rng`` is given) and returns
        ``(frames (F, H, W, 3) uint8, curves (F, C, 4, 2) float)``.
    head_motion : (6,) float, optional
        Yaw, pitch, roll (rad), x, y, z (cm); default the rest pose.
    size : (int, int)
        Frame width and height.
    rng : numpy.random.Generator, optional
        Source of the camera noise; without it the noise pattern is the same fixed one on every call.

    Returns
    -------
    (H, W, 3) uint8
        RGB frame (or frames and true curves for a Script).
    """
    if isinstance(weights, Script):
        frames = np.empty((weights.n_frames, *_size(size)[::-1], 3), np.uint8)
        curves = np.empty((weights.n_frames, len(CURVE_NAMES), 4, 2))
        rng = rng if rng is not None else np.random.default_rng(0)
        for i in range(weights.n_frames):
            frames[i], curves[i] = _render_one(weights.weights[i], weights.head_motion[i], size, rng)
        return frames, curves
    return _render_one(weights, head_motion, size, rng)[0]


def render_performance(script: Script, size: tuple[int, int] = (480, 480), seed: int = 0) -> Iterator[np.ndarray]:
    """Frames of the performer acting ``script``, one (H, W, 3) uint8 RGB frame at a time.

    The camera noise comes from ``np.random.default_rng(seed)``, so the clip is reproducible.
    """
    rng = np.random.default_rng(seed)
    for w, m in zip(script.weights, script.head_motion, strict=True):
        yield _render_one(w, m, size, rng)[0]
