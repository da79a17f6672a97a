"""Side-by-side preview writer: frame count, layout, atomicity."""

from __future__ import annotations

import numpy as np
import pytest

from facepuppet.errors import FacepuppetError
from facepuppet.export.preview import side_by_side, write_preview
from facepuppet.io.frames import open_media


def test_side_by_side_scales_the_right_to_the_left_height():
    out = side_by_side(np.zeros((48, 64, 3), np.uint8), np.full((96, 96, 3), 255, np.uint8))
    assert out.shape == (48, 64 + 48, 3)
    assert out[:, :64].max() == 0 and out[:, 64:].min() == 255


def test_preview_has_every_frame(tmp_path):
    frames = (np.full((48, 64, 3), 20 * k, np.uint8) for k in range(9))
    path = write_preview(tmp_path / "p.mp4", frames, 30.0, right=lambda k: np.full((48, 48, 3), 200, np.uint8),
                         left=lambda k, f: f, progress=False)
    with open_media(path) as src:
        got = list(src)
        assert src.frame_size == (112, 48)
    assert len(got) == 9
    assert abs(int(got[4][:, :64].mean()) - 80) < 8 and abs(int(got[4][:, 70:].mean()) - 200) < 8


def test_failure_leaves_no_file(tmp_path):
    def right(k):
        if k == 3:
            raise RuntimeError("renderer broke")
        return np.zeros((48, 48, 3), np.uint8)

    with pytest.raises(RuntimeError):
        write_preview(tmp_path / "p.mp4", (np.zeros((48, 64, 3), np.uint8) for _ in range(6)), 30.0, right=right,
                      progress=False)
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(FacepuppetError, match="no frames"):
        write_preview(tmp_path / "q.mp4", iter([]), 30.0, right=right, progress=False)
    assert list(tmp_path.iterdir()) == []
