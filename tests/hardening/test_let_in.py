"""Let in what should stay out: .gltf URIs leaving their folder, npz members inflated unchecked."""

import io
import json
import struct
import zipfile

import numpy as np
import pytest

from hardening.hardening_cases import animate_args, run_refused


def _gltf_with_uri(folder, uri: str, byte_length: int = 16):
    """A .gltf whose one buffer is ``uri`` (the toy's own data need not be valid: the URI is refused first)."""
    from facepuppet.demo.toy import toy_character
    from facepuppet.io.gltf import write_glb

    path = folder / "c.gltf"
    write_glb(path, toy_character())
    doc = json.loads(path.read_text())
    doc["buffers"][0]["uri"] = uri
    if byte_length is not None:
        doc["buffers"][0]["byteLength"] = max(byte_length, doc["buffers"][0]["byteLength"])
    path.write_text(json.dumps(doc))
    return path


@pytest.mark.parametrize("uri", ["/etc/passwd", "../secret.bin", "/dev/zero", "sub/../../secret.bin",
                                 "file:///etc/passwd", "%2e%2e/secret.bin", "/proc/self/environ"])
def test_gltf_buffer_uri_outside_its_folder(capsys, world, tmp_path, uri):
    inner = tmp_path / "inner"
    inner.mkdir()
    (tmp_path / "secret.bin").write_bytes(b"\x00" * 4096)
    path = _gltf_with_uri(inner, uri)
    line = run_refused(capsys, ["rig", "--performer", world.performer, "--character", path, "-o",
                                tmp_path / "r.npz"], world, folders=[tmp_path], names=["c.gltf"])
    assert "URI" in line or "buffer" in line


def test_gltf_buffer_that_is_a_fifo(capsys, world, tmp_path):
    import os

    os.mkfifo(tmp_path / "pipe.bin")
    path = _gltf_with_uri(tmp_path, "pipe.bin")
    run_refused(capsys, ["rig", "--performer", world.performer, "--character", path, "-o", tmp_path / "r.npz"],
                world, folders=[tmp_path], names=["c.gltf", "not a regular file"])


def test_gltf_buffer_read_only_to_its_byte_length(tmp_path):
    from facepuppet.io.external import read_external

    (tmp_path / "b.bin").write_bytes(bytes(range(200)))
    assert read_external(tmp_path / "c.gltf", "b.bin", 10, "buffer 0") == bytes(range(10))


def _npz(path, members: dict[str, bytes]):
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in members.items():
            zf.writestr(name + ".npy", data)


def _npy(arr) -> bytes:
    buf = io.BytesIO()
    np.save(buf, arr, allow_pickle=True)
    return buf.getvalue()


def _lying_header(shape, dtype="<f4") -> bytes:
    """A .npy header claiming ``shape`` followed by no data."""
    header = repr({"descr": dtype, "fortran_order": False, "shape": shape}).encode()
    header += b" " * ((64 - (10 + len(header) + 1) % 64) % 64) + b"\n"
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) + header


def _track_members(world):
    with zipfile.ZipFile(world.track) as zf:
        return {n[:-4]: zf.read(n) for n in zf.namelist()}


def test_track_member_claiming_1e12_values(capsys, world, tmp_path):
    members = _track_members(world)
    members["curves"] = _lying_header((10**12,))
    bad = tmp_path / "bad.npz"
    _npz(bad, members)
    line = run_refused(capsys, animate_args(world, track=bad) + ["-o", tmp_path / "a.glb"], world,
                       folders=[tmp_path], names=["bad.npz"])
    assert "claims" in line


def test_track_member_with_objects(capsys, world, tmp_path):
    members = _track_members(world)
    members["valid"] = _npy(np.array([{"a": 1}], dtype=object))
    bad = tmp_path / "obj.npz"
    _npz(bad, members)
    run_refused(capsys, animate_args(world, track=bad) + ["-o", tmp_path / "a.glb"], world, folders=[tmp_path],
                names=["obj.npz", "objects"])


def test_unknown_member_is_never_inflated(world, tmp_path):
    """A member the format does not know is skipped unread: a 256 MiB one costs nothing."""
    import tracemalloc

    from facepuppet.io.track import load_track

    members = _track_members(world)
    path = tmp_path / "big.npz"
    _npz(path, members)
    with zipfile.ZipFile(path, "a", zipfile.ZIP_DEFLATED) as zf, zf.open("payload.npy", "w", force_zip64=True) as f:
        f.write(_lying_header((1 << 26,)))
        zero = bytes(1 << 24)
        for _ in range(16):      # 256 MiB of zeros, about 256 kB on disk
            f.write(zero)
    tracemalloc.start()
    track = load_track(path)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert "payload" not in (track.extras or {})
    assert peak < 50 * 2**20


def test_rig_member_claiming_more_than_the_archive_holds(capsys, world, tmp_path):
    with zipfile.ZipFile(world.rig) as zf:
        members = {n[:-4]: zf.read(n) for n in zf.namelist()}
    members["character.neutral"] = _lying_header((10**6, 3), "<f8")
    bad = tmp_path / "rig.npz"
    _npz(bad, members)
    run_refused(capsys, animate_args(world, rig=bad) + ["-o", tmp_path / "a.glb"], world, folders=[tmp_path],
                names=["rig.npz"])
