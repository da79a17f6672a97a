"""The feature curves of one face crop: §3.2's rules from the layout placed on the crop, the lips refined as snakes
(Eqs. 2-4, Fig. 3), the lids by the performer's eyelid model, the lips, brows and eyes by the performer's shape
models (each where the profile has one; a shape model makes the rules it replaces needless).

:class:`Outliner` does it for a :class:`~facepuppet.capture.color.tracker.ColorTracker`, which places the
layout and the rectangles on the crop.

Conventions: crop pixels (x right, y down); curves (C, 4, 2) control points in
:data:`~facepuppet.capture.curves.CURVE_NAMES` order; rectangles in the order of
:data:`~facepuppet.capture.color.rules.BOX_NAMES`.
"""

from __future__ import annotations

import numpy as np

from facepuppet.capture.color.config import MeasureConfig
from facepuppet.capture.color.lids import PATCH_SIZE, apply_lid_model
from facepuppet.capture.color.profile import Profile
from facepuppet.capture.color.rules import BLOB_PARAMS, BOX_NAMES, outline_features
from facepuppet.capture.color.shape_models import apply_shape_models
from facepuppet.capture.color.snakes import LOWER, UPPER, SnakeSolver, lip_field, snake_fields
from facepuppet.capture.curves import CURVE_NAMES

__all__ = ["Outliner", "SNAKE_MARGIN", "SNAKE_BLUR", "SNAKE_CURVES"]

# Tuning constants                 unit                  what it does
SNAKE_MARGIN = 8                   # crop pixels           around the mouth rectangle the snakes see
SNAKE_BLUR = 5                     # crop pixels           blur of the snakes' fields (:func:`.snakes.snake_fields`)

#: Curves refined as snakes, with the side their feature lies on (Fig. 3).
SNAKE_CURVES = (("lip_upper_outer", UPPER),
                ("lip_lower_outer", LOWER))

_IDX = {n: i for i, n in enumerate(CURVE_NAMES)}
_SNAKE_IDX = np.array([_IDX[n] for n, _ in SNAKE_CURVES], dtype=np.int64)
_SNAKE_SIDE = np.array([s for _, s in SNAKE_CURVES])
_SNAKE_FIXED = np.ones(len(SNAKE_CURVES), bool)
_MOUTH_BOX = BOX_NAMES.index("mouth")
_UP = np.array([0.0, -1.0])                                # the head's up-vector in the upright crop


class Outliner:
    """The curves of a face crop for one performer profile.

    Parameters
    ----------
    profile : Profile
        The performer profile (its lip reach, eyelid model and shape models).
    config : MeasureConfig
        The parts of the rules to run (less those the profile's shape models replace) and the snakes' options.
    """

    def __init__(self, profile: Profile, config: MeasureConfig):
        self.profile = profile
        self.snakes = SnakeSolver(_SNAKE_SIDE, _UP, config.snake, fixed_ends=_SNAKE_FIXED)
        # The rules whose curves the shape models replace are not run.
        shaped = set(profile.shapes)
        replaced = {"mouth"} if "lips" in shaped else set()
        replaced |= {"brows"} if {"brow_left", "brow_right"} <= shaped else set()
        replaced |= {"eyes"} if {"eye_left", "eye_right"} <= shaped else set()
        #: The parts of §3.2's rules run (the configured ones less those the shape models replace).
        self.parts = tuple(p for p in config.outline_parts if p not in replaced)
        # The eyelid model goes with the eyes' rules: where those are not run, it is not either.
        #: The eyelid model's arrays (float64), or {} when it is not applied.
        self.lids = ({k: np.ascontiguousarray(v, dtype=np.float64) for k, v in profile.lids.items()}
                     if "eyes" in self.parts else {})

    def __call__(self, C: np.ndarray, *, raw: np.ndarray, value: np.ndarray, crop: np.ndarray, layout: np.ndarray,
                 boxes: np.ndarray, unit: float, mouth_offset: np.ndarray) -> np.ndarray:
        """The curves (C, 4, 2) in crop pixels.

        Parameters
        ----------
        C, raw : (H, W) float32
            The contrast C of the crop and Eq. 1's intensity before it.
        value : (H, W) uint8
            HSV value of the crop.
        crop : (H, W, 3) uint8
            The face crop, RGB.
        layout : (C, 4, 2) float64
            The profile's layout placed on the crop.
        boxes : (len(BOX_NAMES), 4) int64
            The feature rectangles of this frame.
        unit : float
            Crop pixels per face unit.
        mouth_offset : (2,) float64
            Crop pixels the mouth sits off the layout.
        """
        curves_px = outline_features(C, raw=raw, value=value, layout=layout, boxes=boxes,
                                     blob_params=BLOB_PARAMS, unit=unit, mouth_reach=float(self.profile.mouth_reach),
                                     mouth_offset=mouth_offset, parts=self.parts, rgb=crop)
        idx = _SNAKE_IDX
        if len(idx) and "mouth" in self.parts:
            # The snakes see the mouth rectangle and a margin (the fields are only computed there).
            h, w = C.shape
            m = SNAKE_MARGIN
            x0, y0, x1, y1 = boxes[_MOUTH_BOX]
            x0, y0, x1, y1 = max(x0 - m, 0), max(y0 - m, 0), min(x1 + m, w), min(y1 + m, h)
            if x1 - x0 > 2 * m and y1 - y0 > 2 * m:
                o = np.array([x0, y0], dtype=float)
                # The opening painted at the lips' level: the snakes see the lips' outline (:func:`.snakes.lip_field`).
                field = snake_fields(lip_field(C[y0:y1, x0:x1], curves_px - o), SNAKE_BLUR)
                curves_px[idx] = self.snakes(curves_px[idx] - o, field) + o
        if self.lids:
            # The performer's eyelid model reads the lids off the look of each eye (:mod:`.lids`).
            apply_lid_model(curves_px, crop, self.lids)
        if self.profile.shapes:
            apply_shape_models(curves_px, crop, layout, self.profile.shapes)
        return curves_px

    def warmup_snakes(self, curves: np.ndarray, size: tuple[int, int]) -> None:
        """Run the snakes once on blank fields of a crop of ``size`` (w, h) from ``curves`` (C, 4, 2) float64
        (numba compiles or loads their kernels)."""
        w, h = size
        self.snakes(curves[_SNAKE_IDX], snake_fields(lip_field(np.zeros((h, w), np.float32), curves), SNAKE_BLUR))

    @staticmethod
    def warmup_lids(curves: np.ndarray, crop: np.ndarray) -> None:
        """Run an eyelid model of zeros once on ``crop`` (H, W, 3) uint8 and a copy of ``curves`` (C, 4, 2)."""
        lids = {"coef": np.zeros((2, PATCH_SIZE[0] * PATCH_SIZE[1])), "intercept": np.zeros(2)}
        apply_lid_model(curves.copy(), crop, lids)
