"""Head pose from stable facial features and a generic 3D face, and feature points with the pose removed.

Head coordinates (right-handed, centimetres): origin midway between the inner eye corners, **x to the
performer's left**, **y up**, **z out of the face** (towards a camera the performer looks into). Camera
coordinates are OpenCV's: x right, y down, z forward along the optical axis. A head seen frontally and upright
therefore has rotation ``diag(1, -1, -1)``; a point maps as ``x_cam = R @ x_head + t``.

The generic face is a table of named landmarks of an average adult face, built from textbook anthropometric
proportions (intercanthal width about 3.2 cm, biocular width about 9 cm, mouth width about 5 cm, nasal tip
about 2.4 cm proud of the inner eye corners). It is a prior, not a model of the performer: the pose needs only
the rigid, expression-free landmarks (eye corners, nose base), and the feature points take their depth from it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import lru_cache

import numba as nb
import numpy as np

from facepuppet._util.jit import INNER, KERNEL
from facepuppet.capture.curves import CURVE_NAMES, POINT_SAMPLES, bernstein, curve_points, fit_bezier

__all__ = [
    "GENERIC_FACE",
    "GENERIC_CURVE_LANDMARKS",
    "STABLE_FEATURES",
    "FRONTAL_ROTATION",
    "HeadPose",
    "FailedPose",
    "default_camera",
    "generic_curves",
    "generic_points",
    "estimate_pose",
    "pose_points_from_curves",
    "pose_point_index",
    "points_in_head",
]

# Left half of the generic face (x > 0 is the performer's left); the right half is its mirror image.
_LEFT_HALF: dict[str, tuple[float, float, float]] = {
    "brow_left_0": (1.7, 1.50, 0.20),   # inner end
    "brow_left_1": (2.6, 1.95, 0.15),
    "brow_left_2": (3.5, 2.10, -0.20),
    "brow_left_3": (4.4, 1.90, -0.80),
    "brow_left_4": (5.1, 1.40, -1.60),  # outer end
    "eye_left_inner": (1.6, 0.00, 0.00),
    "eye_left_upper_1": (2.4, 0.45, 0.15),
    "eye_left_upper_2": (3.6, 0.50, -0.20),
    "eye_left_outer": (4.5, 0.15, -1.20),
    "eye_left_lower_1": (2.5, -0.40, 0.05),
    "eye_left_lower_2": (3.6, -0.40, -0.30),
    "nostril_left_mid": (0.7, -4.40, 0.70),
    "ala_left": (1.4, -4.20, 0.20),
    "lip_upper_outer_left_1": (0.6, -5.85, 1.20),
    "lip_upper_outer_left_2": (1.5, -6.10, 0.80),
    "mouth_left": (2.5, -6.60, -0.30),
    "lip_lower_outer_left_1": (1.8, -7.10, 0.40),
    "lip_lower_outer_left_2": (0.9, -7.55, 0.90),
    "lip_upper_inner_left": (0.9, -6.55, 0.80),
    "mouth_inner_left": (2.2, -6.60, 0.00),
    "lip_lower_inner_left": (0.9, -6.60, 0.80),
}
_MIDLINE: dict[str, tuple[float, float, float]] = {
    "nasion": (0.0, 0.90, 0.60),
    "nose_tip": (0.0, -3.60, 2.40),
    "nose_base": (0.0, -4.50, 0.90),
    "lip_upper_outer_mid": (0.0, -5.90, 1.30),
    "lip_upper_inner_mid": (0.0, -6.55, 1.00),
    "lip_lower_inner_mid": (0.0, -6.60, 1.00),
    "lip_lower_outer_mid": (0.0, -7.70, 1.10),
    "chin": (0.0, -10.50, 0.60),
}


def _mirror(table: dict[str, tuple[float, float, float]]) -> dict[str, tuple[float, float, float]]:
    return {k.replace("left", "right"): (-x, y, z) for k, (x, y, z) in table.items()}


#: Named landmarks of the generic face, head coordinates in cm (see the module docstring).
GENERIC_FACE: dict[str, tuple[float, float, float]] = {**_LEFT_HALF, **_mirror(_LEFT_HALF), **_MIDLINE}

#: Landmarks of the generic face along each curve of the vocabulary, in the curve's direction (DESIGN.md).
GENERIC_CURVE_LANDMARKS: dict[str, tuple[str, ...]] = {
    "brow_left": tuple(f"brow_left_{i}" for i in range(5)),
    "brow_right": tuple(f"brow_right_{i}" for i in range(5)),
    "eye_left_upper": ("eye_left_inner", "eye_left_upper_1", "eye_left_upper_2", "eye_left_outer"),
    "eye_left_lower": ("eye_left_inner", "eye_left_lower_1", "eye_left_lower_2", "eye_left_outer"),
    "eye_right_upper": ("eye_right_inner", "eye_right_upper_1", "eye_right_upper_2", "eye_right_outer"),
    "eye_right_lower": ("eye_right_inner", "eye_right_lower_1", "eye_right_lower_2", "eye_right_outer"),
    "lip_upper_outer": ("mouth_right", "lip_upper_outer_right_2", "lip_upper_outer_right_1", "lip_upper_outer_mid",
                        "lip_upper_outer_left_1", "lip_upper_outer_left_2", "mouth_left"),
    "lip_lower_outer": ("mouth_right", "lip_lower_outer_right_1", "lip_lower_outer_right_2", "lip_lower_outer_mid",
                        "lip_lower_outer_left_2", "lip_lower_outer_left_1", "mouth_left"),
    "lip_upper_inner": ("mouth_inner_right", "lip_upper_inner_right", "lip_upper_inner_mid", "lip_upper_inner_left",
                        "mouth_inner_left"),
    "lip_lower_inner": ("mouth_inner_right", "lip_lower_inner_right", "lip_lower_inner_mid", "lip_lower_inner_left",
                        "mouth_inner_left"),
    "nostril_left": ("nose_base", "nostril_left_mid", "ala_left"),
    "nostril_right": ("ala_right", "nostril_right_mid", "nose_base"),
}

#: Landmarks that hardly move with expression; the default input of :func:`estimate_pose`.
STABLE_FEATURES: tuple[str, ...] = (
    "eye_right_outer", "eye_right_inner", "eye_left_inner", "eye_left_outer", "nose_base", "ala_right", "ala_left",
)

#: Where each stable landmark sits on the curves: (curve, index of the control point, 0 or 3).
_CURVE_ENDPOINTS: dict[str, tuple[str, int]] = {
    "eye_right_outer": ("eye_right_upper", 3),
    "eye_right_inner": ("eye_right_upper", 0),
    "eye_left_inner": ("eye_left_upper", 0),
    "eye_left_outer": ("eye_left_upper", 3),
    "nose_base": ("nostril_left", 0),
    "ala_left": ("nostril_left", 3),
    "ala_right": ("nostril_right", 0),
    "mouth_right": ("lip_upper_outer", 0),
    "mouth_left": ("lip_upper_outer", 3),
}

#: Rotation of a frontal, upright head (head x left = camera x right, head y up = camera -y, z towards camera).
FRONTAL_ROTATION = np.diag([1.0, -1.0, -1.0])

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
    return _camera(w, h, None if focal is None else float(focal)).copy()


@lru_cache(maxsize=16)
@lru_cache(maxsize=16)
def _camera(w: float, h: float, focal: float | None) -> np.ndarray:
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


@dataclass(frozen=True)
class FailedPose:
    """A pose that could not be solved; falsy, with the reason in words."""

    reason: str
    rotation: np.ndarray = field(default_factory=lambda: np.full((3, 3), np.nan))
    translation: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))

    def __bool__(self) -> bool:
        return False


def generic_curves(curve_names: tuple[str, ...] = CURVE_NAMES) -> np.ndarray:
    """The feature curves of the generic face in head coordinates, (C, 4, 3) control points, cm."""
    return np.stack([fit_bezier(np.array([GENERIC_FACE[n] for n in GENERIC_CURVE_LANDMARKS[c]]))
                     for c in curve_names])


_GENERIC_CURVES = generic_curves()
#: (P, 3) generic feature points in POINT_NAMES order (module constant; do not modify).
_GENERIC_POINTS = curve_points(_GENERIC_CURVES)
_GENERIC_POINTS.setflags(write=False)
_SAMPLE_BASIS = bernstein(np.asarray(POINT_SAMPLES))


def generic_points(curve_names: tuple[str, ...] = CURVE_NAMES) -> np.ndarray:
    """The feature points of the generic face (curves sampled at POINT_SAMPLES), (P, 3) head coordinates."""
    if tuple(curve_names) == CURVE_NAMES:
        return _GENERIC_POINTS.copy()
    return curve_points(generic_curves(curve_names))


def pose_points_from_curves(curves: np.ndarray, names: tuple[str, ...] = STABLE_FEATURES,
                            curve_names: tuple[str, ...] = CURVE_NAMES) -> dict[str, np.ndarray]:
    """Image positions of landmarks that are curve end points (eye corners, nose base, alae, mouth corners).

    Parameters
    ----------
    curves : (C, 4, 2) float
        Curves in ``curve_names`` order, image pixels.
    names : tuple of str
        Landmarks wanted (keys of the generic face that are curve ends).

    Returns
    -------
    dict of str -> (2,) float
    """
    index = {c: i for i, c in enumerate(curve_names)}
    out = {}
    for n in names:
        if n not in _CURVE_ENDPOINTS:
            raise ValueError(f"landmark {n!r} is not a curve end point; known: {', '.join(_CURVE_ENDPOINTS)}")
        c, k = _CURVE_ENDPOINTS[n]
        out[n] = np.asarray(curves[index[c], k], dtype=float)
    return out


def pose_point_index(names: tuple[str, ...] = STABLE_FEATURES,
                     curve_names: tuple[str, ...] = CURVE_NAMES) -> tuple[np.ndarray, np.ndarray]:
    """Where landmarks that are curve end points sit in a curves array: ``curves[index]`` is (N, 2).

    Returns
    -------
    (N,) int, (N,) int
        Curve index and control point index (0 or 3) of each landmark of ``names``.
    """
    index = {c: i for i, c in enumerate(curve_names)}
    unknown = [n for n in names if n not in _CURVE_ENDPOINTS]
    if unknown:
        raise ValueError(f"landmark {unknown[0]!r} is not a curve end point; known: {', '.join(_CURVE_ENDPOINTS)}")
    return (np.array([index[_CURVE_ENDPOINTS[n][0]] for n in names]),
            np.array([_CURVE_ENDPOINTS[n][1] for n in names]))


@lru_cache(maxsize=64)
def _generic_landmarks(names: tuple[str, ...]) -> np.ndarray:
    unknown = [n for n in names if n not in GENERIC_FACE]
    if unknown:
        raise ValueError(f"image_points: unknown landmark(s) {', '.join(unknown)}; see pose.GENERIC_FACE")
    xyz = np.array([GENERIC_FACE[n] for n in names], dtype=float).reshape(-1, 3)
    xyz.setflags(write=False)
    return xyz


def _as_correspondences(image_points, names):
    if isinstance(image_points, Mapping):
        names = tuple(image_points)
        uv = np.array([np.asarray(image_points[n], dtype=float).reshape(2) for n in names]).reshape(-1, 2)
    else:
        uv = np.asarray(image_points, dtype=float)
        names = tuple(names)
        if uv.shape != (len(names), 2):
            raise ValueError(f"image_points must be ({len(names)}, 2) for landmarks {names}, got shape {uv.shape}")
    return names, uv, _generic_landmarks(names)


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
        neck also moves across the image, that rotation runs against the real turn (the colour tracker's yaw
        correlated at -0.93 with the digital performer's true yaw and at -0.89 with MediaPipe's on a real
        clip before it used this).

    Returns
    -------
    HeadPose or FailedPose
        FailedPose (falsy) when there are too few finite points, the solver fails, the head would be behind
        the camera, or the generic face does not fit the points (mean reprojection error above 35 % of the
        eye-corner span).
    """
    import cv2

    names, uv, xyz = _as_correspondences(image_points, names)
    if not np.isfinite(uv).all():
        finite = np.isfinite(uv).all(axis=1)
        uv, xyz = uv[finite], xyz[finite]
        names = tuple(n for n, ok in zip(names, finite, strict=True) if ok)
    if len(uv) < 4:
        return FailedPose(f"head pose needs at least 4 finite landmarks, got {len(uv)}")
    K = _camera(float(frame_size[0]), float(frame_size[1]), None if focal is None else float(focal))
    if not out_of_plane:
        start = _upright_start(K, xyz, uv) if not previous else (
            float(HeadPose(previous.rotation, previous.translation, K).angles()[2]),
            np.asarray(previous.translation, dtype=float))
        roll, t, ok = _refine_upright(xyz, uv, K, start[0], start[1].copy())
        if not ok or not np.isfinite(t).all():
            return FailedPose("upright head pose did not converge")
        c, s = np.cos(roll), np.sin(roll)
        R = FRONTAL_ROTATION @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        return _checked_pose(R, t, K, xyz, uv, names)
    if previous:
        # From last frame's pose a few Gauss-Newton steps on the same reprojection error converge.
        R, t, ok = _refine_pose(xyz, uv, K, np.asarray(previous.rotation, dtype=float),
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


def _upright_start(K: np.ndarray, xyz: np.ndarray, uv: np.ndarray) -> tuple[float, np.ndarray]:
    """A first upright pose, ``R = FRONTAL_ROTATION @ Rz(roll)`` (no yaw or pitch), as (roll, t).

    With that R, ``R X = (c X_x − s X_y, −s X_x − c X_y, −X_z)`` (c, s the roll's cosine and sine), and each
    point's projection ``u = f_x (R X + t)_x / (R X + t)_z + c_x`` (v alike), multiplied out, is linear in
    (c, s, t): ``f_x (c X_x − s X_y + t_x) − (u − c_x) t_z = −(u − c_x) X_z`` and
    ``f_y (−s X_x − c X_y + t_y) − (v − c_y) t_z = −(v − c_y) X_z``. The least-squares solution of those
    2N equations gives the roll ``atan2(s, c)``, and t is solved again with the roll fixed; exact for the
    points of an upright head, a start for :func:`_refine_upright` otherwise.
    """
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    X, Y, Z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    du, dv = uv[:, 0] - cx, uv[:, 1] - cy
    n = len(xyz)
    zero, one = np.zeros(n), np.ones(n)
    A = np.vstack([np.column_stack([fx * X, -fx * Y, fx * one, zero, -du]),
                   np.column_stack([-fy * Y, -fy * X, zero, fy * one, -dv])])
    c, s = np.linalg.lstsq(A, np.concatenate([-du * Z, -dv * Z]), rcond=None)[0][:2]
    roll = float(np.arctan2(s, c))
    c, s = np.cos(roll), np.sin(roll)
    rest = np.concatenate([-du * Z - fx * (c * X - s * Y), -dv * Z - fy * (-s * X - c * Y)])
    return roll, np.linalg.lstsq(A[:, 2:], rest, rcond=None)[0]


@nb.njit(**KERNEL)
def _refine_upright(xyz: np.ndarray, uv: np.ndarray, K: np.ndarray, roll: float, t: np.ndarray,
                    iterations: int = 10, tol: float = 1e-6):
    """Gauss-Newton on the reprojection error over (roll, t) of the upright pose ``FRONTAL_ROTATION @ Rz(roll)``.

    ``R X + t = (c X_x − s X_y + t_x, −s X_x − c X_y + t_y, t_z − X_z)``; its derivative in the roll is
    ``(−s X_x − c X_y, −c X_x + s X_y, 0)``. Returns (roll, t, converged).
    """
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    JtJ = np.empty((4, 4))
    Jtr = np.empty(4)
    j = np.empty(4)
    for _ in range(iterations):
        c, s = np.cos(roll), np.sin(roll)
        JtJ[:] = 0.0
        Jtr[:] = 0.0
        for i in range(len(xyz)):
            X, Y, Z = xyz[i, 0], xyz[i, 1], xyz[i, 2]
            px, py, pz = c * X - s * Y + t[0], -s * X - c * Y + t[1], t[2] - Z
            if pz <= 0.0:
                return roll, t, False
            iz = 1.0 / pz
            for axis in range(2):
                if axis == 0:
                    f, p, dp, r = fx, px, -s * X - c * Y, fx * px * iz + cx - uv[i, 0]
                    j[1], j[2] = f * iz, 0.0
                else:
                    f, p, dp, r = fy, py, -c * X + s * Y, fy * py * iz + cy - uv[i, 1]
                    j[1], j[2] = 0.0, f * iz
                j[0] = f * dp * iz
                j[3] = -f * p * iz * iz
                for a in range(4):
                    Jtr[a] += j[a] * r
                    for b in range(4):
                        JtJ[a, b] += j[a] * j[b]
        step = _solve_spd(JtJ, -Jtr)
        roll += step[0]
        t = t + step[1:]
        if abs(step[0]) < tol and np.sqrt(step[1] ** 2 + step[2] ** 2 + step[3] ** 2) < tol * max(abs(t[2]), 1.0):
            return roll, t, True
    return roll, t, False


def _checked_pose(R: np.ndarray, t: np.ndarray, K: np.ndarray, xyz: np.ndarray, uv: np.ndarray,
                  names: tuple[str, ...]) -> HeadPose | FailedPose:
    if t[2] <= 0:
        return FailedPose("head pose puts the head behind the camera")
    err = _reprojection_error(xyz, uv, K, R, t)
    scale = _eye_span(names, uv)
    if scale is not None and err > _MAX_REPROJECTION * scale:
        return FailedPose(f"generic face does not fit the landmarks (mean reprojection error {err:.1f} px)")
    return HeadPose(R, t, K, err)


@nb.njit(**INNER)
def _solve_spd(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x with A x = b for a small symmetric positive definite A (Cholesky, A = L Lᵀ)."""
    n = len(b)
    L = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1):
            s = A[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = np.sqrt(max(s, 1e-300)) if i == j else s / L[j, j]
    y = np.empty(n)
    for i in range(n):
        s = b[i]
        for k in range(i):
            s -= L[i, k] * y[k]
        y[i] = s / L[i, i]
    x = np.empty(n)
    for i in range(n - 1, -1, -1):
        s = y[i]
        for k in range(i + 1, n):
            s -= L[k, i] * x[k]
        x[i] = s / L[i, i]
    return x


@nb.njit(**KERNEL)
def _refine_pose(xyz: np.ndarray, uv: np.ndarray, K: np.ndarray, R0: np.ndarray, t0: np.ndarray,
                 iterations: int = 10, tol: float = 1e-5):
    """Gauss-Newton on the reprojection error Σ |π(K (R X + t)) − u|² from (R0, t0).

    Steps are (ω, δt) with R ← exp([ω]×) R, t ← t + δt; ∂P/∂ω = −[R X]×, ∂P/∂t = I for the camera point
    P = R X + t. Returns (R, t, converged); not converged when a point falls behind the camera or the steps
    do not settle (then the caller starts over with the full solver). Settled: a step under ``tol`` radians
    and ``tol`` of the depth. With a performer's own layout the residual stays large and Gauss-Newton
    converges only linearly: at 1e-7, 208 of performer_c's 215 frames fell back to solvePnP; at 1e-5 none
    does, and the pose differs from solvePnP's by at most 0.014 degrees.
    """
    n = len(xyz)
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    R = R0.copy()
    t = t0.copy()
    JtJ = np.empty((6, 6))
    Jtr = np.empty(6)
    J = np.empty((2, 6))
    q = np.empty(3)
    for _ in range(iterations):
        JtJ[:] = 0.0
        Jtr[:] = 0.0
        for i in range(n):
            for r in range(3):
                q[r] = R[r, 0] * xyz[i, 0] + R[r, 1] * xyz[i, 1] + R[r, 2] * xyz[i, 2]
            px, py, pz = q[0] + t[0], q[1] + t[1], q[2] + t[2]
            if pz <= 1e-9:
                return R, t, False
            iz = 1.0 / pz
            res0 = fx * px * iz + cx - uv[i, 0]
            res1 = fy * py * iz + cy - uv[i, 1]
            # d(u, v)/dP, then dP/dω = -[q]x (columns e_k x q) and dP/dt = I.
            a0, a2 = fx * iz, -fx * px * iz * iz
            b1, b2 = fy * iz, -fy * py * iz * iz
            J[0, 0], J[0, 1], J[0, 2] = a2 * q[1], a0 * q[2] - a2 * q[0], -a0 * q[1]
            J[1, 0], J[1, 1], J[1, 2] = -b1 * q[2] + b2 * q[1], -b2 * q[0], b1 * q[0]
            J[0, 3], J[0, 4], J[0, 5] = a0, 0.0, a2
            J[1, 3], J[1, 4], J[1, 5] = 0.0, b1, b2
            for k in range(6):
                Jtr[k] += J[0, k] * res0 + J[1, k] * res1
                for m in range(6):
                    JtJ[k, m] += J[0, k] * J[0, m] + J[1, k] * J[1, m]
        for k in range(6):
            JtJ[k, k] += 1e-9
        step = _solve_spd(JtJ, -Jtr)
        w0, w1, w2 = step[0], step[1], step[2]
        theta = np.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
        W = np.array([[0.0, -w2, w1], [w2, 0.0, -w0], [-w1, w0, 0.0]])
        if theta > 1e-12:
            E = np.eye(3) + np.sin(theta) / theta * W + (1.0 - np.cos(theta)) / theta ** 2 * (W @ W)
        else:
            E = np.eye(3) + W
        R = E @ R
        t = t + step[3:]
        if theta < tol and np.sqrt(step[3] ** 2 + step[4] ** 2 + step[5] ** 2) < tol * max(abs(t[2]), 1.0):
            return R, t, True
    return R, t, False


@nb.njit(**KERNEL)
def _reprojection_error(xyz: np.ndarray, uv: np.ndarray, K: np.ndarray, R: np.ndarray, t: np.ndarray) -> float:
    """Mean distance (pixels) between the image points uv (N, 2) and the head points xyz (N, 3) projected."""
    total = 0.0
    p = np.empty(3)
    for i in range(len(xyz)):
        for r in range(3):
            p[r] = R[r, 0] * xyz[i, 0] + R[r, 1] * xyz[i, 1] + R[r, 2] * xyz[i, 2] + t[r]
        z = K[2, 0] * p[0] + K[2, 1] * p[1] + K[2, 2] * p[2]
        du = (K[0, 0] * p[0] + K[0, 1] * p[1] + K[0, 2] * p[2]) / z - uv[i, 0]
        dv = (K[1, 0] * p[0] + K[1, 1] * p[1] + K[1, 2] * p[2]) / z - uv[i, 1]
        total += np.sqrt(du * du + dv * dv)
    return total / len(xyz)


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
    generic = _GENERIC_POINTS if tuple(curve_names) == CURVE_NAMES else generic_points(curve_names)
    if not pose:
        return np.full(generic.shape, np.nan)
    if frame_size is None:
        K = pose.camera_matrix
    else:
        K = _camera(float(frame_size[0]), float(frame_size[1]), None if focal is None else float(focal))
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
