import cv2
import numpy as np
import pytest

from facepuppet.errors import FacepuppetError
from facepuppet.io.frames import open_media


def write_video(path, frames, fps=25):
    h, w = frames[0].shape[:2]
    out = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, (w, h))
    for f in frames:
        out.write(cv2.cvtColor(f, cv2.COLOR_RGB2BGR))
    out.release()


def test_video_yields_rgb_frames_with_rate_and_size(tmp_path):
    frames = [np.full((48, 64, 3), (200, 30, 10), np.uint8) for _ in range(7)]
    path = tmp_path / "v.avi"
    write_video(path, frames)
    with open_media(path) as src:
        assert src.fps == pytest.approx(25)
        assert src.frame_size == (64, 48)
        got = list(src)
    assert len(got) == 7
    assert got[0].shape == (48, 64, 3) and got[0].dtype == np.uint8
    assert abs(int(got[3][10, 10, 0]) - 200) < 12 and got[3][10, 10, 2] < 40  # red stays red: RGB order


def test_camera_name_with_a_video_standing_in(tmp_path):
    path = tmp_path / "cam.avi"
    write_video(path, [np.zeros((32, 32, 3), np.uint8)] * 3)
    with open_media(f"camera:{path}") as src:
        assert src.is_camera and src.frame_count is None
        assert len(list(src)) == 3


def test_image_and_folder(tmp_path):
    img = np.zeros((20, 30, 3), np.uint8)
    img[..., 1] = 255
    cv2.imwrite(str(tmp_path / "a.png"), cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
    cv2.imwrite(str(tmp_path / "b.png"), cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
    with open_media(tmp_path / "a.png") as src:
        (frame,) = list(src)
    assert frame[0, 0, 1] == 255 and frame[0, 0, 0] == 0
    with open_media(tmp_path) as src:
        assert src.frame_count == 2 and len(list(src)) == 2


def test_bad_media_is_named(tmp_path):
    with pytest.raises(FacepuppetError, match="nothing.mp4: no such file"):
        open_media(tmp_path / "nothing.mp4")
    corrupt = tmp_path / "corrupt.mp4"
    corrupt.write_bytes(b"\x00" * 1000)
    with pytest.raises(FacepuppetError, match="corrupt.mp4"):
        open_media(corrupt)
    (tmp_path / "empty").mkdir()
    with pytest.raises(FacepuppetError, match="holds no images"):
        open_media(tmp_path / "empty")
    bad_img = tmp_path / "bad.png"
    bad_img.write_bytes(b"png?")
    with pytest.raises(FacepuppetError, match="bad.png: cannot read image"):
        open_media(bad_img)
