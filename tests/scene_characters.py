"""Whole characters the tests build themselves: several meshes sharing key-model names, a skin with a head
joint, a textured material with an embedded PNG, normals and UVs, a camera, an animation and an extension.

``skinned_character`` returns the GLB bytes and what went into them. Vertex positions are float32-exact.
"""

from __future__ import annotations

import json
import struct

import cv2
import numpy as np

HEAD_NAMES = ("jawOpen", "eyeBlinkLeft", "mouthSmileLeft", "extraShape")
TEETH_NAMES = ("jawOpen",)
EYES_NAMES = ("eyeBlinkLeft",)
#: Default weights of the head mesh (``extraShape`` is on at 0.3 and no rig drives it).
HEAD_DEFAULTS = (0.0, 0.0, 0.0, 0.3)


class Blob:
    """glTF JSON dict and one binary buffer under construction."""

    def __init__(self) -> None:
        self.doc: dict = {"asset": {"version": "2.0", "generator": "facepuppet tests"}}
        self.data = bytearray()

    def view(self, raw: bytes, target: int | None = None) -> int:
        self.data.extend(b"\0" * (-len(self.data) % 4))
        view = {"buffer": 0, "byteOffset": len(self.data), "byteLength": len(raw)}
        if target:
            view["target"] = target
        self.data.extend(raw)
        self.doc.setdefault("bufferViews", []).append(view)
        return len(self.doc["bufferViews"]) - 1

    def accessor(self, array: np.ndarray, *, target: int | None = 34962, min_max: bool = False,
                 normalized: bool = False) -> int:
        array = np.ascontiguousarray(array)
        k = 1 if array.ndim == 1 else array.shape[1]
        comp = {np.float32: 5126, np.uint8: 5121, np.uint16: 5123, np.uint32: 5125}[array.dtype.type]
        acc = {"bufferView": self.view(array.tobytes(), target), "componentType": comp, "count": len(array),
               "type": {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4", 16: "MAT4"}[k]}
        if k == 16:
            acc["type"] = "MAT4"
        if normalized:
            acc["normalized"] = True
        if min_max:
            flat = array.reshape(len(array), k)
            acc["min"], acc["max"] = [float(x) for x in flat.min(0)], [float(x) for x in flat.max(0)]
        self.doc.setdefault("accessors", []).append(acc)
        return len(self.doc["accessors"]) - 1

    def glb(self) -> bytes:
        self.data.extend(b"\0" * (-len(self.data) % 4))
        self.doc["buffers"] = [{"byteLength": len(self.data)}]
        text = json.dumps(self.doc).encode()
        text += b" " * (-len(text) % 4)
        body = struct.pack("<II", len(text), 0x4E4F534A) + text
        body += struct.pack("<II", len(self.data), 0x004E4942) + bytes(self.data)
        return struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body


def _f32(a) -> np.ndarray:
    return np.asarray(a, dtype=np.float32)


def _part(rng, v: int, m: int, centre) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    base = _f32(rng.normal(size=(v, 3)) * 0.1 + centre)
    deltas = _f32(rng.normal(size=(m, v, 3)) * 0.02)
    faces = np.array([[i, i + 1, i + 2] for i in range(v - 2)], dtype=np.uint16)
    return base, deltas, faces


def _mesh(b: Blob, base, deltas, faces, names, *, material: int, rng, skin_joints=None, defaults=None,
          morph_normals: bool = False) -> int:
    n = rng.normal(size=base.shape)
    attributes = {"POSITION": b.accessor(base, min_max=True),
                  "NORMAL": b.accessor(_f32(n / np.linalg.norm(n, axis=1, keepdims=True))),
                  "TEXCOORD_0": b.accessor(_f32(rng.uniform(0, 1, size=(len(base), 2))))}
    if skin_joints is not None:
        attributes["JOINTS_0"] = b.accessor(skin_joints.astype(np.uint8))
        w = np.zeros((len(base), 4), np.float32)
        w[:, 0] = 1.0
        attributes["WEIGHTS_0"] = b.accessor(w)
    prim = {"attributes": attributes, "indices": b.accessor(faces.reshape(-1), target=34963),
            "material": material, "targets": [{"POSITION": b.accessor(d, min_max=True)} for d in deltas]}
    if morph_normals:
        for target in prim["targets"]:
            target["NORMAL"] = b.accessor(_f32(rng.normal(size=base.shape) * 0.05))
    mesh = {"name": None, "primitives": [prim], "extras": {"targetNames": list(names)}}
    if defaults is not None:
        mesh["weights"] = list(defaults)
    b.doc.setdefault("meshes", []).append(mesh)
    return len(b.doc["meshes"]) - 1


def skinned_character(rng, *, head_joint_name: str = "mixamorig:Head", skinned: bool = True,
                      morph_normals: bool = False) -> dict:
    """A GLB of a skinned head, teeth and eyes (sharing ``jawOpen`` / ``eyeBlinkLeft``), textured; with
    ``morph_normals`` the head's morph targets move its normals too.

    Returns a dict: ``glb`` (bytes), ``parts`` (name -> (base, deltas) in the mesh's own coordinates),
    ``head_joint`` (node index of the head joint).
    """
    b = Blob()
    png = cv2.imencode(".png", (rng.uniform(0, 255, size=(8, 8, 3))).astype(np.uint8))[1].tobytes()
    b.doc["images"] = [{"name": "skin", "bufferView": b.view(png), "mimeType": "image/png"}]
    b.doc["samplers"] = [{"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497}]
    b.doc["textures"] = [{"sampler": 0, "source": 0}]
    b.doc["materials"] = [
        {"name": "skin", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0},
         "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 2.0}},
         "emissiveFactor": [0.1, 0.0, 0.0]},
        {"name": "enamel", "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 0.9, 1.0]}}]
    b.doc["extensionsUsed"] = ["KHR_materials_emissive_strength"]
    head = _part(rng, 40, len(HEAD_NAMES), [0, 1.7, 0])
    teeth = _part(rng, 12, 1, [0, 0.0, 0.05])
    eyes = _part(rng, 10, 1, [0, 0.05, 0.08])
    joints = np.zeros((40, 4), np.uint8)
    joints[:, 0] = np.where(head[0][:, 1] > 1.7, 2, 1)
    m_head = _mesh(b, *head, HEAD_NAMES, material=0, rng=rng, skin_joints=joints if skinned else None,
                   defaults=HEAD_DEFAULTS, morph_normals=morph_normals)
    m_teeth = _mesh(b, *teeth, TEETH_NAMES, material=1, rng=rng)
    m_eyes = _mesh(b, *eyes, EYES_NAMES, material=1, rng=rng)
    for m, name in zip((m_head, m_teeth, m_eyes), ("head", "teeth", "eyes"), strict=True):
        b.doc["meshes"][m]["name"] = name
    q = [0.0, np.sin(0.1), 0.0, np.cos(0.1)]
    b.doc["nodes"] = [
        {"name": "Armature", "translation": [0.0, 0.1, 0.0], "children": [1, 4]},               # 0
        {"name": "Hips", "children": [2]},                                                      # 1
        {"name": "Neck", "translation": [0.0, 1.5, 0.0], "children": [3]},                      # 2
        {"name": head_joint_name, "translation": [0.0, 0.1, 0.0], "rotation": q, "children": [5, 6]},  # 3
        {"name": "HeadMesh", "mesh": m_head},                                                   # 4
        {"name": "Teeth", "mesh": m_teeth, "translation": [0.0, 0.05, 0.0]},                    # 5
        {"name": "Eyes", "mesh": m_eyes},                                                       # 6
        {"name": "Camera", "camera": 0, "translation": [0.0, 1.7, 2.0]},                        # 7
    ]
    if skinned:
        b.doc["nodes"][4]["skin"] = 0
        world = _world_matrices(b.doc["nodes"])
        ibm = np.stack([np.linalg.inv(world[j]).T.reshape(-1) for j in (1, 2, 3)]).astype(np.float32)
        b.doc["skins"] = [{"joints": [1, 2, 3], "skeleton": 1, "inverseBindMatrices": b.accessor(ibm, target=None)}]
    b.doc["cameras"] = [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.01}}]
    b.doc["scenes"] = [{"name": "Scene", "nodes": [0, 7]}]
    b.doc["scene"] = 0
    t = b.accessor(_f32([0.0, 1.0]), target=None, min_max=True)
    r = b.accessor(_f32([[0, 0, 0, 1], [0, np.sin(0.2), 0, np.cos(0.2)]]), target=None)
    b.doc["animations"] = [{"name": "idle", "samplers": [{"input": t, "output": r}],
                            "channels": [{"sampler": 0, "target": {"node": 7, "path": "rotation"}}]}]
    return {"glb": b.glb(), "parts": {"head": head, "teeth": teeth, "eyes": eyes}, "head_joint": 3}


def _world_matrices(nodes) -> dict[int, np.ndarray]:
    from scipy.spatial.transform import Rotation

    parents = {c: i for i, n in enumerate(nodes) for c in n.get("children", [])}

    def local(n):
        m = np.eye(4)
        m[:3, :3] = Rotation.from_quat(n.get("rotation", [0, 0, 0, 1])).as_matrix()
        m[:3, 3] = n.get("translation", [0, 0, 0])
        return m

    out = {}
    for i in range(len(nodes)):
        m, j = np.eye(4), i
        while j is not None:
            m = local(nodes[j]) @ m
            j = parents.get(j)
        out[i] = m
    return out


def world_matrices(glb_doc: dict) -> dict[int, np.ndarray]:
    """World matrix of every node of a glTF dict (TRS nodes only)."""
    return _world_matrices(glb_doc["nodes"])
