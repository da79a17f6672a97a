"""Known answers of the live senders: VMC bundles (decoded by python-osc's parser) and Live Link Face packets
(decoded by a reader written here from the packet's layout), received on loopback sockets."""

from __future__ import annotations

import math
import socket
import struct
import sys
import warnings

import numpy as np
import pytest
from live_helpers import require

require("pythonosc", 'the live extra is not installed (pip install "facepuppet[live]")')

from pythonosc.osc_bundle import OscBundle  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402

from facepuppet.arkit import ARKIT_NAMES  # noqa: E402
from facepuppet.live import LiveFrame, LiveLinkConfig, LiveLinkSender, VmcSender, unity_quaternion  # noqa: E402
from facepuppet.live.livelink import fps_fraction  # noqa: E402


@pytest.fixture
def receiver():
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(5.0)
    yield sock
    sock.close()


def frame(names, weights, head=None, *, index=0, time=0.0):
    return LiveFrame(index=index, time=time, timestamp=0.0, weights=np.asarray(weights, float),
                     names=tuple(names), head_rotation=head)


def yaw(deg):
    """R_y: the face (looking along +z) turned toward +x, its own left, by ``deg`` degrees."""
    a = math.radians(deg)
    return np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])


# ------------------------------------------------------------------------------------------------- VMC
def test_unity_quaternion_known_answers():
    s15, c15 = math.sin(math.radians(15)), math.cos(math.radians(15))
    np.testing.assert_allclose(unity_quaternion(yaw(30)), [0, -s15, 0, c15], atol=1e-12)
    pitch = np.array([[1, 0, 0], [0, math.cos(0.4), -math.sin(0.4)], [0, math.sin(0.4), math.cos(0.4)]])
    np.testing.assert_allclose(unity_quaternion(pitch), [math.sin(0.2), 0, 0, math.cos(0.2)], atol=1e-12)
    roll = Rotation.from_euler("z", 0.3).as_matrix()
    np.testing.assert_allclose(unity_quaternion(roll), [0, 0, -math.sin(0.15), math.cos(0.15)], atol=1e-12)
    np.testing.assert_allclose(unity_quaternion(np.eye(3)), [0, 0, 0, 1])


def test_unity_quaternion_turns_the_avatar_to_its_own_left():
    # Unity's matrix of the quaternion (standard formula) applied to the avatar's forward (+z) gives -x,
    # the avatar's own left in Unity, for a face turned 90 degrees to its own left.
    x, y, z, w = unity_quaternion(yaw(90))
    forward = Rotation.from_quat([x, y, z, w]).apply([0, 0, 1])
    np.testing.assert_allclose(forward, [-1, 0, 0], atol=1e-12)


def test_vmc_bundle_received(receiver):
    names = ("eyeBlink_L", "jawOpen", "mouthSmile", "browInnerUp_L", "browInnerUp_R", "wink")
    sender = VmcSender(names, *receiver.getsockname())
    sender.send(frame(names, [0.25, 0.5, 0.75, 0.2, 0.4, 0.125], yaw(30), time=1.5))
    messages = list(OscBundle(receiver.recv(65536)))
    sender.close()
    addresses = [m.address for m in messages]
    assert addresses == ["/VMC/Ext/Blend/Val"] * 6 + ["/VMC/Ext/Blend/Apply", "/VMC/Ext/Bone/Pos",
                                                      "/VMC/Ext/OK", "/VMC/Ext/T"]
    blend = {m.params[0]: m.params[1] for m in messages[:6]}
    assert blend == pytest.approx({"EyeBlinkLeft": 0.25, "JawOpen": 0.5, "MouthSmileLeft": 0.75,
                                   "MouthSmileRight": 0.75, "BrowInnerUp": 0.3, "wink": 0.125}, abs=1e-7)
    bone = messages[7].params
    assert bone[0] == "Head"
    s15, c15 = math.sin(math.radians(15)), math.cos(math.radians(15))
    np.testing.assert_allclose(bone[1:], [0, 0, 0, 0, -s15, 0, c15], atol=1e-7)
    assert messages[8].params == [1]
    assert messages[9].params == [pytest.approx(1.5)]


def test_vmc_without_head_and_arkit_spelling(receiver):
    from facepuppet.live import VmcConfig

    sender = VmcSender(ARKIT_NAMES, *receiver.getsockname(), config=VmcConfig(names="arkit"))
    w = np.arange(52) / 100
    sender.send(frame(ARKIT_NAMES, w))
    messages = list(OscBundle(receiver.recv(65536)))
    sender.close()
    assert "/VMC/Ext/Bone/Pos" not in [m.address for m in messages]
    blend = {m.params[0]: m.params[1] for m in messages if m.address == "/VMC/Ext/Blend/Val"}
    assert blend == pytest.approx(dict(zip(ARKIT_NAMES, w.tolist(), strict=True)), abs=1e-7)


def test_senders_to_nobody_do_not_raise():
    # a port nobody listens on: ICMP errors come back, the senders count and go on
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()
    vmc, llf = VmcSender(ARKIT_NAMES, "127.0.0.1", port), LiveLinkSender(ARKIT_NAMES, "127.0.0.1", port)
    for i in range(20):
        f = frame(ARKIT_NAMES, np.zeros(52), index=i)
        vmc.send(f)
        llf.send(f)
    vmc.close()
    llf.close()
    vmc.send(frame(ARKIT_NAMES, np.zeros(52)))  # after close: ignored


def test_missing_extra_names_the_pip_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "pythonosc.osc_message_builder", None)
    with pytest.raises(ImportError, match=r'pip install "facepuppet\[live\]"'):
        VmcSender(ARKIT_NAMES)


# ------------------------------------------------------------------------------------------ Live Link Face
def decode_llf(data: bytes) -> dict:
    """Read a Live Link Face packet field by field, from the layout (version 6, big-endian)."""
    at = 0

    def take(fmt):
        nonlocal at
        values = struct.unpack_from(">" + fmt, data, at)
        at += struct.calcsize(">" + fmt)
        return values

    (version,) = take("B")
    (n,) = take("i")
    device = data[at: at + n].decode("utf-8")
    at += n
    (n,) = take("i")
    subject = data[at: at + n].decode("utf-8")
    at += n
    frame_number, subframe = take("i") + take("f")
    num, den = take("ii")
    (count,) = take("B")
    values = take(f"{count}f")
    assert at == len(data), "trailing bytes"
    return dict(version=version, device=device, subject=subject, frame=frame_number, subframe=subframe,
                fps=(num, den), count=count, values=np.array(values))


def test_livelink_packet_received(receiver):
    names = ("jawOpen", "eyeBlink_L", "eyeBlink_R", "browInnerUp_L", "browInnerUp_R", "tongueOut")
    config = LiveLinkConfig(subject="Performer1", device_id="rig-é", fps=30.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # every key-model is ARKit's: no warning
        sender = LiveLinkSender(names, *receiver.getsockname(), config=config)
    sender.send(frame(names, [0.7, 0.25, 0.5, 0.1, 0.3, 1.0], yaw(30), time=1.25))
    packet = decode_llf(receiver.recv(65536))
    sender.close()
    assert packet["version"] == 6
    assert packet["device"] == "rig-é" and packet["subject"] == "Performer1"
    assert packet["frame"] == 37 and packet["subframe"] == pytest.approx(0.5)
    assert packet["fps"] == (30, 1) and packet["count"] == 61
    expected = np.zeros(61)
    # Live Link Face's order: EyeBlinkLeft 0, EyeBlinkRight 7, JawOpen 17, BrowInnerUp 43, TongueOut 51,
    # HeadYaw 52 (30 degrees / 180 degrees)
    expected[[0, 7, 17, 43, 51, 52]] = [0.25, 0.5, 0.7, 0.2, 1.0, 30 / 180]
    np.testing.assert_allclose(packet["values"], expected, atol=1e-7)


def test_livelink_head_pitch_and_roll():
    names = ("jawOpen",)
    sender = LiveLinkSender(names, "127.0.0.1", 9)
    r = Rotation.from_euler("YXZ", [0.3, 0.2, -0.1]).as_matrix()  # R_y(yaw) R_x(pitch) R_z(roll)
    values = sender.values(frame(names, [0.0], r))
    sender.close()
    np.testing.assert_allclose(values[52:55], np.array([0.3, 0.2, -0.1]) / np.pi, atol=1e-12)
    np.testing.assert_allclose(values[55:], 0)


def test_livelink_rigs_without_arkit_names():
    with pytest.raises(ValueError, match="no key-model of the rig has an ARKit name"):
        LiveLinkSender(("smile", "frown"), "127.0.0.1", 9)
    with pytest.warns(UserWarning, match="left out: smile"):
        LiveLinkSender(("smile", "jawOpen"), "127.0.0.1", 9).close()


def test_fps_fraction():
    assert fps_fraction(30) == (30, 1)
    assert fps_fraction(29.97) == (30000, 1001)
    assert fps_fraction(59.94) == (60000, 1001)
    assert fps_fraction(12.5) == (25, 2)
