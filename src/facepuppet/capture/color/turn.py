"""The colour tracker's head turn, frame by frame: the yaw and pitch read off the crop by a trained profile's
head-turn model (:mod:`.head_turn`) or measured on the nose with the built-in profile (:mod:`.nose_turn`),
filtered over time, and composed with the roll of the pose solved upright.

The face frame is an in-plane similarity on the eyes, so the layout's stable points show the head's roll, size
and place but no turn: the pose is solved upright (:func:`~facepuppet.capture.pose.estimate_pose` without its
out-of-plane angles), and the turn read here is put on it, ``R = R_frontal · Ry(yaw) · Rx(pitch) · Rz(roll)``,
the yaw and pitch with a share of the direction of the line of sight through the inner eye corners
(:func:`~.head_turn.turn_angles`: :data:`~.head_turn.RAY_SHARE` for the model, :data:`~.nose_turn.LOOK_SHARE`
for the nose).

Conventions: angles in radians as :meth:`~facepuppet.capture.pose.HeadPose.angles`'; crop pixels ``px`` per face
unit; the layout placed on the crop as the tracker's measurement leaves it (``seen``).
"""

from __future__ import annotations

import numpy as np

from facepuppet.capture.color.face import CROP_EXTENT, similarity_of_pairs
from facepuppet.capture.color.head_turn import RAY_SHARE, apply_turn_model, turn_angles, turn_rotation
from facepuppet.capture.color.nose_turn import LOOK_SHARE, NoseTurn, face_to_image
from facepuppet.capture.curves import CURVE_NAMES
from facepuppet.capture.pose import FRONTAL_ROTATION, HeadPose
from facepuppet.filters import OneEuro, OneEuroConfig

__all__ = ["TURN_FILTER", "HeadTurn"]

_IDX = {n: i for i, n in enumerate(CURVE_NAMES)}
#: Two layout points the placement of the layout is read back from, the outer eye corners: their curves and their
#: control points, as a (C, 4, 2) array's index.
_PLACED_PAIR = ([_IDX["eye_right_upper"], _IDX["eye_left_upper"]], [3, 3])
#: The curves whose first control points are the inner eye corners.
_INNER_RIGHT, _INNER_LEFT = _IDX["eye_right_upper"], _IDX["eye_left_upper"]
#: The One-Euro filter of the yaw and pitch (radians). Read on every frame (the model's), a steady turn of 60
#: degrees a second lags a third of a frame at 30 frames a second, and a still head's frame-to-frame noise is cut
#: to a fifth; the nose's readings, held between the frames they are measured on, step at each.
TURN_FILTER = OneEuroConfig(min_cutoff=1.0, beta=10.0)


class HeadTurn:
    """The head's turn for one tracker: the profile's head-turn model (or the nose's measurement without one),
    the filter over time and the time of its last reading are the state.

    Parameters
    ----------
    model : dict of str -> ndarray
        The profile's head-turn model (:attr:`~.profile.Profile.head`); empty: the nose is measured.
    layout_px : (C, 4, 2) float
        The layout placed on an unmoved face crop, crop pixels.
    px : float
        Crop pixels per face unit.
    """

    def __init__(self, model: dict, layout_px: np.ndarray, px: float):
        self._model = model
        self._layout_pair = np.asarray(layout_px, dtype=float)[_PLACED_PAIR]     # (2, 2) the outer eye corners
        self._px = float(px)
        self._filter = OneEuro(TURN_FILTER)
        self._nose = NoseTurn()
        self._ms: int | None = None         # time of the last reading (None: the filter starts afresh)

    def restart(self) -> None:
        """The next reading starts the filter afresh (the face is being found anew; the nose's tip is kept, sought
        about its reference's place)."""
        self._ms = None
        self._nose.unfollow()

    def __call__(self, timestamp_ms: int, rgb: np.ndarray, seen: tuple[np.ndarray, np.ndarray, np.ndarray] | None
                 ) -> np.ndarray | None:
        """The (yaw, pitch) (2,) radians of the frame ``rgb`` of time ``timestamp_ms``, filtered over time, read off
        the last measurement's ``seen`` (its face crop, crop matrix and the layout placed on the crop); None before
        a face is measured."""
        if seen is None:
            return None
        crop, A, placed = seen
        nose = self._nose
        if self._model or nose.due:
            S = similarity_of_pairs(self._layout_pair, placed[_PLACED_PAIR])
            raw = (apply_turn_model(self._model, crop, S, self._px) if self._model
                   else nose(rgb, face_to_image(A, S, self._px, CROP_EXTENT[:2])))
        else:
            raw = nose.skip()
        if self._ms is None:
            self._filter.restart(raw)
            turn = raw
        else:
            turn = self._filter(raw, max(timestamp_ms - self._ms, 1) / 1000.0)
        self._ms = timestamp_ms
        return turn

    def posed(self, pose: HeadPose, turn: np.ndarray, curves: np.ndarray) -> HeadPose:
        """The upright ``pose`` turned by ``turn`` (yaw, pitch) and the share of the line of sight through the
        inner eye corners of ``curves`` (C, 4, 2) image pixels that goes with it (:func:`~.head_turn.turn_angles`),
        its roll kept."""
        inner = 0.5 * (curves[_INNER_RIGHT, 0] + curves[_INNER_LEFT, 0])
        yaw, pitch = turn_angles(turn, inner, pose.camera_matrix, RAY_SHARE if self._model else LOOK_SHARE)
        return HeadPose(FRONTAL_ROTATION @ turn_rotation(yaw, pitch, pose.roll),
                        pose.translation, pose.camera_matrix, pose.reprojection_error)
