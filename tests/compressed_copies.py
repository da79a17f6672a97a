"""Compressed copies of a test character, made with the packages' own encoders (``meshopt``, ``DracoPy``);
a test skips when the package is missing."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from facepuppet.io.scene import glb_bytes, parse_glb


def _uses(doc: dict, view: int) -> tuple[int, int]:
    """(count, element size in bytes) of the accessor reading buffer view ``view``."""
    size = {5126: 4, 5121: 1, 5123: 2, 5125: 4}
    width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}
    acc = next(a for a in doc["accessors"] if a.get("bufferView") == view)
    return acc["count"], size[acc["componentType"]] * width[acc["type"]]


def meshopt_copy(glb: bytes) -> bytes:
    """Every vertex and index buffer view meshopt-encoded into buffer 0; their plain data in a fallback buffer."""
    meshopt = pytest.importorskip("meshopt")
    doc, blob = parse_glb(glb)
    doc = copy.deepcopy(doc)
    packed, fallback = bytearray(), 0
    for i, view in enumerate(doc["bufferViews"]):
        raw = blob[view.get("byteOffset", 0):view.get("byteOffset", 0) + view["byteLength"]]
        packed.extend(b"\0" * (-len(packed) % 4))
        if view.get("target") in (34962, 34963):
            count, size = _uses(doc, i)
            if view["target"] == 34962:
                mode, data = "ATTRIBUTES", np.frombuffer(raw, np.uint8).reshape(count, size)
                view["byteStride"] = size
            else:
                mode, data = "TRIANGLES", np.frombuffer(raw, np.uint16)
            enc = meshopt.encode_gltf_buffer(data, mode)
            ext = {"buffer": 0, "byteOffset": len(packed), "byteLength": len(enc), "byteStride": size,
                   "count": count, "mode": mode}
            packed.extend(enc)
            view.update(buffer=1, byteOffset=fallback, extensions={"EXT_meshopt_compression": ext})
            fallback += view["byteLength"] + (-view["byteLength"] % 4)
        else:
            view.update(buffer=0, byteOffset=len(packed))
            packed.extend(raw)
    packed.extend(b"\0" * (-len(packed) % 4))
    doc["buffers"] = [{"byteLength": len(packed)},
                      {"byteLength": fallback, "extensions": {"EXT_meshopt_compression": {"fallback": True}}}]
    for key in ("extensionsUsed", "extensionsRequired"):
        doc[key] = doc.get(key, []) + ["EXT_meshopt_compression"]
    return glb_bytes(doc, bytes(packed))


def draco_copy(glb: bytes) -> bytes:
    """Positions, normals, UVs and indices of every primitive Draco-encoded (order kept; targets stay plain)."""
    draco = pytest.importorskip("DracoPy")
    doc, blob = parse_glb(glb)
    doc = copy.deepcopy(doc)

    def values(index, dtype, width):
        acc = doc["accessors"][index]
        view = doc["bufferViews"][acc["bufferView"]]
        return np.frombuffer(blob, dtype, acc["count"] * width, view.get("byteOffset", 0)).reshape(-1, width)

    extra = bytearray(blob)
    for mesh in doc["meshes"]:
        for prim in mesh["primitives"]:
            a = prim["attributes"]
            enc = draco.encode(values(a["POSITION"], np.float32, 3).astype(np.float64),
                               values(prim["indices"], np.uint16, 1).reshape(-1, 3).astype(np.int64),
                               quantization_bits=30, preserve_order=True,
                               normals=values(a["NORMAL"], np.float32, 3).astype(np.float64),
                               tex_coord=values(a["TEXCOORD_0"], np.float32, 2).astype(np.float64))
            ids = {x["attribute_type"]: x["unique_id"] for x in draco.decode(enc).attributes}
            extra.extend(b"\0" * (-len(extra) % 4))
            doc["bufferViews"].append({"buffer": 0, "byteOffset": len(extra), "byteLength": len(enc)})
            extra.extend(enc)
            prim["extensions"] = {"KHR_draco_mesh_compression": {
                "bufferView": len(doc["bufferViews"]) - 1,
                "attributes": {"POSITION": ids[0], "NORMAL": ids[1], "TEXCOORD_0": ids[3]}}}
            for index in (a["POSITION"], a["NORMAL"], a["TEXCOORD_0"], prim["indices"]):
                doc["accessors"][index].pop("bufferView")
    extra.extend(b"\0" * (-len(extra) % 4))
    doc["buffers"] = [{"byteLength": len(extra)}]
    for key in ("extensionsUsed", "extensionsRequired"):
        doc[key] = doc.get(key, []) + ["KHR_draco_mesh_compression"]
    return glb_bytes(doc, bytes(extra))
