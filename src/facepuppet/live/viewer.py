"""The browser viewer: one port serving the page, its assets and a WebSocket streaming the frames.

:class:`ViewerServer` runs websockets' asyncio server in a thread of its own with its own event loop. The
page (``static/index.html``, ``viewer.js``, ``viewer.css``) draws the character with a small WebGL2 renderer
of morph targets, the camera picture with the tracked curves, fps, latency, a bar per key-model, and a
"neutral" button.

**HTTP.** ``GET`` of exactly one of :data:`ASSET_PATHS` answers 200 (the query string is ignored); any other
path is 404. No path is ever built from a request: assets are bytes read once, at start, from the package's
fixed file names, and the character's ``/mesh.bin`` (:mod:`facepuppet.live.mesh`) and ``/rig.json``.

**WebSocket** (``/ws``). Accepted when the ``Origin`` is the page's own (``http://`` + the request's
``Host``) and that ``Host`` is the server's (``127.0.0.1``, ``localhost``, ``[::1]`` or the bound host, with
its port; a wildcard bind accepts any host name) -- others get 403, which also stops DNS rebinding. At most
:attr:`ViewerConfig.max_clients` clients (503 beyond). Messages, server to page:

- text, per frame: ``{"type": "frame", "i": index, "t": time s, "w": [weights in rig.json's order],
  "h": [9 floats, the head rotation row by row] or null, "v": valid, "lat": ms from capture to this message,
  "c": [[[x, y] x 4] x C] curves or null, "size": [W, H] of the camera picture or null}``;
- binary, the camera picture of a frame: uint32 little-endian frame index, then the picture as JPEG. It is
  encoded in a worker thread after the frame's text went out (one at a time, the newest picture winning), so
  the weights never wait for a JPEG.

Page to server (text): ``{"type": "neutral"}`` (the button; :meth:`ViewerServer.neutral_requested` reports it
once), ``{"type": "picture", "on": bool}`` (this client wants the camera picture or not).

**Reliability.** ``send`` only puts the frame in a one-slot mailbox (the newest frame wins) and wakes the
server's loop; it never waits for the network. Each client has a one-slot queue of its own, also newest-wins,
so a client that stops reading holds at most one pending frame and websockets' write buffer
(:attr:`ViewerConfig.write_limit`), never slowing the stream or the other clients; it is closed when it does not
answer pings.
"""

from __future__ import annotations

import asyncio
import json
import logging
import threading
import time
from dataclasses import dataclass
from importlib import resources
from urllib.parse import urlsplit

import numpy as np

from facepuppet.live._optional import import_extra
from facepuppet.live.frame import DEFAULT_HOST, LiveFrame, warn_if_exposed
from facepuppet.live.mesh import mesh_asset, rig_description

__all__ = ["ViewerConfig", "ViewerServer", "ASSET_PATHS", "DEFAULT_VIEWER_PORT"]

log = logging.getLogger(__name__)

#: The viewer's default port.
DEFAULT_VIEWER_PORT = 8765
#: Request path -> (packaged file name or generated asset, content type).
ASSET_PATHS: dict[str, tuple[str, str]] = {
    "/": ("index.html", "text/html; charset=utf-8"),
    "/index.html": ("index.html", "text/html; charset=utf-8"),
    "/viewer.js": ("viewer.js", "text/javascript; charset=utf-8"),
    "/viewer.css": ("viewer.css", "text/css; charset=utf-8"),
    "/rig.json": ("<rig.json>", "application/json"),
    "/mesh.bin": ("<mesh.bin>", "application/octet-stream"),
}
_WS_PATH = "/ws"
_LOOPBACK_NAMES = ("127.0.0.1", "localhost", "[::1]")
_WILDCARD = ("0.0.0.0", "::", "")


@dataclass(frozen=True, kw_only=True)
class ViewerConfig:
    """Options of the viewer server.

    Attributes
    ----------
    max_clients : int
        WebSocket clients at once; more are refused (503).
    picture_width : int
        The camera picture is scaled down to at most this width (pixels) before JPEG encoding.
    jpeg_quality : int
        JPEG quality of the camera picture, 1..100.
    write_limit : int
        Bytes websockets buffers per client before a send waits (on that client only).
    ping_interval, ping_timeout : float
        Seconds between pings, and to wait for a pong before closing a client.
    start_timeout : float
        Seconds to wait for the server to start listening.
    """

    max_clients: int = 32
    picture_width: int = 640
    jpeg_quality: int = 80
    write_limit: int = 2**16
    ping_interval: float = 10.0
    ping_timeout: float = 10.0
    start_timeout: float = 10.0

    def __post_init__(self) -> None:
        if self.max_clients < 1:
            raise ValueError(f"max_clients must be at least 1, got {self.max_clients}")
        if not 1 <= self.jpeg_quality <= 100:
            raise ValueError(f"jpeg_quality must be in 1..100, got {self.jpeg_quality}")


class _Client:
    """One WebSocket client: a one-slot mailbox (newest wins) and an event that wakes its writer."""

    def __init__(self, ws) -> None:
        self.ws = ws
        self.slot: str | None = None
        self.picture_slot: bytes | None = None
        self.wake = asyncio.Event()
        self.closed = False
        self.picture = True


class ViewerServer:
    """Serves the viewer page and streams frames to every browser that opens it.

    Parameters
    ----------
    character : facepuppet.io.character.Character
        The rig's character (neutral, key-models, faces).
    host : str
        Address to bind; 127.0.0.1 unless given (a warning is logged for others).
    port : int
        TCP port; 0 picks a free one (see :attr:`port`).
    names : sequence of str, optional
        Key-model names of the frames' weights when they differ from the character's order (weights are
        sent in the character's order; names it lacks are dropped, its names no frame has are 0).
    colors : (V, 3) or (V, 4), optional
        Vertex colours of the character (:func:`facepuppet.live.mesh.mesh_asset`).
    config : ViewerConfig, optional
    on_neutral : callable, optional
        Called with no argument, in the server's thread, when a page presses "neutral".

    Attributes
    ----------
    port : int
        The port it listens on.
    url : str
        The page's address.
    clients : int
        WebSocket clients connected now.
    frames_in, frames_out : int
        Frames given to :meth:`send`, and frames sent on to the clients (the difference were replaced by a
        newer frame before the server's thread got to them).

    Raises
    ------
    ValueError
        When the port cannot be bound (in use, not permitted) -- one line naming it.
    """

    def __init__(self, character, host: str = DEFAULT_HOST, port: int = DEFAULT_VIEWER_PORT, *, names=None,
                 colors=None, config: ViewerConfig | None = None, on_neutral=None) -> None:
        self._ws_server = import_extra("websockets.asyncio.server", "the browser viewer (--viewer)")
        self._http = import_extra("websockets.http11", "the browser viewer (--viewer)")
        self._datastructures = import_extra("websockets.datastructures", "the browser viewer (--viewer)")
        self._exceptions = import_extra("websockets.exceptions", "the browser viewer (--viewer)")
        self.config = config or ViewerConfig()
        self.host = host
        self._on_neutral = on_neutral
        self._neutral = threading.Event()
        self._order = self._weight_order(character.names, names)
        package = resources.files("facepuppet.live") / "static"
        generated = {"<rig.json>": rig_description(character), "<mesh.bin>": mesh_asset(character, colors=colors)}
        self._assets = {path: (generated[f] if f in generated else (package / f).read_bytes(), kind)
                        for path, (f, kind) in ASSET_PATHS.items()}
        self._lock = threading.Lock()
        self._latest: LiveFrame | None = None
        self._wake_pending = False
        self._closed = False
        self._clients: set[_Client] = set()
        self._picture_next: tuple[np.ndarray, int] | None = None
        self._picture_task: asyncio.Task | None = None
        self.frames_in = 0
        self.frames_out = 0
        self._loop = asyncio.new_event_loop()
        self._server = None
        self._started = threading.Event()
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, args=(port,), name="facepuppet-viewer", daemon=True)
        self._thread.start()
        if not self._started.wait(self.config.start_timeout):
            raise ValueError(f"--viewer: the server on {host}:{port} did not start")
        if self._error is not None:
            self._thread.join(5.0)
            raise ValueError(f"--viewer: cannot listen on {host}:{port} ({self._error})") from self._error
        self.port = self._server.sockets[0].getsockname()[1]
        warn_if_exposed(host, f"--viewer (http://{host}:{self.port}/)")
        log.info("viewer at %s", self.url)

    @staticmethod
    def _weight_order(targets, names) -> np.ndarray | None:
        if names is None or tuple(names) == tuple(targets):
            return None
        index = {str(n): i for i, n in enumerate(names)}
        return np.array([index.get(str(t), -1) for t in targets])

    @property
    def url(self) -> str:
        """The page's address."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{'127.0.0.1' if self.host in _WILDCARD else host}:{self.port}/"

    @property
    def clients(self) -> int:
        """WebSocket clients connected now."""
        return len(self._clients)

    # -- the loop's side -----------------------------------------------------------------------------------------
    def send(self, frame: LiveFrame) -> None:
        """Hand the newest frame to the server; returns at once (an older frame not yet sent is replaced)."""
        with self._lock:
            if self._closed:
                return
            self._latest = frame
            self.frames_in += 1
            wake = not self._wake_pending
            self._wake_pending = True
        if wake:
            try:
                self._loop.call_soon_threadsafe(self._broadcast)
            except RuntimeError:  # the server's loop has ended (closed, or its thread failed)
                pass

    def neutral_requested(self) -> bool:
        """True once for each press of a page's "neutral" button since the last call."""
        if self._neutral.is_set():
            self._neutral.clear()
            return True
        return False

    def close(self) -> None:
        """Close every client and the server, and end its thread (idempotent)."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        if self._thread.is_alive():
            try:
                self._loop.call_soon_threadsafe(self._shutdown)
            except RuntimeError:
                return
            if threading.current_thread() is not self._thread:  # close() from a callback: do not wait on itself
                self._thread.join(10.0)

    # -- the server's thread --------------------------------------------------------------------------------------
    def _run(self, port: int) -> None:
        asyncio.set_event_loop(self._loop)

        async def start():
            return await self._ws_server.serve(
                self._handler, self.host, port, process_request=self._process_request, max_size=4096,
                max_queue=4, write_limit=self.config.write_limit, compression=None,
                ping_interval=self.config.ping_interval, ping_timeout=self.config.ping_timeout,
                close_timeout=2.0, server_header=None, logger=log.getChild("ws"))

        try:
            self._server = self._loop.run_until_complete(start())
        except Exception as e:  # OSError (port in use, not permitted), a bad host name, ...
            self._error = e
            self._loop.close()
            self._started.set()
            return
        self._started.set()
        try:
            self._loop.run_forever()
        finally:
            self._loop.run_until_complete(self._loop.shutdown_asyncgens())
            self._loop.run_until_complete(self._loop.shutdown_default_executor())
            self._loop.close()

    def _shutdown(self) -> None:
        async def stop() -> None:
            self._server.close(close_connections=True)
            try:
                await asyncio.wait_for(self._server.wait_closed(), 5.0)
            except asyncio.TimeoutError:
                log.warning("viewer: clients did not close in time")
            tasks = [t for t in asyncio.all_tasks() if t is not asyncio.current_task()]
            for t in tasks:
                t.cancel()
            await asyncio.gather(*tasks, return_exceptions=True)
            self._loop.stop()

        self._loop.create_task(stop())

    def _allowed_host(self, host: str) -> bool:
        names = _LOOPBACK_NAMES + (() if self.host in _WILDCARD else
                                   (f"[{self.host}]" if ":" in self.host else self.host,))
        if self.host in _WILDCARD:
            return bool(host) and host.endswith(f":{self.port}")
        return host in {f"{n}:{self.port}" for n in names}

    def _response(self, status: int, reason: str, body: bytes, kind: str):
        headers = self._datastructures.Headers([
            ("Content-Type", kind), ("Content-Length", str(len(body))), ("Cache-Control", "no-store"),
            ("X-Content-Type-Options", "nosniff"), ("Connection", "close"),
            ("Content-Security-Policy", "default-src 'self'; img-src 'self' blob:; connect-src 'self'; "
                                        "frame-ancestors 'none'")])
        return self._http.Response(status, reason, headers, body)

    def _process_request(self, connection, request):
        path = urlsplit(request.path).path
        hosts, origins = request.headers.get_all("Host"), request.headers.get_all("Origin")
        host = hosts[0] if len(hosts) == 1 else ""
        if not self._allowed_host(host):
            return self._response(403, "Forbidden", b"unknown host\n", "text/plain")
        if path == _WS_PATH:
            if len(origins) != 1 or origins[0] != f"http://{host}":
                return self._response(403, "Forbidden", b"origin not allowed\n", "text/plain")
            if len(self._clients) >= self.config.max_clients:
                return self._response(503, "Service Unavailable", b"too many viewers\n", "text/plain")
            return None
        asset = self._assets.get(path)
        if asset is None:
            return self._response(404, "Not Found", b"not found\n", "text/plain")
        return self._response(200, "OK", *asset)

    def _encode(self, frame: LiveFrame) -> str:
        w = np.asarray(frame.weights, dtype=np.float64)
        if self._order is not None:
            w = np.where(self._order >= 0, w[np.maximum(self._order, 0)], 0.0)
        w = np.where(np.isfinite(w), w, 0.0)
        head = None
        if frame.head_rotation is not None and np.all(np.isfinite(frame.head_rotation)):
            head = np.asarray(frame.head_rotation, dtype=np.float64).ravel().tolist()
        size = None if frame.image is None else [int(frame.image.shape[1]), int(frame.image.shape[0])]
        curves = None if frame.curves is None else np.round(np.asarray(frame.curves, float), 2).tolist()
        message = {"type": "frame", "i": int(frame.index), "t": float(frame.time), "w": w.tolist(), "h": head,
                   "v": bool(frame.valid), "lat": round((time.perf_counter() - frame.timestamp) * 1e3, 3),
                   "c": curves, "size": size}
        return json.dumps(message, separators=(",", ":"))

    def _jpeg(self, image: np.ndarray, index: int) -> bytes | None:
        """uint32 frame index + JPEG of the picture (in a worker thread: OpenCV releases the GIL)."""
        import cv2

        img = np.ascontiguousarray(image[..., ::-1])  # RGB -> BGR
        if img.shape[1] > self.config.picture_width:
            scale = self.config.picture_width / img.shape[1]
            img = cv2.resize(img, (self.config.picture_width, max(1, round(img.shape[0] * scale))),
                             interpolation=cv2.INTER_AREA)
        ok, data = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, self.config.jpeg_quality])
        return np.uint32(index).astype("<u4").tobytes() + data.tobytes() if ok else None

    def _broadcast(self) -> None:
        """Give every client the newest frame's message at once; its picture follows when encoded."""
        with self._lock:
            frame, self._latest = self._latest, None
            self._wake_pending = False
        if frame is None or not self._clients:
            return
        try:
            text = self._encode(frame)
        except Exception:  # a malformed frame must not stop the viewer
            log.exception("viewer: frame %s could not be encoded", frame.index)
            return
        for client in self._clients:
            client.slot = text
            client.wake.set()
        self.frames_out += 1
        if frame.image is not None and any(c.picture for c in self._clients):
            self._picture_next = (frame.image, frame.index)  # newest wins while one is being encoded
            if self._picture_task is None:
                self._picture_task = self._loop.create_task(self._pictures())

    async def _pictures(self) -> None:
        """Encode the newest picture in a worker thread, one at a time, and hand it to the clients."""
        try:
            while self._picture_next is not None:
                (image, index), self._picture_next = self._picture_next, None
                data = await self._loop.run_in_executor(None, self._jpeg, image, index)
                for client in self._clients:
                    if data is not None and client.picture:
                        client.picture_slot = data
                        client.wake.set()
        except Exception:
            log.exception("viewer: the camera picture could not be encoded")
        finally:
            self._picture_task = None

    async def _handler(self, ws) -> None:
        client = _Client(ws)
        self._clients.add(client)
        reader = asyncio.get_running_loop().create_task(self._read(client))
        closed = self._exceptions.ConnectionClosed
        try:
            while not client.closed:
                await client.wake.wait()
                client.wake.clear()
                text, client.slot = client.slot, None
                picture, client.picture_slot = client.picture_slot, None
                if text is not None:
                    await ws.send(text)
                if picture is not None:
                    await ws.send(picture)
        except closed:
            pass
        finally:
            self._clients.discard(client)
            reader.cancel()
            await asyncio.gather(reader, return_exceptions=True)

    async def _read(self, client: _Client) -> None:
        try:
            async for message in client.ws:
                if isinstance(message, str):
                    self._on_message(client, message)
        except self._exceptions.ConnectionClosed:
            pass
        finally:
            client.closed = True
            client.wake.set()

    def _on_message(self, client: _Client, text: str) -> None:
        try:
            message = json.loads(text)
        except ValueError:
            return
        if not isinstance(message, dict):
            return
        if message.get("type") == "neutral":
            self._neutral.set()
            if self._on_neutral is not None:
                try:
                    self._on_neutral()
                except Exception:
                    log.exception("viewer: the neutral callback failed")
        elif message.get("type") == "picture":
            client.picture = bool(message.get("on", True))
