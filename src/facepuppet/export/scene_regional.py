"""A regional animation in the character's own scene: its morph targets split by region, added to its meshes.

The regional blend T = T_B + Σ_k Σ_i M_k ⊙ w_ik (T_i − T_B) (docs/mapping.md) is linear in the key-models, so a
glTF player plays it with one morph target per region k and key-model i: M_k ⊙ δ_i, where δ_i is the
key-model's delta on the mesh (Σ factor · target delta over the targets it binds there,
:func:`facepuppet.io.keymodels.keymodel_binds`) and M_k the region's mask on the mesh's vertices. Each mesh
that a paired key-model moves gets these targets appended after its own, for every attribute its targets
carry (POSITION, and NORMAL, TANGENT, ... where they do, since a player takes a missing attribute as the base
value), on every primitive, named ``"<region>/<key-model>"`` in ``extras.targetNames``, default weight 0. A
target that is zero on most vertices is stored as a sparse accessor (glTF 2.0 §3.6.2.3).

The masks are over the character's vertices as :func:`facepuppet.io.gltf.read_gltf` joined them (every mesh
with morph targets, the scene's nodes depth first); a mesh shown by several nodes takes the masks of its first.
The mesh's own targets of the paired key-models are then driven to zero, so only the split ones play.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from facepuppet.io.glb import BufferParts
from facepuppet.io.gltf import morph_mesh_vertices, morph_target_arrays
from facepuppet.io.keymodels import Bind, keymodel_binds, morph_names

__all__ = ["scene_vertex_count", "add_regional_targets"]

_TYPES = {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4"}


def scene_vertex_count(source: bytes) -> int:
    """How many vertices :func:`facepuppet.io.gltf.read_gltf` joins from the scene ``source`` (GLB bytes)."""
    return sum(sum(counts) for _, counts in morph_mesh_vertices(source))


def add_regional_targets(doc: dict, parts: BufferParts, source: bytes, names: Sequence[str],
                         region_names: Sequence[str], masks: np.ndarray) -> dict[str, list[Bind]]:
    """Append the split targets (module notes) to ``doc``'s meshes and their data to ``parts``.

    Parameters
    ----------
    doc : dict
        The scene's glTF JSON, changed in place.
    parts : BufferParts
        Buffer 0 of the scene; the targets' data are appended.
    source : bytes
        The scene as it was read (GLB), whose targets are split.
    names : sequence of M str
        The paired key-models.
    region_names : sequence of R str
    masks : (R, V) float
        Region masks over the scene's :func:`scene_vertex_count` vertices.

    Returns
    -------
    dict
        Channel name ``"<region>/<key-model>"`` (R·M of them, region-major) -> its binds ``(mesh, target,
        factor)``; the first region's also bind the key-model's own targets with factor 0.
    """
    masks = np.asarray(masks, dtype=np.float64)
    layout = morph_mesh_vertices(source)
    spans: dict[int, list[tuple[int, int]]] = {}
    at = 0
    for mesh, counts in layout:
        mine = []
        for c in counts:
            mine.append((at, at + c))
            at += c
        spans.setdefault(mesh, mine)
    if masks.ndim != 2 or masks.shape != (len(region_names), at):
        raise ValueError(f"region masks must be ({len(region_names)}, {at}) for this scene, got {masks.shape}")
    binds = keymodel_binds(doc)
    channels: dict[str, list[Bind]] = {f"{r}/{n}": [] for r in region_names for n in names}
    for name in names:
        channels[f"{region_names[0]}/{name}"] += [(m, j, 0.0) for m, j, _ in binds[name]]
    for mesh in sorted({m for n in names for m, _, _ in binds[n]} & set(spans)):
        movers = [n for n in names if any(m == mesh for m, _, _ in binds[n])]
        old = morph_names(doc, mesh)
        arrays = morph_target_arrays(source, mesh)
        for prim, (a, b), attrs in zip(doc["meshes"][mesh]["primitives"], spans[mesh], arrays, strict=True):
            targets = prim.setdefault("targets", [])
            moved = {n: {attr: sum(f * deltas[j] for m, j, f in binds[n] if m == mesh)
                         for attr, deltas in attrs.items()} for n in movers}     # δ_i on this primitive
            for k in range(len(region_names)):
                for n in movers:
                    targets.append({attr: _accessor(doc, parts, masks[k, a:b, None] * d)
                                    for attr, d in moved[n].items()})
        new = [f"{r}/{n}" for r in region_names for n in movers]
        for j, channel in enumerate(new):
            channels[channel].append((mesh, len(old) + j, 1.0))
        _name_targets(doc["meshes"][mesh], old + new)
    return channels


def _name_targets(mesh: dict, names: list[str]) -> None:
    """Set the mesh's target names (and its default weights, the new ones 0) to cover ``names``."""
    n_old = len(mesh.get("weights") or [])
    if n_old:
        mesh["weights"] = list(mesh["weights"]) + [0.0] * (len(names) - n_old)
    mesh.setdefault("extras", {})
    if not isinstance(mesh["extras"], dict):
        mesh["extras"] = {}
    mesh["extras"]["targetNames"] = list(names)
    for prim in mesh.get("primitives") or []:
        extras = prim.get("extras")
        if isinstance(extras, dict) and isinstance(extras.get("targetNames"), list):
            extras["targetNames"] = list(names)


def _view(doc: dict, parts: BufferParts, data: bytes) -> int:
    parts.align()
    doc.setdefault("bufferViews", []).append({"buffer": 0, "byteOffset": parts.append(data),
                                              "byteLength": len(data)})
    return len(doc["bufferViews"]) - 1


def _accessor(doc: dict, parts: BufferParts, values: np.ndarray) -> int:
    """A float32 accessor of ``values`` (n, k): sparse when that is smaller (zeros elsewhere), with min / max."""
    values = np.asarray(values, dtype=np.float32)
    n, k = values.shape
    acc: dict = {"componentType": 5126, "count": int(n), "type": _TYPES[k],
                 "min": [float(x) for x in values.min(axis=0)] if n else [0.0] * k,
                 "max": [float(x) for x in values.max(axis=0)] if n else [0.0] * k}
    rows = np.flatnonzero(np.any(values != 0, axis=1))
    if len(rows) * (4 + 4 * k) < n * 4 * k:
        if len(rows):
            acc["sparse"] = {"count": int(len(rows)),
                             "indices": {"bufferView": _view(doc, parts, rows.astype("<u4").tobytes()),
                                         "componentType": 5125},
                             "values": {"bufferView": _view(doc, parts, values[rows].astype("<f4").tobytes())}}
    else:
        acc["bufferView"] = _view(doc, parts, values.astype("<f4").tobytes())
    doc.setdefault("accessors", []).append(acc)
    return len(doc["accessors"]) - 1
