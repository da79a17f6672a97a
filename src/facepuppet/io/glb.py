"""Build a glTF 2.0 asset in memory and write it as GLB (or .gltf with an embedded buffer), atomically.

Shared by :func:`facepuppet.io.gltf.write_glb` and :mod:`facepuppet.export.gltf_animation`. The JSON is a plain
dict; binary data goes into one buffer, each array in its own 4-byte aligned buffer view.
"""

from __future__ import annotations

import base64
import json
import os
import struct
from pathlib import Path

import numpy as np

from facepuppet._util.atomic import atomic_path

__all__ = ["GltfBuilder", "ARRAY_BUFFER", "ELEMENT_ARRAY_BUFFER", "vertex_normals"]

ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963
_COMPONENT = {np.dtype(np.float32): 5126, np.dtype(np.uint16): 5123, np.dtype(np.uint32): 5125,
              np.dtype(np.uint8): 5121, np.dtype(np.int8): 5120, np.dtype(np.int16): 5122}
_TYPE = {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4"}
_GLB_MAGIC, _CHUNK_JSON, _CHUNK_BIN = 0x46546C67, 0x4E4F534A, 0x004E4942


class GltfBuilder:
    """An asset under construction: ``json`` is the glTF dict, arrays go in with :meth:`add_accessor`."""

    def __init__(self, generator: str = "facepuppet") -> None:
        self.json: dict = {"asset": {"version": "2.0", "generator": generator}}
        self._blob = bytearray()

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
        while len(self._blob) % 4:
            self._blob.append(0)
        view = {"buffer": 0, "byteOffset": len(self._blob), "byteLength": array.nbytes}
        if target is not None:
            view["target"] = target
        self._blob.extend(array.tobytes())
        accessor = {"bufferView": self._append("bufferViews", view), "componentType": _COMPONENT[array.dtype],
                    "count": int(array.shape[0]), "type": _TYPE[k]}
        if min_max:
            flat = array.reshape(len(array), k)
            cast = float if array.dtype.kind == "f" else int
            accessor["min"] = [cast(x) for x in flat.min(axis=0)]
            accessor["max"] = [cast(x) for x in flat.max(axis=0)]
        return self._append("accessors", accessor)

    def _finish(self, uri: str | None) -> dict:
        while len(self._blob) % 4:
            self._blob.append(0)
        doc = dict(self.json)
        if self._blob:
            buffer = {"byteLength": len(self._blob)}
            if uri is not None:
                buffer["uri"] = uri
            doc["buffers"] = [buffer]
        return doc

    def glb_bytes(self) -> bytes:
        """The asset as a GLB container: header, JSON chunk (space padded), BIN chunk (zero padded)."""
        text = json.dumps(self._finish(None), separators=(",", ":")).encode("utf-8")
        text += b" " * (-len(text) % 4)
        chunks = struct.pack("<II", len(text), _CHUNK_JSON) + text
        if self._blob:
            chunks += struct.pack("<II", len(self._blob), _CHUNK_BIN) + bytes(self._blob)
        return struct.pack("<III", _GLB_MAGIC, 2, 12 + len(chunks)) + chunks

    def gltf_text(self) -> str:
        """The asset as .gltf JSON with the buffer embedded as a base64 data URI."""
        uri = "data:application/octet-stream;base64," + base64.b64encode(bytes(self._blob)).decode("ascii")
        return json.dumps(self._finish(uri if self._blob else None), indent=1)

    def write(self, path: str | os.PathLike) -> None:
        """Write to ``path`` atomically: GLB unless the suffix is ``.gltf``."""
        path = Path(path)
        with atomic_path(path) as tmp:
            if path.suffix.lower() == ".gltf":
                tmp.write_text(self.gltf_text(), encoding="utf-8")
            else:
                tmp.write_bytes(self.glb_bytes())


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
