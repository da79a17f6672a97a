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


def frames_and_threads(path, threads, n):
    with open_media(path, decode_threads=threads) as src:
        return [f for _, f in zip(range(n), src, strict=False)], src.decode_threads


@pytest.mark.parametrize("threads", [1, 3])
def test_a_videos_frames_are_the_same_on_any_number_of_decoder_threads(assets, threads):
    """H.264 (the shared clips) decoded on the reading thread alone or on 3 frame threads: the same pixels as
    FFmpeg's default count, frame for frame."""
    path = assets / "video" / "performer_c.mp4"
    default, _ = frames_and_threads(path, None, 10_000)
    got, used = frames_and_threads(path, threads, 10_000)
    assert used == threads
    assert len(got) == len(default) == 216
    assert all(np.array_equal(a, b) for a, b in zip(got, default, strict=True))


def test_decoder_threads_of_a_written_video_and_of_what_takes_none(tmp_path):
    rng = np.random.default_rng(3)
    frames = [rng.integers(0, 256, (48, 64, 3), dtype=np.uint8) for _ in range(12)]
    path = tmp_path / "v.mp4"
    h, w = frames[0].shape[:2]
    out = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 25, (w, h))
    for f in frames:
        out.write(f)
    out.release()
    one, used = frames_and_threads(path, 1, 100)
    two, used_two = frames_and_threads(path, 2, 100)
    assert (used, used_two) == (1, 2) and len(one) == 12
    assert all(np.array_equal(a, b) for a, b in zip(one, two, strict=True))
    with pytest.raises(FacepuppetError, match="no such file"):
        open_media(tmp_path / "none.mp4", decode_threads=1)
    cv2.imwrite(str(tmp_path / "a.png"), frames[0])
    with open_media(tmp_path / "a.png", decode_threads=1) as src:       # a still takes no thread count
        assert src.decode_threads is None and len(list(src)) == 1


def test_container_frame_count_of_a_video_and_of_what_is_not_one(tmp_path):
    from facepuppet.io.frames import container_frame_count

    path = tmp_path / "v.avi"
    write_video(path, [np.zeros((32, 32, 3), np.uint8)] * 9)
    assert container_frame_count(path) == 9
    with open_media(path) as src:
        assert src.frame_count == 9
    corrupt = tmp_path / "corrupt.mp4"
    corrupt.write_bytes(b"\x00" * 1000)
    cv2.imwrite(str(tmp_path / "a.png"), np.zeros((8, 8, 3), np.uint8))
    for name in (corrupt, tmp_path / "none.mp4", tmp_path / "a.png", tmp_path, f"camera:{path}"):
        assert container_frame_count(name) is None
