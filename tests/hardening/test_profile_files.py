"""Let in what should stay out, the colour tracker's profile: only its own members read, each checked first."""

from __future__ import annotations

import io
import zipfile

import numpy as np
import pytest

from hardening.hardening_cases import run_refused
from hardening.test_let_in import _lying_header, _npy, _npz


@pytest.fixture
def members(tmp_path):
    from facepuppet.capture.color.profile import default_profile, save_profile

    save_profile(tmp_path / "good.npz", default_profile())
    with zipfile.ZipFile(tmp_path / "good.npz") as zf:
        out = {n[:-4]: zf.read(n) for n in zf.namelist()}
    (tmp_path / "good.npz").unlink()
    return out


def _zeros_member(nbytes: int) -> bytes:
    """A real .npy of ``nbytes`` zero bytes (float64): it deflates to about a thousandth of that."""
    buf = io.BytesIO()
    np.save(buf, np.zeros(nbytes // 8))
    return buf.getvalue()


def _track_with(world, tmp_path, profile):
    return ["track", world.video, "--profile", profile, "-o", tmp_path / "t.npz", "--no-progress"]


@pytest.mark.parametrize("case", ["huge_layout", "lying_header", "wrong_dtype", "missing", "pickle", "text_weights",
                                  "nan_anchors", "net_misshapen", "name_not_text"])
def test_damaged_profile_is_refused_naming_it(capsys, world, tmp_path, members, case):
    if case == "huge_layout":            # 200 MB of zeros in a known member, about 200 kB on disk
        members["layout"] = _zeros_member(200 << 20)
    elif case == "lying_header":
        members["weights"] = _lying_header((10**12,), "<f8")
    elif case == "wrong_dtype":
        members["layout"] = _npy(np.zeros((8, 4, 2), dtype=np.complex128))
    elif case == "missing":
        del members["skin_cov"]
    elif case == "pickle":
        members["anchors"] = _npy(np.array([{"x": 1}], dtype=object))
    elif case == "text_weights":
        members["weights"] = _npy(np.array(["a", "b", "c", "d"]))
    elif case == "nan_anchors":
        members["anchors"] = _npy(np.full((3, 2), np.nan))
    elif case == "net_misshapen":
        members["net_w0"] = _npy(np.zeros((3, 3)))
    elif case == "name_not_text":
        members["name"] = _npy(np.arange(3))
    bad = tmp_path / "prof.npz"
    _npz(bad, members)
    run_refused(capsys, _track_with(world, tmp_path, bad), world, folders=[tmp_path], names=["prof.npz"])


def test_unknown_profile_member_is_never_inflated(world, tmp_path, members):
    import tracemalloc

    from facepuppet.capture.color.profile import load_profile

    members["payload"] = _zeros_member(256 << 20)
    path = tmp_path / "p.npz"
    _npz(path, members)
    tracemalloc.start()
    profile = load_profile(path)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert profile.name == "generic"
    assert peak < 50 * 2**20


def test_profile_that_is_a_fifo(capsys, world, tmp_path):
    import os

    os.mkfifo(tmp_path / "prof.npz")
    run_refused(capsys, _track_with(world, tmp_path, tmp_path / "prof.npz"), world, folders=[tmp_path],
                names=["prof.npz"])
