"""The generic 3D face of the head pose: named landmarks of an average adult face, and its feature curves.

Head coordinates (right-handed, centimetres): origin midway between the inner eye corners, **x to the
performer's left**, **y up**, **z out of the face** (towards a camera the performer looks into).

The generic face is a table of named landmarks built from textbook anthropometric proportions (intercanthal
width about 3.2 cm, biocular width about 9 cm, mouth width about 5 cm, nasal tip about 2.4 cm proud of the inner
eye corners). It is a prior, not a model of the performer: the pose needs only the rigid, expression-free
landmarks (eye corners, nose base), and the feature points take their depth from it.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from facepuppet.capture.curves import CURVE_NAMES, curve_points, fit_bezier

__all__ = [
    "GENERIC_FACE",
    "GENERIC_CURVE_LANDMARKS",
    "GENERIC_CURVES",
    "GENERIC_POINTS",
    "STABLE_FEATURES",
    "CURVE_ENDPOINTS",
    "FRONTAL_ROTATION",
    "generic_curves",
    "generic_points",
    "generic_landmarks",
    "pose_points_from_curves",
    "pose_point_index",
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


#: Landmarks that hardly move with expression; the default input of
#: :func:`~facepuppet.capture.pose.estimate_pose`.
STABLE_FEATURES: tuple[str, ...] = (
    "eye_right_outer", "eye_right_inner", "eye_left_inner", "eye_left_outer", "nose_base", "ala_right", "ala_left",
)


#: Where each stable landmark sits on the curves: (curve, index of the control point, 0 or 3).
CURVE_ENDPOINTS: dict[str, tuple[str, int]] = {
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


def generic_curves(curve_names: tuple[str, ...] = CURVE_NAMES) -> np.ndarray:
    """The feature curves of the generic face in head coordinates, (C, 4, 3) control points, cm."""
    return np.stack([fit_bezier(np.array([GENERIC_FACE[n] for n in GENERIC_CURVE_LANDMARKS[c]]))
                     for c in curve_names])


#: (C, 4, 3) generic feature curves in CURVE_NAMES order (module constant; do not modify).
GENERIC_CURVES = generic_curves()
GENERIC_CURVES.setflags(write=False)
#: (P, 3) generic feature points in POINT_NAMES order (module constant; do not modify).
GENERIC_POINTS = curve_points(GENERIC_CURVES)
GENERIC_POINTS.setflags(write=False)


def generic_points(curve_names: tuple[str, ...] = CURVE_NAMES) -> np.ndarray:
    """The feature points of the generic face (curves sampled at POINT_SAMPLES), (P, 3) head coordinates."""
    if tuple(curve_names) == CURVE_NAMES:
        return GENERIC_POINTS.copy()
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
        if n not in CURVE_ENDPOINTS:
            raise ValueError(f"landmark {n!r} is not a curve end point; known: {', '.join(CURVE_ENDPOINTS)}")
        c, k = CURVE_ENDPOINTS[n]
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
    unknown = [n for n in names if n not in CURVE_ENDPOINTS]
    if unknown:
        raise ValueError(f"landmark {unknown[0]!r} is not a curve end point; known: {', '.join(CURVE_ENDPOINTS)}")
    return (np.array([index[CURVE_ENDPOINTS[n][0]] for n in names]),
            np.array([CURVE_ENDPOINTS[n][1] for n in names]))


@lru_cache(maxsize=64)
def generic_landmarks(names: tuple[str, ...]) -> np.ndarray:
    unknown = [n for n in names if n not in GENERIC_FACE]
    if unknown:
        raise ValueError(f"image_points: unknown landmark(s) {', '.join(unknown)}; see pose.GENERIC_FACE")
    xyz = np.array([GENERIC_FACE[n] for n in names], dtype=float).reshape(-1, 3)
    xyz.setflags(write=False)
    return xyz
