"""A character's whole glTF scene as one self-contained GLB, kept so that the animation can be written into it.

:func:`load_scene` reads a .glb, .gltf or .vrm and returns a :class:`Scene`: the glTF JSON as a plain dict and
one binary blob that buffer 0 holds. A GLB with a single embedded buffer is kept as it is, JSON and bytes. Any
other file is packed: every buffer view is copied into one blob (8-byte aligned, in view order), external or
data-URI images become buffer views of that blob, and buffer views or primitives compressed with
``EXT_meshopt_compression`` / ``KHR_draco_mesh_compression`` are decoded to plain data
(:mod:`facepuppet.io.compressed`; the extension is then dropped, so what is written back is uncompressed).
Accessor values are never changed.

External files are read only from the glTF file's own folder or below it (a relative URI without ``..`` that
leaves it, no absolute path, no scheme other than ``data:``).
"""

from __future__ import annotations

import base64
import copy
import json
import os
import struct
import urllib.parse
from dataclasses import dataclass
from pathlib import Path

from facepuppet.errors import FacepuppetError

__all__ = ["Scene", "load_scene", "scene_from_glb", "parse_glb", "glb_bytes"]

_GLB_MAGIC, _CHUNK_JSON, _CHUNK_BIN = 0x46546C67, 0x4E4F534A, 0x004E4942
#: Image MIME types by file suffix (glTF 2.0 allows PNG and JPEG; KTX2 and WebP come with extensions).
_MIME = {".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg", ".webp": "image/webp",
         ".ktx2": "image/ktx2"}
_ALIGN = 8


@dataclass(frozen=True)
class Scene:
    """A glTF asset with all its binary data in one blob.

    Attributes
    ----------
    doc : dict
        The glTF JSON; ``buffers`` is ``[{"byteLength": len(blob)}]`` (or absent when ``blob`` is empty).
    blob : bytes
        The data of buffer 0 (a GLB's BIN chunk).
    """

    doc: dict
    blob: bytes

    def glb(self) -> bytes:
        """The scene as GLB bytes."""
        return glb_bytes(self.doc, self.blob)


def parse_glb(data: bytes, label: str = "GLB") -> tuple[dict, bytes | None]:
    """Split GLB bytes into (JSON dict, BIN chunk or None); FacepuppetError on a malformed container."""
    if len(data) < 20 or struct.unpack_from("<I", data, 0)[0] != _GLB_MAGIC:
        raise FacepuppetError(f"{label}: not a GLB file")
    _, version, length = struct.unpack_from("<III", data, 0)
    if version != 2 or length > len(data):
        raise FacepuppetError(f"{label}: GLB version {version} or length {length} is wrong")
    doc, blob, at = None, None, 12
    while at + 8 <= length:
        size, kind = struct.unpack_from("<II", data, at)
        chunk = data[at + 8:at + 8 + size]
        if len(chunk) != size:
            raise FacepuppetError(f"{label}: GLB chunk at byte {at} runs past the file")
        if kind == _CHUNK_JSON and doc is None:
            try:
                doc = json.loads(chunk.decode("utf-8"))
            except (UnicodeDecodeError, ValueError, RecursionError) as e:
                raise FacepuppetError(f"{label}: bad JSON chunk ({_reason(e)})") from e
        elif kind == _CHUNK_BIN and blob is None:
            blob = bytes(chunk)
        at += 8 + size + (-size % 4)
    if not isinstance(doc, dict):
        raise FacepuppetError(f"{label}: GLB has no JSON chunk")
    _check_depth(doc, label)
    _check_nodes(doc, label)
    return doc, blob


#: Deepest nesting of objects and lists a glTF JSON may have (a scene is a few levels; extras a few more).
MAX_JSON_DEPTH = 64


def _reason(e: Exception) -> str:
    return "nested too deeply" if isinstance(e, RecursionError) else str(e)


#: A node's transform members and how many numbers each holds (glTF 2.0 node: TRS or a column-major matrix).
_TRANSFORM_SIZES = {"translation": 3, "rotation": 4, "scale": 3, "matrix": 16}
#: The largest float32 magnitude: viewers hold node transforms in float32, so a larger value is infinite there.
_FLOAT32_MAX = 3.4028234663852886e38


def _check_nodes(doc: dict, label: str) -> None:
    """FacepuppetError naming ``label`` unless the nodes form trees, as glTF requires: every child index names a
    node, no node has two parents, no node is its own ancestor (walking such a graph would never end); every
    node's transform is a list of finite numbers of its size that float32 can hold; every skin's joints and
    skeleton name nodes."""
    nodes = doc.get("nodes") or []
    if not isinstance(nodes, list):
        raise FacepuppetError(f"{label}: glTF nodes is not a list")
    for i, node in enumerate(nodes):
        for key, size in _TRANSFORM_SIZES.items():
            value = node.get(key) if isinstance(node, dict) else None
            if value is None:
                continue
            if not (isinstance(value, list) and len(value) == size
                    and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                            and abs(v) <= _FLOAT32_MAX for v in value)):   # NaN fails the comparison
                raise FacepuppetError(f"{label}: node {i}'s {key} is not {size} finite numbers within float32's "
                                      f"range")
    skins = doc.get("skins") or []
    for k, skin in enumerate(skins if isinstance(skins, list) else [None]):
        joints = skin.get("joints") if isinstance(skin, dict) else None
        refs = list(joints) if isinstance(joints, list) else [None]
        if isinstance(skin, dict) and "skeleton" in skin:
            refs.append(skin["skeleton"])
        for j in refs:
            if not isinstance(j, int) or isinstance(j, bool) or not 0 <= j < len(nodes):
                raise FacepuppetError(f"{label}: skin {k} names a joint {j!r} that is no node")
    parent: dict[int, int] = {}
    for i, node in enumerate(nodes):
        children = node.get("children") or [] if isinstance(node, dict) else None
        if not isinstance(children, list):
            raise FacepuppetError(f"{label}: node {i} is damaged (its children are not a list)")
        for c in children:
            if not isinstance(c, int) or isinstance(c, bool) or not 0 <= c < len(nodes):
                raise FacepuppetError(f"{label}: node {i} has a child {c!r} that is no node")
            if c in parent:
                raise FacepuppetError(f"{label}: node {c} has two parents (nodes {parent[c]} and {i})")
            parent[c] = i
    for start in parent:
        seen, at = {start}, parent[start]
        while at in parent:
            if at in seen:
                raise FacepuppetError(f"{label}: node {start} is its own ancestor (the node tree has a cycle)")
            seen.add(at)
            at = parent[at]
        if at == start:
            raise FacepuppetError(f"{label}: node {start} is its own ancestor (the node tree has a cycle)")


def _check_depth(doc, label: str) -> None:
    """FacepuppetError naming ``label`` when the JSON nests deeper than :data:`MAX_JSON_DEPTH` (walked without
    recursion: copying or walking it later would exhaust Python's stack)."""
    level = [doc]
    for _ in range(MAX_JSON_DEPTH + 1):
        level = [v for x in level for v in (x.values() if isinstance(x, dict) else x)
                 if isinstance(v, (dict, list))]
        if not level:
            return
    raise FacepuppetError(f"{label}: glTF JSON nested more than {MAX_JSON_DEPTH} levels deep")


def glb_bytes(doc: dict, blob: bytes) -> bytes:
    """GLB container of ``doc`` and ``blob``: header, JSON chunk (space padded), BIN chunk (zero padded)."""
    text = json.dumps(doc, separators=(",", ":"), ensure_ascii=False).encode("utf-8")
    text += b" " * (-len(text) % 4)
    chunks = struct.pack("<II", len(text), _CHUNK_JSON) + text
    if blob:
        padded = bytes(blob) + b"\0" * (-len(blob) % 4)
        chunks += struct.pack("<II", len(padded), _CHUNK_BIN) + padded
    return struct.pack("<III", _GLB_MAGIC, 2, 12 + len(chunks)) + chunks


def scene_from_glb(data: bytes, label: str = "GLB") -> Scene:
    """A :class:`Scene` from bytes :meth:`Scene.glb` wrote (one embedded buffer)."""
    doc, blob = parse_glb(bytes(data), label)
    return Scene(doc=doc, blob=blob or b"")


def load_scene(path: str | os.PathLike) -> Scene:
    """Read a .glb / .gltf / .vrm file into a :class:`Scene` (see the module notes)."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as e:
        raise FacepuppetError(f"{path}: cannot read ({e.strerror})") from e
    if data[:4] == b"glTF":
        doc, glb_blob = parse_glb(data, str(path))
    else:
        glb_blob = None
        try:
            doc = json.loads(data.decode("utf-8-sig"))
        except (UnicodeDecodeError, ValueError, RecursionError) as e:
            raise FacepuppetError(f"{path}: neither GLB nor glTF JSON ({_reason(e)})") from e
        if not isinstance(doc, dict):
            raise FacepuppetError(f"{path}: glTF JSON is not an object")
        _check_depth(doc, str(path))
        _check_nodes(doc, str(path))
    from facepuppet.io.compressed import COMPRESSION, decode_compressed

    buffers = doc.get("buffers") or []
    images = doc.get("images") or []
    compressed = set(doc.get("extensionsUsed") or []) & COMPRESSION
    simple = (len(buffers) <= 1 and all(b.get("uri") is None for b in buffers)
              and all(im.get("uri") is None for im in images) and not compressed)
    if simple:
        return Scene(doc=doc, blob=glb_blob or b"")
    doc = copy.deepcopy(doc)
    data_of = [_buffer_data(path, i, b, glb_blob) for i, b in enumerate(doc.get("buffers") or [])]
    views = [_view_bytes(path, i, v, data_of) for i, v in enumerate(doc.get("bufferViews") or [])]
    if compressed:
        views = decode_compressed(doc, views, data_of, str(path))
    for i, image in enumerate(images):
        if image.get("uri") is not None:
            views.append(_uri_bytes(path, image["uri"], f"image {i}"))
            doc.setdefault("bufferViews", []).append({"buffer": 0, "byteLength": len(views[-1])})
            mime = image.get("mimeType") or _mime(image["uri"], path, i)
            del image["uri"]
            image["bufferView"], image["mimeType"] = len(doc["bufferViews"]) - 1, mime
    blob = bytearray()
    for view, chunk in zip(doc.get("bufferViews") or [], views, strict=True):
        blob.extend(b"\0" * (-len(blob) % _ALIGN))
        view["buffer"], view["byteOffset"], view["byteLength"] = 0, len(blob), len(chunk)
        blob.extend(chunk)
    if blob:
        doc["buffers"] = [{"byteLength": len(blob)}]
    else:
        doc.pop("buffers", None)
    return Scene(doc=doc, blob=bytes(blob))


def _buffer_data(path: Path, index: int, buf: dict, glb_blob: bytes | None) -> bytes | None:
    """Bytes of buffer ``index``; None for a buffer without data (a meshopt fallback buffer)."""
    uri = buf.get("uri")
    if uri is None:
        if index == 0 and glb_blob is not None:
            return glb_blob
        if (buf.get("extensions") or {}).get("EXT_meshopt_compression", {}).get("fallback"):
            return None
        raise FacepuppetError(f"{path}: buffer {index} has no data (no uri and no GLB BIN chunk)")
    data = _uri_bytes(path, uri, f"buffer {index}", int(buf.get("byteLength", 0)))
    if len(data) < int(buf.get("byteLength", 0)):
        raise FacepuppetError(f"{path}: buffer {index} holds {len(data)} bytes, needs {buf.get('byteLength')}")
    return data


def _view_bytes(path: Path, index: int, view: dict, data_of: list) -> bytes:
    data = data_of[view.get("buffer", 0)] if 0 <= view.get("buffer", 0) < len(data_of) else None
    if data is None:
        if "EXT_meshopt_compression" in (view.get("extensions") or {}):
            return b""  # filled by the decoder
        raise FacepuppetError(f"{path}: buffer view {index} points at a buffer without data")
    start, length = int(view.get("byteOffset", 0)), int(view["byteLength"])
    if start < 0 or start + length > len(data):
        raise FacepuppetError(f"{path}: buffer view {index} runs past its buffer")
    return data[start:start + length]


#: Largest image file a character may reference, bytes.
MAX_IMAGE_BYTES = 1 << 30


def _uri_bytes(path: Path, uri: str, what: str, byte_length: int | None = None) -> bytes:
    """Bytes a URI of ``path`` names: a data URI, or a regular file inside ``path``'s folder (a buffer: its
    first ``byte_length`` bytes, :func:`~facepuppet.io.external.read_external`'s rules)."""
    if byte_length is not None and not uri.startswith("data:"):
        from facepuppet.io.external import read_external

        return read_external(path, uri, byte_length, what)
    if uri.startswith("data:"):
        try:
            return base64.b64decode(uri.split(",", 1)[1])
        except (IndexError, ValueError) as e:
            raise FacepuppetError(f"{path}: {what} has a bad data URI") from e
    parsed = urllib.parse.urlparse(uri)
    rel = urllib.parse.unquote(parsed.path)
    if parsed.scheme or parsed.netloc or os.path.isabs(rel):
        raise FacepuppetError(f"{path}: {what} URI {uri!r} is not a relative file name")
    folder = path.parent.resolve()
    file = (folder / rel).resolve()
    if folder not in file.parents:
        raise FacepuppetError(f"{path}: {what} URI {uri!r} leaves the file's folder")
    if not file.is_file():
        raise FacepuppetError(f"{path}: {what} URI {uri!r} names no regular file")
    if file.stat().st_size > MAX_IMAGE_BYTES:
        raise FacepuppetError(f"{path}: {what} file {file} is larger than {MAX_IMAGE_BYTES >> 20} MB")
    try:
        return file.read_bytes()
    except OSError as e:
        raise FacepuppetError(f"{path}: cannot read {what.split()[0]} file {file} ({e.strerror})") from e


def _mime(uri: str, path: Path, index: int) -> str:
    suffix = Path(urllib.parse.urlparse(uri).path).suffix.lower()
    if uri.startswith("data:"):
        return uri[5:].split(";", 1)[0].split(",", 1)[0] or "image/png"
    if suffix not in _MIME:
        raise FacepuppetError(f"{path}: image {index} {uri!r}: unknown image type (no mimeType, suffix {suffix})")
    return _MIME[suffix]
