import numpy as np
import pytest

from facepuppet._util.npz import check_format, read_npz
from facepuppet.errors import FacepuppetError


def test_reads_every_array(tmp_path):
    path = tmp_path / "a.npz"
    np.savez(path, x=np.arange(3), format=np.asarray("kind"), version=np.asarray(2))
    arrays = read_npz(path, "kind file")
    np.testing.assert_array_equal(arrays["x"], [0, 1, 2])
    assert check_format(arrays, path, "kind file", "kind", 3) == 2


@pytest.mark.parametrize("content, match", [
    (None, "no such file"),
    (b"", "cannot read kind file"),
    (b"garbage", "cannot read kind file"),
])
def test_unreadable_files_are_named(tmp_path, content, match):
    path = tmp_path / "bad.npz"
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(FacepuppetError, match=f"bad.npz: {match}"):
        read_npz(path, "kind file")


def test_pickled_and_plain_arrays_are_refused(tmp_path):
    obj = tmp_path / "obj.npz"
    np.savez(obj, x=np.array([{"a": 1}], dtype=object))
    with pytest.raises(FacepuppetError, match="obj.npz: cannot read"):
        read_npz(obj, "kind file")
    single = tmp_path / "single.npy"
    np.save(single, np.zeros(3))
    with pytest.raises(FacepuppetError, match="single.npy: cannot read"):
        read_npz(single, "kind file")


def test_truncated_archive(tmp_path):
    good = tmp_path / "good.npz"
    np.savez_compressed(good, x=np.random.default_rng(0).normal(size=5000))
    cut = tmp_path / "cut.npz"
    cut.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    with pytest.raises(FacepuppetError, match="cut.npz"):
        read_npz(cut, "kind file")


def test_format_and_version_checks(tmp_path):
    path = tmp_path / "f.npz"
    with pytest.raises(FacepuppetError, match="not a facepuppet kind file"):
        check_format({"format": np.asarray("other"), "version": np.asarray(1)}, path, "kind file", "kind", 1)
    with pytest.raises(FacepuppetError, match="no valid version"):
        check_format({"format": np.asarray("kind")}, path, "kind file", "kind", 1)
    with pytest.raises(FacepuppetError, match="version 5 is newer"):
        check_format({"format": np.asarray("kind"), "version": np.asarray(5)}, path, "kind file", "kind", 1)


def test_a_member_of_fixed_size_is_refused_by_its_header(tmp_path):
    path = tmp_path / "big.npz"
    np.savez_compressed(path, fps=np.zeros(2_000_000), x=np.arange(3))
    with pytest.raises(FacepuppetError, match=r"big.npz: .*'fps' holds 2000000 values .* at most 1"):
        read_npz(path, "kind file", sizes={"fps": 1})
    assert read_npz(path, "kind file", sizes={"x": 3})["x"].tolist() == [0, 1, 2]


def test_a_track_whose_frame_rate_is_an_array_is_refused_before_inflating(tmp_path):
    from facepuppet.io.track import load_track

    path = tmp_path / "t.npz"
    np.savez_compressed(path, fps=np.zeros(2_000_000), frame_size=np.array([64, 64]))
    with pytest.raises(FacepuppetError, match="t.npz: cannot read track file .*'fps' holds 2000000 values"):
        load_track(path)
