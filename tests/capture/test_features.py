"""FrameFeatures and the Tracker protocol."""

import dataclasses

import numpy as np
import pytest

from facepuppet.capture.curves import CURVE_NAMES, POINT_NAMES
from facepuppet.capture.features import FrameFeatures, Tracker


def test_lost_frame_has_nan_arrays_of_the_right_shapes():
    f = FrameFeatures.lost(len(CURVE_NAMES), len(POINT_NAMES))
    assert not f.valid
    assert f.curves.shape == (12, 4, 2) and np.isnan(f.curves).all()
    assert f.rotation.shape == (3, 3) and np.isnan(f.rotation).all()
    assert f.translation.shape == (3,) and np.isnan(f.translation).all()
    assert f.points.shape == (48, 3) and np.isnan(f.points).all()
    assert f.extras is None


def test_frame_features_are_frozen():
    f = FrameFeatures.lost(2, 8)
    with pytest.raises(dataclasses.FrozenInstanceError):
        f.valid = True


def test_a_class_with_name_track_close_is_a_tracker():
    class Dummy:
        name = "dummy"

        def track(self, rgb, timestamp_ms):
            return FrameFeatures.lost(1, 4)

        def close(self):
            pass

    import inspect

    assert list(inspect.signature(Tracker.track).parameters) == ["self", "rgb", "timestamp_ms"]
    assert list(inspect.signature(Tracker.close).parameters) == ["self"]
    f = Dummy().track(np.zeros((4, 4, 3), np.uint8), 0)
    assert not f.valid and f.curves.shape == (1, 4, 2) and np.isnan(f.points).all()
