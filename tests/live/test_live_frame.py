"""LiveFrame's checks, HOST:PORT parsing, the loopback rule, the Sender protocol and the mesh asset layout."""

from __future__ import annotations

import logging
import struct

import numpy as np
import pytest
from live_helpers import grid_character

from facepuppet.live import LiveFrame, LiveLinkSender, Sender, is_loopback, parse_address, warn_if_exposed
from facepuppet.live.mesh import mesh_asset


def test_live_frame_checks_shapes():
    ok = LiveFrame(index=0, time=0.0, timestamp=0.0, weights=np.zeros(2), names=("a", "b"))
    assert ok.valid and ok.head_rotation is None
    with pytest.raises(ValueError, match=r"weights must have shape \(2,\)"):
        LiveFrame(index=0, time=0.0, timestamp=0.0, weights=np.zeros(3), names=("a", "b"))
    with pytest.raises(ValueError, match="head_rotation"):
        LiveFrame(index=0, time=0.0, timestamp=0.0, weights=np.zeros(1), names=("a",), head_rotation=np.eye(4))
    with pytest.raises(ValueError, match="curves"):
        LiveFrame(index=0, time=0.0, timestamp=0.0, weights=np.zeros(1), names=("a",), curves=np.zeros((2, 3, 2)))
    with pytest.raises(ValueError, match="image"):
        LiveFrame(index=0, time=0.0, timestamp=0.0, weights=np.zeros(1), names=("a",), image=np.zeros((4, 4)))


@pytest.mark.parametrize("text, expected", [
    ("8765", ("127.0.0.1", 8765)), ("0.0.0.0:80", ("0.0.0.0", 80)), ("localhost:39539", ("localhost", 39539)),
    ("[::1]:11111", ("::1", 11111)), ("studio-pc:1", ("studio-pc", 1)), (" 65535 ", ("127.0.0.1", 65535))])
def test_parse_address(text, expected):
    assert parse_address(text, what="--vmc") == expected


@pytest.mark.parametrize("text", ["", "abc", "0", "65536", "host:", ":80", "1.2.3.4:80:90", "::1:80", "h:-1"])
def test_parse_address_refuses(text):
    with pytest.raises(ValueError, match=r"^--viewer: expected \[HOST:\]PORT"):
        parse_address(text, what="--viewer")


def test_loopback_and_the_warning(caplog):
    assert is_loopback("127.0.0.1") and is_loopback("127.8.0.1") and is_loopback("::1")
    assert is_loopback("localhost") and not is_loopback("0.0.0.0") and not is_loopback("192.168.1.5")
    assert not is_loopback("studio-pc")
    with caplog.at_level(logging.WARNING, logger="facepuppet.live"):
        warn_if_exposed("127.0.0.1", "--viewer")
        assert not caplog.records
        warn_if_exposed("0.0.0.0", "--viewer")
    assert len(caplog.records) == 1 and "reachable from other machines" in caplog.records[0].getMessage()


def test_senders_are_senders():
    sender = LiveLinkSender(("jawOpen",), "127.0.0.1", 9)
    assert isinstance(sender, Sender)
    sender.close()


def test_mesh_asset_layout():
    character = grid_character(n=4)
    colors = np.linspace(0, 1, 16 * 3).reshape(16, 3)
    data = mesh_asset(character, colors=colors)
    assert data[:4] == b"FPM1"
    v, m, t, flags = struct.unpack_from("<4I", data, 4)
    assert (v, m, t, flags) == (16, 3, 18, 1)
    at = 20
    neutral = np.frombuffer(data, "<f4", v * 3, at).reshape(v, 3)
    at += v * 12
    deltas = np.frombuffer(data, "<f4", m * v * 3, at).reshape(m, v, 3)
    at += m * v * 12
    faces = np.frombuffer(data, "<u4", t * 3, at).reshape(t, 3)
    at += t * 12
    rgba = np.frombuffer(data, np.uint8, v * 4, at).reshape(v, 4)
    assert at + v * 4 == len(data)
    np.testing.assert_allclose(neutral, character.neutral, rtol=1e-7)
    np.testing.assert_allclose(deltas, character.targets - character.neutral, atol=1e-7)
    np.testing.assert_array_equal(faces, character.faces)
    np.testing.assert_array_equal(rgba[:, :3], np.round(colors * 255))
    assert (rgba[:, 3] == 255).all()
    with pytest.raises(ValueError, match="colors must have shape"):
        mesh_asset(character, colors=np.zeros((3, 3)))
