"""The character's own scene, whole, with one more animation: the performance.

:func:`write_scene_animation` takes the scene a character was read from (:attr:`Character.source`, one
self-contained GLB; :mod:`facepuppet.io.scene`) and writes it back with everything it had (nodes, meshes, every
primitive attribute, materials, textures, images, samplers, skins, cameras, extensions, animations) and one
added animation; the JSON changes only by that animation, the buffer views and accessors of its keys (appended
after the existing ones) and the length of buffer 0 (the keys appended to its end). When the head turns in a
scene without a head joint, one node is added too (below).

The animation has one key per frame (LINEAR):

- a ``weights`` channel on every node whose mesh has a morph target bound to a driven key-model
  (:func:`facepuppet.io.keymodels.keymodel_binds`): target j of mesh m gets Σ_k w_k · factor over the driven
  key-models k that bind it, every other target its file's default weight (``mesh.weights``, else 0);
- the head rotation R_f (scene space, about the head's pivot), on the **head joint** when there is one: the
  VRM humanoid's ``head`` bone, else a joint of a skin whose name, lower-cased, with any ``prefix:`` or
  ``prefix|`` dropped and only letters and digits kept, is one of :data:`HEAD_JOINT_NAMES` (``Head``,
  ``mixamorig:Head``, ``J_Bip_C_Head``, ``DEF-head`` ...). Its local rotation becomes P⁻¹ R_f P L, with P the
  parent's world rotation and L the joint's rest rotation, so the head turns by R_f about the joint;
- without a head joint, on a new node ``facepuppet_head`` put in place of the faces' nodes (below their
  lowest common ancestor, which keeps its other children): rest transform identity, animated rotation and
  translation T(c) R_f T(-c) about the pivot c, in its parent's frame. Skinned meshes ignore node transforms,
  so a skinned face without a head joint keeps its rest pose (a warning is logged).
"""

from __future__ import annotations

import copy
import json
import logging
import os
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from facepuppet._util.atomic import atomic_path
from facepuppet.export.gltf_animation import rotation_quaternions
from facepuppet.export.take import TakeRows, as_take
from facepuppet.io.glb import BufferParts, write_glb_stream, write_gltf_stream
from facepuppet.io.gltf import quaternion_matrix
from facepuppet.io.keymodels import keymodel_binds, morph_names
from facepuppet.io.scene import scene_from_glb

__all__ = ["write_scene_animation", "find_head_joint", "HEAD_JOINT_NAMES"]

log = logging.getLogger(__name__)

#: Normalised names of head joints (see the module notes): Mixamo, Unity/Unreal humanoids, VRoid, Rigify,
#: Character Creator, 3ds Max Biped, and common hand-made rigs.
HEAD_JOINT_NAMES = frozenset({"head", "jbipchead", "defhead", "ccbasehead", "bip01head", "bip001head",
                              "headjnt", "headjoint", "headbone", "headj"})


def write_scene_animation(path: str | os.PathLike, source: bytes, names: Sequence[str],
                          weights: np.ndarray | TakeRows, fps: float, *, times: np.ndarray | None = None,
                          head_rotation: np.ndarray | None = None, pivot: np.ndarray | None = None,
                          name: str = "performance", regions: tuple[Sequence[str], np.ndarray] | None = None,
                          ) -> None:
    """Write the scene ``source`` with one animation of key-model weights (and head rotation), atomically.

    Parameters
    ----------
    path : str or PathLike
        Output .glb / .vrm (GLB container) or .gltf (JSON with the buffer as a data URI).
    source : bytes
        The scene as one self-contained GLB (:attr:`Character.source`).
    names : sequence of K str
        The key-models the weights drive (names :func:`keymodel_binds` knows).
    weights : (F, K) float, or TakeRows
        Weights per frame; a frame with a non-finite weight is neutral (zeros). Or the whole take as
        :class:`~facepuppet.export.take.TakeRows`, read chunk by chunk as the file is written (``times`` and
        ``head_rotation`` are then its own).
    fps : float
        Frame rate; frame f is keyed at f / fps seconds unless ``times`` is given.
    times : (F,) float, optional
        Increasing key times in seconds.
    head_rotation : (F, 3, 3) float, optional
        Head rotation per frame in scene space; a non-finite one is the rest pose.
    pivot : (3,) float, optional
        Where the head turns when there is no head joint (scene space); the origin if None.
    name : str
        The animation's name.
    regions : (region names (R,), masks (R, V)), optional
        A regional animation: the key-models ``names`` are split by region into new morph targets of the
        scene's meshes (:mod:`facepuppet.export.scene_regional`; V the vertices the reader joins), and
        ``weights`` has R·M columns, region-major (column k·M + i is w_ik).
    """
    names = list(names)
    scene = scene_from_glb(source, "character scene")
    doc, parts = copy.deepcopy(scene.doc), BufferParts(scene.blob)
    binds = keymodel_binds(doc)
    if regions is not None:
        from facepuppet.export.scene_regional import add_regional_targets

        unknown = [n for n in names if n not in binds]
        if unknown:
            raise ValueError(f"key-models not in the character's scene: {', '.join(unknown)}")
        binds = add_regional_targets(doc, parts, scene.glb(), names, *regions)
        names = list(binds)
    rows = as_take(weights, len(names), fps, times=times, head_rotation=head_rotation)
    f = rows.frames
    add = _Appender(doc, parts)

    unknown = [n for n in names if n not in binds]
    if unknown:
        raise ValueError(f"key-models not in the character's scene: {', '.join(unknown)}")
    per_mesh = _mesh_weights(doc, binds, names)

    def key_times():
        for chunk in rows.times_checked():
            yield chunk.times.astype(np.float32)

    def mesh_keys(make, n_targets):
        def chunks():
            for chunk in rows.read():
                w = chunk.weights
                w = np.where(np.all(np.isfinite(w), axis=1, keepdims=True), w, 0.0)
                yield make(w).astype(np.float32).reshape(-1)
        return add.streamed(f * n_targets, 1, chunks)

    t_acc = add.streamed(f, 1, key_times, min_max=True)
    samplers, channels = [], []
    for node_index, node in enumerate(doc.get("nodes") or []):
        if node.get("mesh") in per_mesh:
            samplers.append({"input": t_acc, "interpolation": "LINEAR", "output": mesh_keys(*per_mesh[node["mesh"]])})
            channels.append({"sampler": len(samplers) - 1, "target": {"node": node_index, "path": "weights"}})
    if not channels:
        raise ValueError("no node of the scene shows a mesh the key-models move")
    if rows.has_rotation:
        faces = sorted({c["target"]["node"] for c in channels})
        c = np.zeros(3) if pivot is None else np.asarray(pivot, dtype=np.float64).reshape(3)
        for node, path_name, width, values in _head_channels(doc, faces, c):
            def chunks(values=values):
                state: dict = {}
                for chunk in rows.read():
                    yield values(chunk.rotation, state).astype(np.float32)

            samplers.append({"input": t_acc, "interpolation": "LINEAR", "output": add.streamed(f, width, chunks)})
            channels.append({"sampler": len(samplers) - 1, "target": {"node": node, "path": path_name}})
    doc.setdefault("animations", []).append({"name": name, "samplers": samplers, "channels": channels})
    add.finish()
    path = Path(path)
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        if path.suffix.lower() == ".gltf":
            write_gltf_stream(fh, doc, doc["buffers"][0], parts, indent=1, ensure_ascii=False)
        else:
            write_glb_stream(fh, json.dumps(doc, separators=(",", ":"), ensure_ascii=False).encode("utf-8"), parts)


class _Appender:
    """Appends accessors (own 4-byte aligned buffer views) to buffer 0 of ``doc`` / ``parts``, their float32
    values streamed as the file is written."""

    def __init__(self, doc: dict, parts: BufferParts) -> None:
        self.doc, self.parts = doc, parts

    def streamed(self, count: int, k: int, chunks, *, min_max: bool = False) -> int:
        """An accessor of ``count`` float32 items of ``k`` values made by ``chunks()``; its index."""
        self.parts.align()
        nbytes = int(count) * int(k) * 4
        self.doc.setdefault("bufferViews", []).append({"buffer": 0, "byteOffset": self.parts.size,
                                                       "byteLength": nbytes})
        self.parts.append_stream(nbytes, chunks)
        acc = {"bufferView": len(self.doc["bufferViews"]) - 1, "componentType": 5126, "count": int(count),
               "type": {1: "SCALAR", 3: "VEC3", 4: "VEC4"}[k]}
        if min_max:
            low, high = np.inf, -np.inf
            for array in chunks():
                if len(array):
                    low, high = min(low, array.min()), max(high, array.max())
            acc["min"], acc["max"] = [float(low)], [float(high)]
        self.doc.setdefault("accessors", []).append(acc)
        return len(self.doc["accessors"]) - 1

    def finish(self) -> None:
        self.parts.align()
        buffers = self.doc.setdefault("buffers", [{"byteLength": 0}])
        buffers[0]["byteLength"] = self.parts.size


def _mesh_weights(doc: dict, binds: dict, names: list[str]) -> dict[int, tuple]:
    """mesh index -> (make, n targets) for meshes with a target bound to a driven key-model; ``make`` turns
    key-model weights (n, K) into the mesh's morph weights (n, n targets)."""
    driven: dict[int, set[int]] = {}
    for name in names:
        for m, j, _ in binds[name]:
            driven.setdefault(m, set()).add(j)
    out: dict[int, tuple] = {}
    for m, targets in driven.items():
        n = len(morph_names(doc, m))
        default = np.zeros(n)
        stored = doc["meshes"][m].get("weights")
        if isinstance(stored, list) and len(stored) == n:
            default = np.asarray(stored, dtype=np.float64)
        terms = [(k, j, factor) for k, name in enumerate(names) for mm, j, factor in binds[name] if mm == m]
        targets = sorted(targets)

        def make(weights, default=default, targets=targets, terms=terms):
            w = np.repeat(default[None], len(weights), axis=0)
            w[:, targets] = 0.0
            for k, j, factor in terms:
                w[:, j] += factor * weights[:, k]
            return w

        out[m] = (make, n)
    return out


def _normalised(name: str) -> str:
    return re.sub(r"[^a-z0-9]", "", re.split(r"[:|]", name.lower())[-1])


def find_head_joint(doc: dict) -> int | None:
    """Index of the head joint node (see the module notes), or None."""
    ext = doc.get("extensions") or {}
    head = ((ext.get("VRMC_vrm") or {}).get("humanoid") or {}).get("humanBones", {}).get("head", {}).get("node")
    if isinstance(head, int):
        return head
    for bone in ((ext.get("VRM") or {}).get("humanoid") or {}).get("humanBones") or []:
        if bone.get("bone") == "head" and isinstance(bone.get("node"), int):
            return bone["node"]
    nodes = doc.get("nodes") or []
    for skin in doc.get("skins") or []:
        for j in skin.get("joints") or []:
            if 0 <= j < len(nodes) and _normalised(str(nodes[j].get("name", ""))) in HEAD_JOINT_NAMES:
                return j
    return None


def _local(node: dict) -> np.ndarray:
    if node.get("matrix") is not None:
        return np.asarray(node["matrix"], dtype=np.float64).reshape(4, 4).T
    m = np.eye(4)
    m[:3, :3] = quaternion_matrix(node.get("rotation", [0, 0, 0, 1])) * np.asarray(node.get("scale", [1, 1, 1]))
    m[:3, 3] = node.get("translation", [0, 0, 0])
    return m


def _parents(doc: dict) -> dict[int, int]:
    return {c: i for i, n in enumerate(doc.get("nodes") or []) for c in n.get("children") or []}


def _world(doc: dict, index: int | None, parents: dict[int, int]) -> np.ndarray:
    m = np.eye(4)
    while index is not None:
        m = _local(doc["nodes"][index]) @ m
        index = parents.get(index)
    return m


def _rotation_part(m: np.ndarray) -> np.ndarray:
    u, _, vt = np.linalg.svd(m[:3, :3])
    return u @ vt


def _quaternions(matrices: np.ndarray, state: dict) -> np.ndarray:
    """:func:`rotation_quaternions` of one chunk, in the hemisphere of the chunk before (``state["q"]``)."""
    q = rotation_quaternions(matrices, previous=state.get("q"))
    if len(q):
        state["q"] = q[-1]
    return q


def _head_channels(doc: dict, faces: list[int], pivot: np.ndarray):
    """(node, path, width, values) channels that turn the head (see the module notes); ``values(rotation,
    state)`` gives a chunk's keys (n, width) of rotations (n, 3, 3), ``state`` a dict kept over one pass."""
    nodes, parents = doc["nodes"], _parents(doc)
    joint = find_head_joint(doc)
    if joint is not None:
        p = _rotation_part(_world(doc, parents.get(joint), parents))
        rest = _rotation_part(_local(nodes[joint]))
        if "matrix" in nodes[joint]:
            log.warning("head joint %r has a matrix, which glTF cannot animate; head rotation not written",
                        nodes[joint].get("name"))
            return []

        def joint_rotation(rotation, state):
            return _quaternions(np.einsum("ij,fjk,kl,lm->fim", p.T, rotation, p, rest), state)

        return [(joint, "rotation", 4, joint_rotation)]
    rigid = [i for i in faces if nodes[i].get("skin") is None]
    if not rigid:
        log.warning("the face is skinned and the skeleton has no head joint; head rotation not written")
        return []
    chains = []
    for i in rigid:
        chain = [i]
        while chain[-1] in parents:
            chain.append(parents[chain[-1]])
        chains.append(chain[::-1])
    depth = 0
    while all(len(c) > depth + 1 for c in chains) and len({c[depth] for c in chains}) == 1:
        depth += 1
    parent = chains[0][depth - 1] if depth else None  # the lowest common ancestor (None: the scene)
    children = list(dict.fromkeys(c[depth] for c in chains))
    siblings = nodes[parent].get("children", []) if parent is not None else \
        [r for sc in doc.get("scenes") or [] for r in sc.get("nodes") or []]
    children.sort(key=lambda c: siblings.index(c) if c in siblings else len(siblings))
    head = len(nodes)
    nodes.append({"name": "facepuppet_head", "children": children})
    if parent is None:
        for scene in doc.get("scenes") or []:
            roots = scene.get("nodes") or []
            if any(c in roots for c in children):
                at = min(roots.index(c) for c in children if c in roots)
                scene["nodes"] = [r for r in roots[:at] if r not in children] + [head] + \
                                 [r for r in roots[at:] if r not in children]
    else:
        kids = nodes[parent]["children"]
        at = min(kids.index(c) for c in children)
        nodes[parent]["children"] = [k for k in kids[:at] if k not in children] + [head] + \
                                    [k for k in kids[at:] if k not in children]
    world = _world(doc, parent, parents)
    inv = np.linalg.inv(world)

    def turned(rotation):
        finite = np.isfinite(rotation).all(axis=(1, 2))
        rotation = np.where(finite[:, None, None], rotation, np.eye(3))   # a non-finite one: the rest pose
        local = np.zeros((len(rotation), 4, 4))
        local[:, :3, :3] = rotation
        local[:, :3, 3] = pivot - rotation @ pivot
        local[:, 3, 3] = 1.0
        return inv[None] @ local @ world[None]

    def head_rotation(rotation, state):
        return _quaternions(np.stack([_rotation_part(m) for m in turned(rotation)]), state)

    def head_translation(rotation, state):
        return turned(rotation)[:, :3, 3]

    return [(head, "rotation", 4, head_rotation), (head, "translation", 3, head_translation)]
