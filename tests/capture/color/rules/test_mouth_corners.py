"""The mouth's corners on the line where the lips meet, not on shade that the mouth blob runs into."""

import numpy as np
import pytest

from facepuppet.capture.color.profile import GENERIC_MOUTH_REACH
from facepuppet.capture.color.rules import BLOB_PARAMS, outline_features
from facepuppet.capture.curves import CURVE_NAMES


def _scene():
    from facepuppet.capture.color.tracker import ColorTracker

    t = ColorTracker()
    w, h = t.crop_size
    return t.layout_in_crop, t.feature_boxes, (h, w), t.config.measure.px


def _mouth_with_shade(fold: bool):
    """A closed mouth drawn on the layout: lips (high in C, HSV value 120) from 2 rows above the layout's corner
    line to 8 below it, the line itself dark (value 60); skin of value 200. With ``fold``, the blob runs on past
    the right end of the lips into a shaded fold 5 columns wide, lower than the lips (high in C too) and darkening
    downwards from 140 to 104 with no dark line in it. Returns the curves, the line's row and the lips' ends."""
    layout, boxes, (h, w), px = _scene()
    uo = CURVE_NAMES.index("lip_upper_outer")
    xl, xr = int(layout[uo, 0, 0]) + 1, int(layout[uo, 3, 0]) - 1
    line = int(round(0.5 * (layout[uo, 0, 1] + layout[uo, 3, 1])))
    C = np.zeros((h, w), np.float32)
    value = np.full((h, w), 200, np.uint8)
    C[line - 2:line + 9, xl:xr] = 1.0
    value[line - 2:line + 9, xl:xr] = 120
    value[line, xl:xr] = 60
    if fold:
        rows = np.arange(line + 3, line + 13)
        C[rows[0]:rows[-1] + 1, xr:xr + 5] = 1.0
        value[rows[0]:rows[-1] + 1, xr:xr + 5] = np.linspace(140, 104, len(rows)).astype(np.uint8)[:, None]
    out = outline_features(C, raw=np.zeros((h, w), np.float32), value=value, layout=layout, boxes=boxes,
                           blob_params=BLOB_PARAMS, unit=px, mouth_reach=GENERIC_MOUTH_REACH)
    return out, line, xl, xr


@pytest.mark.parametrize("fold", [False, True])
def test_corners_stay_on_the_lips_line_next_to_a_shaded_fold(fold):
    """The blob's last columns are the fold's (darkest at their bottom, 10 pixels below the line): the right
    corner still lies on the lips' dark line, as the left one does, and as both do without the fold."""
    out, line, xl, xr = _mouth_with_shade(fold)
    uo = CURVE_NAMES.index("lip_upper_outer")
    assert out[uo, 0, 1] == pytest.approx(line + 0.5, abs=1.0), (out[uo, 0, 1], line)
    assert out[uo, 3, 1] == pytest.approx(line + 0.5, abs=1.0), (out[uo, 3, 1], line)
    # Each lip curve ends at the corners.
    lo = CURVE_NAMES.index("lip_lower_outer")
    assert np.allclose(out[lo, [0, 3]], out[uo, [0, 3]])
