"""Build a glTF 2.0 asset and write it as GLB (or .gltf with an embedded buffer), atomically.

Shared by :func:`facepuppet.io.gltf.write_glb` and :mod:`facepuppet.export.gltf_animation`. The JSON is a plain
dict; binary data goes into one buffer (:class:`BufferParts`), each array in its own 4-byte aligned buffer
view. An array can be held in memory or **streamed**: its size (count × width × item size) is known when it is
added, so every offset and the JSON are fixed before its bytes exist, and the bytes are made chunk by chunk
as the file is written (:func:`write_glb_stream`, :func:`write_gltf_stream`), one chunk in memory at a time.
The file is the same byte for byte either way.
"""

from __future__ import annotations

import base64
import json
import os
import struct
import uuid
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import BinaryIO

import numpy as np

from facepuppet._util.atomic import atomic_path

__all__ = ["GltfBuilder", "BufferParts", "write_glb_stream", "write_gltf_stream", "ARRAY_BUFFER",
           "ELEMENT_ARRAY_BUFFER", "vertex_normals"]

ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963
_COMPONENT = {np.dtype(np.float32): 5126, np.dtype(np.uint16): 5123, np.dtype(np.uint32): 5125,
              np.dtype(np.uint8): 5121, np.dtype(np.int8): 5120, np.dtype(np.int16): 5122}
_TYPE = {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4"}
_GLB_MAGIC, _CHUNK_JSON, _CHUNK_BIN = 0x46546C67, 0x4E4F534A, 0x004E4942


class BufferParts:
    """One glTF buffer as it is built: bytes in memory and streamed arrays (see the module notes).

    Parameters
    ----------
    data : bytes, optional
        What the buffer starts with (an existing scene's buffer).
    """

    def __init__(self, data: bytes | bytearray = b"") -> None:
        self._parts: list = [bytearray(data)]
        self.size = len(data)

    def align(self) -> None:
        """Pad with zeros to a multiple of 4 bytes."""
        self.append(b"\0" * (-self.size % 4))

    def append(self, data: bytes) -> int:
        """Append bytes; returns their offset."""
        at = self.size
        if not isinstance(self._parts[-1], bytearray):
            self._parts.append(bytearray())
        self._parts[-1].extend(data)
        self.size += len(data)
        return at

    def append_stream(self, nbytes: int, chunks: Callable[[], Iterable[np.ndarray]]) -> int:
        """Reserve ``nbytes`` made when the file is written by ``chunks()`` (contiguous arrays whose bytes, in
        order, are exactly ``nbytes``); returns their offset."""
        at = self.size
        self._parts.append((int(nbytes), chunks))
        self.size += int(nbytes)
        return at

    def iter_bytes(self) -> Iterator[bytes | bytearray | memoryview]:
        """The buffer's bytes in order, a streamed array chunk by chunk (ValueError if one is not its size)."""
        for part in self._parts:
            if isinstance(part, bytearray):
                if part:
                    yield part
                continue
            nbytes, chunks = part
            made = 0
            for array in chunks():
                data = memoryview(np.ascontiguousarray(array)).cast("B")
                made += len(data)
                if made > nbytes:
                    break
                yield data
            if made != nbytes:
                raise ValueError(f"a streamed array made {made} bytes, {nbytes} were reserved")

    def tobytes(self) -> bytes:
        return b"".join(bytes(b) for b in self.iter_bytes())


def write_glb_stream(fh: BinaryIO, json_text: bytes, parts: BufferParts) -> None:
    """Write a GLB container to ``fh``: header, JSON chunk (``json_text``, space padded), then the BIN chunk
    (``parts``, zero padded) streamed."""
    text = json_text + b" " * (-len(json_text) % 4)
    pad = -parts.size % 4
    total = 12 + 8 + len(text) + (8 + parts.size + pad if parts.size else 0)
    fh.write(struct.pack("<III", _GLB_MAGIC, 2, total))
    fh.write(struct.pack("<II", len(text), _CHUNK_JSON))
    fh.write(text)
    if parts.size:
        fh.write(struct.pack("<II", parts.size + pad, _CHUNK_BIN))
        for data in parts.iter_bytes():
            fh.write(data)
        fh.write(b"\0" * pad)


def write_gltf_stream(fh: BinaryIO, doc: dict, buffer: dict, parts: BufferParts, *, indent: int = 1,
                      ensure_ascii: bool = True) -> None:
    """Write ``doc`` as .gltf JSON (UTF-8) to ``fh``, the dict ``buffer`` (one of ``doc``'s buffers) getting
    ``parts`` as a base64 data URI, streamed: the same text as ``json.dumps`` of the document with the URI in
    place."""
    marker = f"facepuppet-buffer-{uuid.uuid4().hex}"
    before = buffer.get("uri")
    buffer["uri"] = marker
    try:
        text = json.dumps(doc, indent=indent, ensure_ascii=ensure_ascii)
    finally:
        if before is None:
            del buffer["uri"]
        else:
            buffer["uri"] = before
    head, sep, tail = text.partition(marker)
    if not sep or marker in tail:
        raise ValueError("the buffer's URI could not be placed in the glTF JSON")
    fh.write(head.encode("utf-8"))
    fh.write(b"data:application/octet-stream;base64,")
    carry = b""
    for data in parts.iter_bytes():
        data = carry + bytes(data)
        cut = len(data) - len(data) % 3
        fh.write(base64.b64encode(data[:cut]))
        carry = data[cut:]
    fh.write(base64.b64encode(carry))
    fh.write(tail.encode("utf-8"))


class GltfBuilder:
    """An asset under construction: ``json`` is the glTF dict, arrays go in with :meth:`add_accessor`
    (in memory) or :meth:`add_streamed_accessor` (made as the file is written)."""

    def __init__(self, generator: str = "facepuppet") -> None:
        self.json: dict = {"asset": {"version": "2.0", "generator": generator}}
        self._parts = BufferParts()

    def _append(self, key: str, item: dict) -> int:
        self.json.setdefault(key, []).append(item)
        return len(self.json[key]) - 1

    def add_node(self, node: dict) -> int:
        return self._append("nodes", node)

    def add_mesh(self, mesh: dict) -> int:
        return self._append("meshes", mesh)

    def add_animation(self, animation: dict) -> int:
        return self._append("animations", animation)

    def add_accessor(self, array: np.ndarray, *, target: int | None = None, min_max: bool = False) -> int:
        """Store ``array`` ((N,) or (N, k), dtype float32/uint16/uint32/...) and return its accessor index."""
        array = np.ascontiguousarray(array)
        if array.dtype not in _COMPONENT:
            raise TypeError(f"cannot store dtype {array.dtype} in glTF")
        k = 1 if array.ndim == 1 else array.shape[1]
        self._parts.align()
        view = {"buffer": 0, "byteOffset": self._parts.size, "byteLength": array.nbytes}
        if target is not None:
            view["target"] = target
        self._parts.append(array.tobytes())
        accessor = {"bufferView": self._append("bufferViews", view), "componentType": _COMPONENT[array.dtype],
                    "count": int(array.shape[0]), "type": _TYPE[k]}
        if min_max:
            flat = array.reshape(len(array), k)
            cast = float if array.dtype.kind == "f" else int
            accessor["min"] = [cast(x) for x in flat.min(axis=0)]
            accessor["max"] = [cast(x) for x in flat.max(axis=0)]
        return self._append("accessors", accessor)

    def add_streamed_accessor(self, count: int, k: int, chunks: Callable[[], Iterable[np.ndarray]], *,
                              min_max: bool = False) -> int:
        """An accessor of ``count`` float32 items of ``k`` values, made by ``chunks()`` (float32 arrays of
        shape (n,) or (n, k), together ``count`` items) when the file is written; ``min_max`` takes one pass
        now for the accessor's bounds. Returns its accessor index."""
        self._parts.align()
        nbytes = int(count) * int(k) * 4
        view = {"buffer": 0, "byteOffset": self._parts.size, "byteLength": nbytes}
        self._parts.append_stream(nbytes, chunks)
        accessor = {"bufferView": self._append("bufferViews", view), "componentType": _COMPONENT[np.dtype(np.float32)],
                    "count": int(count), "type": _TYPE[k]}
        if min_max:
            low, high = _bounds(chunks(), k)
            accessor["min"] = [float(x) for x in low]
            accessor["max"] = [float(x) for x in high]
        return self._append("accessors", accessor)

    def _finish(self, uri: str | None) -> dict:
        self._parts.align()
        doc = dict(self.json)
        if self._parts.size:
            buffer = {"byteLength": self._parts.size}
            if uri is not None:
                buffer["uri"] = uri
            doc["buffers"] = [buffer]
        return doc

    def glb_bytes(self) -> bytes:
        """The asset as a GLB container: header, JSON chunk (space padded), BIN chunk (zero padded)."""
        text = json.dumps(self._finish(None), separators=(",", ":")).encode("utf-8")
        text += b" " * (-len(text) % 4)
        chunks = struct.pack("<II", len(text), _CHUNK_JSON) + text
        if self._parts.size:
            chunks += struct.pack("<II", self._parts.size, _CHUNK_BIN) + self._parts.tobytes()
        return struct.pack("<III", _GLB_MAGIC, 2, 12 + len(chunks)) + chunks

    def gltf_text(self) -> str:
        """The asset as .gltf JSON with the buffer embedded as a base64 data URI."""
        uri = "data:application/octet-stream;base64," + base64.b64encode(self._parts.tobytes()).decode("ascii")
        return json.dumps(self._finish(uri if self._parts.size else None), indent=1)

    def write(self, path: str | os.PathLike) -> None:
        """Write to ``path`` atomically, streamed arrays chunk by chunk: GLB unless the suffix is ``.gltf``."""
        path = Path(path)
        with atomic_path(path) as tmp, open(tmp, "wb") as fh:
            doc = self._finish(None)
            if path.suffix.lower() != ".gltf":
                write_glb_stream(fh, json.dumps(doc, separators=(",", ":")).encode("utf-8"), self._parts)
            elif "buffers" in doc:
                write_gltf_stream(fh, doc, doc["buffers"][0], self._parts)
            else:
                fh.write(json.dumps(doc, indent=1).encode("utf-8"))


def _bounds(chunks: Iterable[np.ndarray], k: int) -> tuple[np.ndarray, np.ndarray]:
    """Per-component min and max over float32 chunks of ``k`` values an item."""
    low = np.full(k, np.inf, dtype=np.float32)
    high = np.full(k, -np.inf, dtype=np.float32)
    for array in chunks:
        flat = np.asarray(array, dtype=np.float32).reshape(-1, k)
        if len(flat):
            low = np.minimum(low, flat.min(axis=0))
            high = np.maximum(high, flat.max(axis=0))
    return low, high


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(V, 3) unit vertex normals, area-weighted from ``faces`` (T, 3); +y where a vertex has no face."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    face_n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    n = np.zeros_like(v)
    for corner in range(3):
        np.add.at(n, f[:, corner], face_n)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    out = np.where(length > 0, n / np.where(length > 0, length, 1.0), [0.0, 1.0, 0.0])
    return out.astype(np.float32)
