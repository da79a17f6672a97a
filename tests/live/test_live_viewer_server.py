"""The viewer server on loopback: its fixed assets, 404 for anything else, Origin and Host checks, and a
stream that goes on while 100 clients come and go and one client never reads."""

from __future__ import annotations

import asyncio
import base64
import http.client
import json
import os
import socket
import threading
import time

import numpy as np
import pytest
from live_helpers import grid_character, live_frame, require

require("websockets", 'the live extra is not installed (pip install "facepuppet[live]")')

from websockets.asyncio.client import connect  # noqa: E402
from websockets.exceptions import InvalidStatus  # noqa: E402

from facepuppet.live import ViewerConfig, ViewerServer  # noqa: E402
from facepuppet.live.mesh import mesh_asset  # noqa: E402


@pytest.fixture
def character():
    return grid_character()


@pytest.fixture
def server(character):
    s = ViewerServer(character, "127.0.0.1", 0)
    yield s
    s.close()


def get(port, path, host=None):
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
    try:
        conn.request("GET", path, headers={"Host": host or f"127.0.0.1:{port}"})
        r = conn.getresponse()
        return r.status, r.getheader("Content-Type"), r.read()
    finally:
        conn.close()


def origin(server):
    return f"http://127.0.0.1:{server.port}"


def test_assets_200(server, character):
    for path, kind in (("/", "text/html"), ("/index.html", "text/html"), ("/viewer.js", "text/javascript"),
                       ("/viewer.css", "text/css"), ("/rig.json", "application/json"),
                       ("/mesh.bin", "application/octet-stream"), ("/?x=1", "text/html")):
        status, content_type, body = get(server.port, path)
        assert status == 200 and content_type.startswith(kind), path
        assert body
    assert get(server.port, "/mesh.bin")[2] == mesh_asset(character)
    rig = json.loads(get(server.port, "/rig.json")[2])
    assert rig["names"] == list(character.names) and rig["vertices"] == len(character.neutral)
    page = get(server.port, "/")[2].decode()
    assert "/viewer.js" in page and "http" not in page.replace("http-equiv", "")  # nothing from elsewhere


@pytest.mark.parametrize("path", [
    "/../../../../etc/passwd", "/..%2f..%2fetc%2fpasswd", "/%2e%2e/%2e%2e/etc/passwd", "/static/index.html",
    "/viewer.py", "/index.html/../viewer.py", "//etc/passwd", "/viewer.js/", "/ws/../index.html", "/.",
    "/static/../__init__.py", "/mesh.bin.bak", "/INDEX.HTML"])
def test_anything_else_404(server, path):
    assert get(server.port, path)[0] == 404


def test_unknown_host_refused(server):
    # a page of another site that resolves its name to 127.0.0.1 (DNS rebinding) sends its own Host
    assert get(server.port, "/", host=f"evil.example:{server.port}")[0] == 403
    assert get(server.port, "/", host="127.0.0.1:1")[0] == 403
    assert get(server.port, "/", host=f"localhost:{server.port}")[0] == 200


def test_websocket_origin_checked(server):
    async def attempt(origin_header):
        try:
            async with connect(f"ws://127.0.0.1:{server.port}/ws", origin=origin_header, open_timeout=5):
                return 101
        except InvalidStatus as e:
            return e.response.status_code

    async def main():
        return [await attempt(origin(server)), await attempt("http://evil.example"),
                await attempt(None), await attempt(f"http://127.0.0.1:{server.port + 1}"),
                await attempt(f"https://127.0.0.1:{server.port}")]

    assert asyncio.run(main()) == [101, 403, 403, 403, 403]


def test_neutral_button_message(character):
    pressed = []
    server = ViewerServer(character, "127.0.0.1", 0, on_neutral=lambda: pressed.append(1))

    async def main():
        async with connect(f"ws://127.0.0.1:{server.port}/ws", origin=origin(server)) as ws:
            await ws.send("not json")
            await ws.send(json.dumps({"type": "neutral"}))
            await asyncio.sleep(0.2)

    try:
        asyncio.run(main())
        assert pressed == [1]
        assert server.neutral_requested() is True
        assert server.neutral_requested() is False
    finally:
        server.close()


def test_port_in_use_is_one_line(character):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        with pytest.raises(ValueError, match=f"--viewer: cannot listen on 127.0.0.1:{port}"):
            ViewerServer(character, "127.0.0.1", port)


def test_weights_reordered_to_the_character(character, server):
    s = ViewerServer(character, "127.0.0.1", 0, names=("eyeBlink_L", "jawOpen", "other"))

    async def main():
        async with connect(f"ws://127.0.0.1:{s.port}/ws", origin=f"http://127.0.0.1:{s.port}") as ws:
            await asyncio.sleep(0.1)
            s.send(live_frame(("eyeBlink_L", "jawOpen", "other"), [0.1, 0.2, 0.3], index=4))
            return json.loads(await asyncio.wait_for(ws.recv(), 5))

    try:
        message = asyncio.run(main())
    finally:
        s.close()
    assert message["i"] == 4 and message["w"] == [0.2, 0.0, 0.1]  # jawOpen, mouthSmile_L (absent), eyeBlink_L


def handshake(port: int, *, host: str | None = None, origin_header: str | None = None,
              rcvbuf: int | None = None) -> tuple[int, socket.socket]:
    """A WebSocket opening handshake by hand: the HTTP status, and the socket (not read any further)."""
    sock = socket.socket()
    if rcvbuf:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
    sock.settimeout(10)
    sock.connect(("127.0.0.1", port))
    key = base64.b64encode(os.urandom(16)).decode()
    origin_line = f"Origin: {origin_header}\r\n" if origin_header else ""
    sock.sendall((f"GET /ws HTTP/1.1\r\nHost: {host or f'127.0.0.1:{port}'}\r\nUpgrade: websocket\r\n"
                  f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n"
                  f"{origin_line}\r\n").encode())
    reply = b""
    while b"\r\n\r\n" not in reply:
        chunk = sock.recv(1)
        if not chunk:
            break
        reply += chunk
    return int(reply.split(b" ", 2)[1]), sock


def test_dns_rebinding_refused(server):
    status, sock = handshake(server.port, host=f"evil.example:{server.port}",
                             origin_header=f"http://evil.example:{server.port}")
    sock.close()
    assert status == 403


def stalled_client(port: int) -> socket.socket:
    """A WebSocket client that completes the handshake and then never reads."""
    status, sock = handshake(port, origin_header=f"http://127.0.0.1:{port}", rcvbuf=4096)
    assert status == 101
    return sock


def test_stream_survives_churn_and_a_client_that_never_reads(character):
    server = ViewerServer(character, "127.0.0.1", 0, config=ViewerConfig(max_clients=32, write_limit=2**14))
    threads_before = threading.active_count()
    names = character.names
    image = np.random.default_rng(0).integers(0, 255, (480, 640, 3), dtype=np.uint8)  # ~200 kB of JPEG noise
    stalled = stalled_client(server.port)
    stop, churn_done = threading.Event(), threading.Event()
    sent, received, churn_ok = [], [], []

    async def reader():
        async with connect(f"ws://127.0.0.1:{server.port}/ws", origin=origin(server), max_size=2**22) as ws:
            while not stop.is_set():
                try:
                    message = await asyncio.wait_for(ws.recv(), 0.5)
                except asyncio.TimeoutError:
                    continue
                if isinstance(message, str):
                    received.append(json.loads(message)["i"])

    async def one_visitor(k):
        async with connect(f"ws://127.0.0.1:{server.port}/ws", origin=origin(server), max_size=2**22) as ws:
            message = await asyncio.wait_for(ws.recv(), 10)
            while not isinstance(message, str):  # a picture whose frame came before this client did
                message = await asyncio.wait_for(ws.recv(), 10)
            churn_ok.append(json.loads(message)["type"] == "frame")
            if k % 2:
                ws.transport.abort()  # gone without a closing handshake

    async def clients():
        read = asyncio.create_task(reader())
        await asyncio.sleep(0.2)
        for wave in range(10):
            await asyncio.gather(*(one_visitor(10 * wave + k) for k in range(10)))
        churn_done.set()
        while not stop.is_set():
            await asyncio.sleep(0.05)
        await read

    def produce():
        i = 0
        deadline = time.monotonic() + 60
        while not churn_done.is_set() and time.monotonic() < deadline:
            server.send(live_frame(names, np.full(len(names), (i % 100) / 100), index=i, image=image))
            sent.append(i)
            i += 1
            time.sleep(0.004)

    client_thread = threading.Thread(target=lambda: asyncio.run(clients()))
    client_thread.start()
    producer = threading.Thread(target=produce)
    producer.start()
    producer.join(90)
    assert not producer.is_alive(), "send() blocked"
    try:
        assert churn_done.is_set() and len(churn_ok) == 100 and all(churn_ok)
        # newest wins: the reader ends on the last frame sent, in order, never the same frame twice
        deadline = time.monotonic() + 10
        while (not received or received[-1] != sent[-1]) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert received and received[-1] == sent[-1]
        assert all(b > a for a, b in zip(received, received[1:], strict=False))
        deadline = time.monotonic() + 20  # the server notices the last visitors leave
        while server.clients > 2 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert server.clients == 2  # the reader and the stalled client; the 100 visitors are gone
    finally:
        stop.set()
        client_thread.join(30)
        stalled.close()
    deadline = time.monotonic() + 10
    while server.clients and time.monotonic() < deadline:
        time.sleep(0.05)
    assert server.clients == 0
    server.close()
    assert threading.active_count() <= threads_before
    server.send(live_frame(names, np.zeros(len(names))))  # after close: ignored
