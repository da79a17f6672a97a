"""The colour tracker's feature rules (§3.2): the layout's curves moved onto each feature's blob."""

from facepuppet.capture.color.rules.outline import (
    BLOB_CONFIGS,
    BLOB_KINDS,
    BLOB_PARAMS,
    BOX_NAMES,
    OUTLINE_PARTS,
    move_boxes,
    outline_features,
)

__all__ = ["BLOB_CONFIGS", "BLOB_KINDS", "BLOB_PARAMS", "BOX_NAMES", "OUTLINE_PARTS", "move_boxes", "outline_features"]
