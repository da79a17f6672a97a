"""Decoding of compressed glTF meshes: ``EXT_meshopt_compression`` and ``KHR_draco_mesh_compression``.

Optional extras: ``pip install 'facepuppet[meshopt]'`` (PyPI ``meshopt``) and ``pip install 'facepuppet[draco]'``
(PyPI ``DracoPy``). :func:`decode_compressed` works on the JSON dict and the bytes of each buffer view that
:func:`facepuppet.io.scene.load_scene` collects: a meshopt-compressed view gets its decoded bytes (filters
undone), a Draco-compressed primitive gets plain accessors (new buffer views, appended), and the extension is
removed from the view, the primitive and ``extensionsUsed`` / ``extensionsRequired``.

Draco reorders vertices unless the encoder was told to keep their order; the glTF extension requires the order
kept when a primitive has morph targets (they stay uncompressed accessors), so key-models stay aligned.
"""

from __future__ import annotations

import logging

import numpy as np

from facepuppet.errors import FacepuppetError

__all__ = ["COMPRESSION", "decode_compressed"]

log = logging.getLogger(__name__)

MESHOPT, DRACO = "EXT_meshopt_compression", "KHR_draco_mesh_compression"
#: Compression extensions decoded here (KHR_meshopt_compression is the ratified name of the same format).
COMPRESSION = frozenset({MESHOPT, "KHR_meshopt_compression", DRACO})
_DTYPE = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}
_NORM = {5120: 127.0, 5121: 255.0, 5122: 32767.0, 5123: 65535.0}


def _need(module: str, extra: str, extension: str, label: str):
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError as e:
        raise FacepuppetError(f"{label}: compressed with {extension}; decoding it needs "
                              f"pip install 'facepuppet[{extra}]'") from e


def decode_compressed(doc: dict, views: list[bytes], buffers: list[bytes | None], label: str) -> list[bytes]:
    """Decode every compressed view and primitive of ``doc`` in place; return the views' bytes.

    Parameters
    ----------
    doc : dict
        glTF JSON (modified: extensions removed, accessors of Draco primitives pointed at new views).
    views : list of bytes
        Bytes of each buffer view (empty for a meshopt view whose buffer is a fallback without data).
    buffers : list of bytes or None
        Each buffer's data (None for a fallback buffer).
    label : str
        The file, for messages.
    """
    views = list(views)
    for name in ("EXT_meshopt_compression", "KHR_meshopt_compression"):
        if any(name in (v.get("extensions") or {}) for v in doc.get("bufferViews") or []):
            meshopt = _need("meshopt", "meshopt", name, label)
            for i, view in enumerate(doc["bufferViews"]):
                ext = (view.get("extensions") or {}).pop(name, None)
                if ext is None:
                    continue
                source = buffers[ext.get("buffer", 0)]
                if source is None:
                    raise FacepuppetError(f"{label}: buffer view {i}: its compressed buffer has no data")
                start = int(ext.get("byteOffset", 0))
                data = source[start:start + int(ext["byteLength"])]
                filt = ext.get("filter", "NONE")
                out = meshopt.decode_gltf_buffer(data, int(ext["count"]), int(ext["byteStride"]), ext["mode"],
                                                 None if filt == "NONE" else filt)
                views[i] = np.ascontiguousarray(out).tobytes()
                if not view["extensions"]:
                    del view["extensions"]
    prims = [p for m in doc.get("meshes") or [] for p in m.get("primitives") or []
             if DRACO in (p.get("extensions") or {})]
    if prims:
        draco = _need("DracoPy", "draco", DRACO, label)
        for prim in prims:
            ext = prim["extensions"].pop(DRACO)
            if not prim["extensions"]:
                del prim["extensions"]
            try:
                mesh = draco.decode(views[ext["bufferView"]])
            except Exception as e:  # DracoPy raises its own error types
                raise FacepuppetError(f"{label}: cannot decode a Draco primitive ({e})") from e
            if prim.get("indices") is not None and getattr(mesh, "faces", None) is not None:
                _fill(doc, views, prim["indices"], np.asarray(mesh.faces).reshape(-1))
            for attr, uid in (ext.get("attributes") or {}).items():
                if attr in prim.get("attributes", {}):
                    att = mesh.get_attribute_by_unique_id(int(uid))
                    if att is None:
                        raise FacepuppetError(f"{label}: Draco primitive lacks attribute {attr} (id {uid})")
                    _fill(doc, views, prim["attributes"][attr], np.asarray(att["data"]))
    found = sorted(set(doc.get("extensionsUsed") or []) & COMPRESSION)
    if found:
        log.warning("%s: decoded %s; what facepuppet writes from this character is uncompressed", label,
                    ", ".join(found))
    for key in ("extensionsUsed", "extensionsRequired"):
        kept = [e for e in doc.get(key) or [] if e not in COMPRESSION]
        if kept:
            doc[key] = kept
        else:
            doc.pop(key, None)
    return views


def _fill(doc: dict, views: list[bytes], index: int, values: np.ndarray) -> None:
    """Point accessor ``index`` at a new view holding ``values`` in the accessor's own component type."""
    acc = doc["accessors"][index]
    dtype, width = _DTYPE[acc["componentType"]], _WIDTH[acc["type"]]
    values = np.asarray(values).reshape(int(acc["count"]), width)
    if acc.get("normalized") and values.dtype.kind == "f":
        values = np.round(values * _NORM[acc["componentType"]])
    data = values.astype(dtype).tobytes()
    view: dict = {"buffer": 0, "byteLength": len(data)}
    doc.setdefault("bufferViews", []).append(view)
    views.append(data)
    acc["bufferView"], acc["byteOffset"] = len(doc["bufferViews"]) - 1, 0
