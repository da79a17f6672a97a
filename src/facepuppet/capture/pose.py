"""Head pose from stable facial features and the generic 3D face, and feature points with the pose removed.

Head coordinates (right-handed, centimetres): origin midway between the inner eye corners, **x to the
performer's left**, **y up**, **z out of the face** (the generic face: :mod:`facepuppet.capture.generic_face`).
Camera coordinates are OpenCV's: x right, y down, z forward along the optical axis. A head seen frontally and
upright therefore has rotation ``diag(1, -1, -1)``; a point maps as ``x_cam = R @ x_head + t``.

The generic face's names are importable from here too.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import lru_cache

import numba as nb
import numpy as np

from facepuppet._util.jit import KERNEL
from facepuppet.capture.curves import CURVE_NAMES, POINT_SAMPLES, bernstein
from facepuppet.capture.generic_face import (
    FRONTAL_ROTATION,
    GENERIC_CURVE_LANDMARKS,
    GENERIC_FACE,
    GENERIC_POINTS,
    STABLE_FEATURES,
    generic_curves,
    generic_landmarks,
    generic_points,
    pose_point_index,
    pose_points_from_curves,
)
from facepuppet.capture.pose_solvers import refine_pose, refine_upright, reprojection_error, upright_start

__all__ = [
    "GENERIC_FACE",
    "GENERIC_CURVE_LANDMARKS",
    "STABLE_FEATURES",
    "FRONTAL_ROTATION",
    "HeadPose",
    "FailedPose",
    "default_camera",
    "camera_matrix",
    "generic_curves",
    "generic_points",
    "estimate_pose",
    "refine_pose",
    "pose_points_from_curves",
    "pose_point_index",
    "points_in_head",
]

#: Largest mean reprojection error accepted, as a fraction of the inner-to-outer eye-corner span in the image.
_MAX_REPROJECTION = 0.35


def default_camera(frame_size: tuple[int, int] | np.ndarray, focal: float | None = None) -> np.ndarray:
    """A pinhole camera for frames of ``frame_size`` (width, height): principal point at the centre.

    The default focal length is the larger frame side in pixels (a field of view of about 53 degrees across
    that side, a typical webcam).

    Returns
    -------
    (3, 3) float
        The camera matrix K.
    """
    w, h = (float(v) for v in frame_size)
    return camera_matrix(w, h, None if focal is None else float(focal)).copy()


@lru_cache(maxsize=16)
def camera_matrix(w: float, h: float, focal: float | None) -> np.ndarray:
    f = focal if focal is not None else max(w, h)
    if not (w > 0 and h > 0 and f > 0):
        raise ValueError(f"frame size and focal length must be positive, got {w:g}x{h:g} and {focal}")
    K = np.array([[f, 0.0, w / 2.0], [0.0, f, h / 2.0], [0.0, 0.0, 1.0]])
    K.setflags(write=False)
    return K


@dataclass(frozen=True)
class HeadPose:
    """A solved head pose.

    Attributes
    ----------
    rotation : (3, 3) float
        Head-to-camera rotation.
    translation : (3,) float
        Head origin in camera coordinates, cm.
    camera_matrix : (3, 3) float
        The pinhole camera the pose was solved with.
    reprojection_error : float
        Mean distance in pixels between the given image points and the generic face projected with this pose.
    """

    rotation: np.ndarray
    translation: np.ndarray
    camera_matrix: np.ndarray
    reprojection_error: float = 0.0

    def __bool__(self) -> bool:
        return True

    def project(self, points_head: np.ndarray) -> np.ndarray:
        """Project head-coordinate points (N, 3) into the image, (N, 2) pixels."""
        cam = np.asarray(points_head, dtype=float) @ self.rotation.T + self.translation
        uv = cam @ self.camera_matrix.T
        return uv[:, :2] / uv[:, 2:3]

    def up_vector_image(self, at: np.ndarray | None = None) -> np.ndarray:
        """The head's up direction (+y of head coordinates) as a unit vector in the image, (2,).

        Parameters
        ----------
        at : (3,) float, optional
            Head-coordinate point where the direction is taken (default the head origin); perspective makes
            it vary slightly across the face.

        Returns
        -------
        (2,) float
            Unit vector in pixels (x right, y down); an upright head gives about (0, -1).
        """
        p = np.zeros(3) if at is None else np.asarray(at, dtype=float)
        uv = self.project(np.stack([p, p + np.array([0.0, 1.0, 0.0])]))
        d = uv[1] - uv[0]
        n = np.hypot(*d)
        return d / n if n > 0 else np.array([0.0, -1.0])

    def angles(self) -> np.ndarray:
        """Yaw, pitch, roll in radians relative to a frontal upright head, (3,).

        Defined by ``R = FRONTAL_ROTATION @ Ry(yaw) @ Rx(pitch) @ Rz(roll)``, rotations about the head's own
        y (up), x (left) and z (forward) axes, right-handed.
        """
        m = FRONTAL_ROTATION @ self.rotation  # Ry(yaw) Rx(pitch) Rz(roll)
        pitch = np.arcsin(np.clip(-m[1, 2], -1.0, 1.0))
        yaw = np.arctan2(m[0, 2], m[2, 2])
        roll = np.arctan2(m[1, 0], m[1, 1])
        return np.array([yaw, pitch, roll])

    @property
    def roll(self) -> float:
        """The roll of :meth:`angles` (radians), without the yaw and pitch."""
        return _roll(self.rotation)


def _roll(rotation: np.ndarray) -> float:
    """The roll (radians) of the head-to-camera ``rotation`` (3, 3), as :meth:`HeadPose.angles` reads it."""
    m = FRONTAL_ROTATION @ rotation
    return float(np.arctan2(m[1, 0], m[1, 1]))


@dataclass(frozen=True)
class FailedPose:
    """A pose that could not be solved; falsy, with the reason in words."""

    reason: str
    rotation: np.ndarray = field(default_factory=lambda: np.full((3, 3), np.nan))
    translation: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))

    def __bool__(self) -> bool:
        return False


_SAMPLE_BASIS = bernstein(np.asarray(POINT_SAMPLES))


def _as_correspondences(image_points, names):
    if isinstance(image_points, Mapping):
        names = tuple(image_points)
        uv = np.array([np.asarray(image_points[n], dtype=float).reshape(2) for n in names]).reshape(-1, 2)
    else:
        uv = np.asarray(image_points, dtype=float)
        names = tuple(names)
        if uv.shape != (len(names), 2):
            raise ValueError(f"image_points must be ({len(names)}, 2) for landmarks {names}, got shape {uv.shape}")
    return names, uv, generic_landmarks(names)


def estimate_pose(image_points: Mapping[str, np.ndarray] | np.ndarray, frame_size: tuple[int, int] | np.ndarray,
                  *, focal: float | None = None, previous: HeadPose | FailedPose | None = None,
                  names: tuple[str, ...] = STABLE_FEATURES, out_of_plane: bool = True) -> HeadPose | FailedPose:
    """Head pose from image landmarks and the generic face (Perspective-n-Point, iterative).

    Parameters
    ----------
    image_points : dict of str -> (2,) float, or (N, 2) float
        Image positions (pixels) of named landmarks of :data:`GENERIC_FACE`; an array is taken in the order
        of ``names``. At least four are needed; the stable ones (:data:`STABLE_FEATURES`) give the most
        expression-independent pose.
    frame_size : (2,) int
        Width and height of the frame, for the default camera.
    focal : float, optional
        Focal length in pixels (default: see :func:`default_camera`).
    previous : HeadPose, optional
        Last frame's pose, used as the initial guess; otherwise a frontal head at the distance the eye span
        suggests.
    names : tuple of str
        Landmark names of an array ``image_points``.
    out_of_plane : bool
        Solve the head's yaw and pitch (the default). False holds them at zero, the head facing along the
        camera's optical axis, and solves only its roll and position: for landmarks placed by an in-plane
        similarity of a fixed layout, which carry no sign of a turn. Solved freely, such points
        turn the head towards the camera wherever it sits in the image, and since a head turning about the
        neck also moves across the image, that rotation runs against the real turn.

    Returns
    -------
    HeadPose or FailedPose
        FailedPose (falsy) when there are too few finite points, the solver fails, the head would be behind
        the camera, or the generic face does not fit the points (mean reprojection error above 35 % of the
        eye-corner span).
    """
    names, uv, xyz = _as_correspondences(image_points, names)
    if not np.isfinite(uv).all():
        finite = np.isfinite(uv).all(axis=1)
        uv, xyz = uv[finite], xyz[finite]
        names = tuple(n for n, ok in zip(names, finite, strict=True) if ok)
    if len(uv) < 4:
        return FailedPose(f"head pose needs at least 4 finite landmarks, got {len(uv)}")
    K = camera_matrix(float(frame_size[0]), float(frame_size[1]), None if focal is None else float(focal))
    if not out_of_plane:
        start = upright_start(K, xyz, uv) if not previous else (
            _roll(previous.rotation), np.asarray(previous.translation, dtype=float))
        roll, t, ok = refine_upright(xyz, uv, K, start[0], start[1].copy())
        if not ok or not np.isfinite(t).all():
            return FailedPose("upright head pose did not converge")
        c, s = np.cos(roll), np.sin(roll)
        R = FRONTAL_ROTATION @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        return _checked_pose(R, t, K, xyz, uv, names)
    import cv2

    if previous:
        # From last frame's pose a few Gauss-Newton steps on the same reprojection error converge.
        R, t, ok = refine_pose(xyz, uv, K, np.asarray(previous.rotation, dtype=float),
                                np.asarray(previous.translation, dtype=float))
        if ok:
            return _checked_pose(R, t, K, xyz, uv, names)
        rvec0 = cv2.Rodrigues(np.asarray(previous.rotation, dtype=float))[0]
        tvec0 = np.asarray(previous.translation, dtype=float).reshape(3, 1).copy()
    else:
        # Frontal guess: depth from the image spread of the points against that of the generic face.
        spread_img = np.sqrt(((uv - uv.mean(0)) ** 2).sum(1).mean())
        spread_3d = np.sqrt(((xyz[:, :2] - xyz[:, :2].mean(0)) ** 2).sum(1).mean())
        if not spread_img > 0:
            return FailedPose("head pose: the landmarks coincide in the image")
        z = K[0, 0] * spread_3d / spread_img
        c = (uv.mean(0) - K[:2, 2]) * z / K[0, 0]
        rvec0 = cv2.Rodrigues(FRONTAL_ROTATION)[0]
        tvec0 = (np.array([c[0], c[1], z]) - FRONTAL_ROTATION @ xyz.mean(0)).reshape(3, 1)
    try:
        ok, rvec, tvec = cv2.solvePnP(xyz, uv, K, None, rvec0.copy(), tvec0.copy(), useExtrinsicGuess=True,
                                      flags=cv2.SOLVEPNP_ITERATIVE)
    except cv2.error as e:
        return FailedPose(f"head pose solver failed ({str(e).strip().splitlines()[-1]})")
    if not ok or not (np.isfinite(rvec).all() and np.isfinite(tvec).all()):
        return FailedPose("head pose solver did not converge")
    return _checked_pose(cv2.Rodrigues(rvec)[0], tvec.reshape(3), K, xyz, uv, names)


def _checked_pose(R: np.ndarray, t: np.ndarray, K: np.ndarray, xyz: np.ndarray, uv: np.ndarray,
                  names: tuple[str, ...]) -> HeadPose | FailedPose:
    if t[2] <= 0:
        return FailedPose("head pose puts the head behind the camera")
    err = reprojection_error(xyz, uv, K, R, t)
    scale = _eye_span(names, uv)
    if scale is not None and err > _MAX_REPROJECTION * scale:
        return FailedPose(f"generic face does not fit the landmarks (mean reprojection error {err:.1f} px)")
    return HeadPose(R, t, K, err)


def _eye_span(names, uv) -> float | None:
    pairs = _eye_pairs(tuple(names))
    if not pairs:
        return None
    p = np.asarray(uv).tolist()
    return max(float(np.hypot(p[a][0] - p[b][0], p[a][1] - p[b][1])) for a, b in pairs)


@lru_cache(maxsize=64)
def _eye_pairs(names: tuple[str, ...]) -> tuple[tuple[int, int], ...]:
    idx = {n: i for i, n in enumerate(names)}
    return tuple((idx[a], idx[b]) for a, b in (("eye_left_inner", "eye_left_outer"),
                                                ("eye_right_inner", "eye_right_outer")) if a in idx and b in idx)


def points_in_head(curves: np.ndarray, pose: HeadPose, frame_size: tuple[int, int] | np.ndarray | None = None,
                   *, focal: float | None = None, curve_names: tuple[str, ...] = CURVE_NAMES) -> np.ndarray:
    """Feature points of the curves, back-projected onto the generic face and expressed in head coordinates.

    Each curve is sampled at POINT_SAMPLES; the camera ray through each sample is intersected with the plane
    through the generic face's corresponding point parallel to the face (normal = the head's z axis), and the
    intersection is taken into head coordinates, ``x_head = Rᵀ (x_cam − t)``. A point that moves on the face
    plane at its generic depth is thus recovered exactly whatever the head pose; the z coordinate of every
    point equals the generic face's.

    Parameters
    ----------
    curves : (C, 4, 2) float
        Control points in image pixels, ``curve_names`` order.
    pose : HeadPose
    frame_size : (2,) int, optional
        Width and height, to build the camera with ``focal``; default the pose's own camera.
    focal : float, optional
    curve_names : tuple of str

    Returns
    -------
    (C * len(POINT_SAMPLES), 3) float, cm; all NaN if the pose failed.
    """
    curves = np.asarray(curves, dtype=float)
    if curves.shape != (len(curve_names), 4, 2):
        raise ValueError(f"curves must have shape ({len(curve_names)}, 4, 2), got {curves.shape}")
    generic = GENERIC_POINTS if tuple(curve_names) == CURVE_NAMES else generic_points(curve_names)
    if not pose:
        return np.full(generic.shape, np.nan)
    if frame_size is None:
        K = pose.camera_matrix
    else:
        K = camera_matrix(float(frame_size[0]), float(frame_size[1]), None if focal is None else float(focal))
    R, t = np.asarray(pose.rotation, dtype=float), np.asarray(pose.translation, dtype=float)
    return _back_project(np.ascontiguousarray(curves), _SAMPLE_BASIS, np.ascontiguousarray(generic, dtype=float),
                         np.asarray(K, dtype=float), np.ascontiguousarray(R), np.ascontiguousarray(t))


@nb.njit(**KERNEL)
def _back_project(curves: np.ndarray, basis: np.ndarray, generic: np.ndarray, K: np.ndarray, R: np.ndarray,
                  t: np.ndarray) -> np.ndarray:
    """The work of :func:`points_in_head`: each curve sample's camera ray X = depth · ray met with the plane
    through its generic point with normal the head's z axis, then Rᵀ (X − t); NaN where the ray runs along
    the plane."""
    n_curves, n_samples = curves.shape[0], basis.shape[0]
    out = np.empty((n_curves * n_samples, 3))
    nx, ny, nz = R[0, 2], R[1, 2], R[2, 2]                          # head z axis in the camera
    for c in range(n_curves):
        for s in range(n_samples):
            i = c * n_samples + s
            u = v = 0.0
            for j in range(4):
                u += basis[s, j] * curves[c, j, 0]
                v += basis[s, j] * curves[c, j, 1]
            rx, ry = (u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1]
            denom = rx * nx + ry * ny + nz
            depth = np.nan
            if abs(denom) > 1e-6:
                a = 0.0                                             # generic point in the camera, along the normal
                for r in range(3):
                    a += (R[r, 0] * generic[i, 0] + R[r, 1] * generic[i, 1] + R[r, 2] * generic[i, 2] + t[r]) * R[r, 2]
                depth = a / denom
            d0, d1, d2 = rx * depth - t[0], ry * depth - t[1], depth - t[2]
            for k in range(3):
                out[i, k] = d0 * R[0, k] + d1 * R[1, k] + d2 * R[2, k]
    return out
