"""Characters in glTF 2.0 (.gltf, .glb): a mesh with morph targets is a neutral mesh plus key-models.

Reading keeps the file's vertex order exactly: the primitives of a mesh are concatenated in order, and nothing
is merged or split. Accessors are decoded here with numpy (float, normalised and plain integer components,
strided buffer views, sparse accessors with or without a base buffer view); pygltflib parses the container.
Each mesh is placed in scene space by its node's world matrix (the chain of parent matrices / TRS), so the
neutral and key-models are what a viewer shows (a skinned mesh in its bind pose, as the spec places it).
Key-model names come from the mesh's ``extras.targetNames`` (or a primitive's), else ``target_<i>``.

Writing stores the neutral as POSITION and each key-model as a morph target of deltas T_i - T_B, so glTF's own
morphing, base + Σ w_i δ_i, is the paper's Eq. 14.
"""

from __future__ import annotations

import base64
import dataclasses
import logging
import os
from pathlib import Path

import numpy as np

from facepuppet.errors import FacepuppetError
from facepuppet.io.character_type import Character
from facepuppet.io.external import read_external
from facepuppet.io.glb import ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER, GltfBuilder, vertex_normals
from facepuppet.io.keymodels import keymodel_binds, morph_names
from facepuppet.io.scene import load_scene

__all__ = ["read_gltf", "write_glb", "add_character", "colored_glb", "quaternion_matrix", "morph_mesh_vertices",
           "morph_target_arrays"]

log = logging.getLogger(__name__)

_DTYPE = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
#: Divisor of normalised integer components (glTF 2.0 §3.11: signed values clamp at -1).
_NORM = {5120: 127.0, 5121: 255.0, 5122: 32767.0, 5123: 65535.0, 5125: 4294967295.0}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}
#: Most items one accessor may hold (vertices, indices): a bound on what a damaged file can ask to allocate.
_MAX_COUNT = 50_000_000


def read_gltf(path: str | os.PathLike, *, mesh: str | int | None = None) -> Character:
    """Read a character from a .gltf or .glb file.

    Parameters
    ----------
    path : str or PathLike
        A .gltf (external or data-URI buffers) or .glb file.
    mesh : str or int, optional
        Which mesh to read, by name or index. By default every mesh with morph targets that the scene
        places is read and concatenated in node order; key-models with the same name are joined, and a
        mesh that lacks one contributes zero deltas to it.

    Returns
    -------
    Character
        Neutral (V, 3), targets (M, V, 3) as absolute positions in scene space, names, faces (T, 3) or None.
    """
    path = Path(path)
    if not path.is_file():
        raise FacepuppetError(f"{path}: no such file")
    scene = load_scene(path)  # one embedded buffer, compression decoded (io/scene.py)
    gltf = _parsed(scene.glb(), str(path))
    if gltf is None:
        raise FacepuppetError(f"{path}: not a glTF or GLB file")
    reader = _Reader(gltf, path)
    if not gltf.meshes:
        raise FacepuppetError(f"{path}: no mesh in the file")
    try:
        try:
            instances = _mesh_instances(gltf)
        except ValueError as e:                                       # a node transform no scene can have
            raise FacepuppetError(f"{path}: damaged glTF ({e})") from e
        if mesh is not None:
            index = _find_mesh(gltf, mesh, path)
            chosen = [(m, mat) for m, mat in instances if m == index] or [(index, np.eye(4))]
        else:
            chosen = [(m, mat) for m, mat in instances if any(p.targets for p in gltf.meshes[m].primitives)]
            if not chosen:
                raise FacepuppetError(f"{path}: no mesh has morph targets (key-models)")
        parts = [reader.mesh(m, mat) for m, mat in chosen]
        if mesh is None:
            parts = _with_expressions(scene.doc, [m for m, _ in chosen], parts)
        character = _join(parts, name=_character_name(gltf, chosen, path), path=path)
    except (IndexError, KeyError, TypeError, AttributeError) as e:   # an index to nothing, a missing field
        raise FacepuppetError(f"{path}: damaged glTF ({type(e).__name__}: {e}; an index points at nothing "
                              f"or a required field is missing)") from e
    return dataclasses.replace(character, source=scene.glb())


def _parsed(source: bytes, label: str):
    import pygltflib

    try:
        gltf = pygltflib.GLTF2.load_from_bytes(source)
    except Exception as e:  # pygltflib raises a mix of json, struct and key errors
        raise FacepuppetError(f"{label}: cannot read glTF ({type(e).__name__}: {e})") from e
    return gltf


def morph_mesh_vertices(source: bytes, label: str = "character scene") -> list[tuple[int, tuple[int, ...]]]:
    """Where :func:`read_gltf` (every mesh, the default) takes a character's vertices from.

    Parameters
    ----------
    source : bytes
        The scene as one self-contained GLB (:attr:`Character.source`).
    label : str
        Names the scene in errors.

    Returns
    -------
    list of (mesh index, vertex counts of its primitives)
        One entry per node showing a mesh with morph targets, in the reader's order (the scene's nodes depth
        first): the character's vertices are these primitives' vertices one after another. A mesh shown by
        two nodes appears twice.
    """
    gltf = _parsed(source, label)
    try:
        out = []
        for m, _ in _mesh_instances(gltf):
            prims = gltf.meshes[m].primitives
            if any(p.targets for p in prims):
                out.append((m, tuple(int(gltf.accessors[p.attributes.POSITION].count) for p in prims)))
    except (ValueError, IndexError, KeyError, TypeError, AttributeError) as e:
        raise FacepuppetError(f"{label}: damaged glTF ({type(e).__name__}: {e})") from e
    return out


def morph_target_arrays(source: bytes, mesh: int, label: str = "character scene") -> list[dict[str, np.ndarray]]:
    """The morph targets of mesh ``mesh``, decoded: for each primitive, attribute name -> (T, n, k) float64
    deltas of its T targets on its n vertices, for every attribute any of its targets has (zeros in a target
    that lacks it), in the mesh's own coordinates."""
    gltf = _parsed(source, label)
    reader = _Reader(gltf, Path(label))
    out = []
    try:
        for prim in gltf.meshes[mesh].primitives:
            n = int(gltf.accessors[prim.attributes.POSITION].count)
            targets = [t if isinstance(t, dict) else vars(t) for t in (prim.targets or [])]
            attrs = sorted({a for t in targets for a, v in t.items() if v is not None})
            arrays = {}
            for a in attrs:
                decoded = [reader.accessor(t[a]) if t.get(a) is not None else None for t in targets]
                k = next(d.shape[1] for d in decoded if d is not None)
                stack = np.zeros((len(targets), n, k))
                for j, d in enumerate(decoded):
                    if d is not None:
                        if d.shape != (n, k):
                            raise FacepuppetError(f"{label}: mesh {mesh} morph target {j} {a} has shape "
                                                  f"{d.shape}, the primitive ({n}, {k})")
                        stack[j] = d
                arrays[a] = stack
            out.append(arrays)
    except (IndexError, KeyError, TypeError, AttributeError) as e:
        raise FacepuppetError(f"{label}: damaged glTF ({type(e).__name__}: {e})") from e
    return out


def _with_expressions(doc: dict, meshes: list[int], parts: list) -> list:
    """Add the asset's VRM expressions (io/keymodels.py) to the parts as key-models: Σ factor · delta."""
    targets = {n for m in range(len(doc.get("meshes") or [])) for n in morph_names(doc, m)}
    expressions = {k: b for k, b in keymodel_binds(doc).items() if k not in targets}
    if not expressions:
        return parts
    out = []
    for m, (pos, d, names, faces) in zip(meshes, parts, strict=True):
        extra = np.zeros((len(expressions),) + pos.shape)
        for e, binds in enumerate(expressions.values()):
            for mesh, j, factor in binds:
                if mesh == m:
                    extra[e] += factor * d[j]
        out.append((pos, np.concatenate([d, extra]), list(names) + list(expressions), faces))
    return out


def write_glb(path: str | os.PathLike, character: Character, *, normals: bool = False) -> None:
    """Write ``character`` as GLB (or as .gltf with an embedded buffer when ``path`` ends in .gltf).

    Parameters
    ----------
    path : str or PathLike
        Output file; written atomically.
    character : Character
    normals : bool
        Also store vertex normals of the neutral (needs faces).
    """
    builder = GltfBuilder()
    node = add_character(builder, character, normals=normals)
    builder.json["scenes"] = [{"nodes": [node]}]
    builder.json["scene"] = 0
    builder.write(path)


def add_character(builder: GltfBuilder, character: Character, *, normals: bool = False) -> int:
    """Add the character's mesh and a node holding it to ``builder``; return the node index."""
    neutral = np.asarray(character.neutral, dtype=np.float32)
    if not np.all(np.isfinite(neutral)) or not np.all(np.isfinite(character.targets)):
        raise ValueError(f"character {character.name!r} has non-finite vertex positions")
    attributes = {"POSITION": builder.add_accessor(neutral, target=ARRAY_BUFFER, min_max=True)}
    primitive: dict = {"attributes": attributes, "mode": 4}
    if character.faces is not None and len(character.faces):
        faces = np.asarray(character.faces)
        if faces.min() < 0 or faces.max() >= len(neutral):
            raise ValueError(f"character {character.name!r} has face indices outside 0..{len(neutral) - 1}")
        index_type = np.uint16 if len(neutral) < 65535 else np.uint32
        primitive["indices"] = builder.add_accessor(faces.astype(index_type).reshape(-1),
                                                    target=ELEMENT_ARRAY_BUFFER)
        if normals:
            attributes["NORMAL"] = builder.add_accessor(vertex_normals(neutral, faces), target=ARRAY_BUFFER)
    elif normals:
        raise ValueError("normals need the character's faces")
    deltas = (np.asarray(character.targets, dtype=np.float64)
              - np.asarray(character.neutral, dtype=np.float64)[None]).astype(np.float32)
    primitive["targets"] = [{"POSITION": builder.add_accessor(d, target=ARRAY_BUFFER, min_max=True)}
                            for d in deltas]
    mesh: dict = {"name": character.name, "primitives": [primitive]}
    if len(deltas):
        mesh["weights"] = [0.0] * len(deltas)
        mesh["extras"] = {"targetNames": list(character.names)}
    else:
        del primitive["targets"]
    return builder.add_node({"name": character.name, "mesh": builder.add_mesh(mesh)})


def colored_glb(character: Character, colors: np.ndarray) -> bytes:
    """GLB bytes of ``character`` with normals, vertex colours ``colors`` (V, 3) in [0, 1] (``COLOR_0``) under
    one white, rough, non-metallic material, so a viewer shows the colours; morph targets as in
    :func:`write_glb`."""
    builder = GltfBuilder()
    node = add_character(builder, character, normals=True)
    prim = builder.json["meshes"][builder.json["nodes"][node]["mesh"]]["primitives"][0]
    colors = np.asarray(colors, dtype=np.float32)
    if colors.shape != (len(character.neutral), 3):
        raise ValueError(f"colors must have shape ({len(character.neutral)}, 3), got {colors.shape}")
    prim["attributes"]["COLOR_0"] = builder.add_accessor(np.clip(colors, 0, 1), target=ARRAY_BUFFER)
    builder.json["materials"] = [{"name": f"{character.name} (vertex colours)", "pbrMetallicRoughness": {
        "baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.7}}]
    prim["material"] = 0
    builder.json["scenes"] = [{"name": character.name, "nodes": [node]}]
    builder.json["scene"] = 0
    return builder.glb_bytes()


# --------------------------------------------------------------------------------------------------- reading


class _Reader:
    """Decodes buffers and accessors of one loaded asset."""

    def __init__(self, gltf, path: Path) -> None:
        self.gltf, self.path = gltf, path
        self._buffers: dict[int, bytes] = {}

    def buffer(self, index: int) -> bytes:
        if index not in self._buffers:
            buf = self.gltf.buffers[index]
            if buf.uri is None:
                data = self.gltf.binary_blob()
                if data is None:
                    raise FacepuppetError(f"{self.path}: buffer {index} has no data (no GLB BIN chunk)")
            elif buf.uri.startswith("data:"):
                try:
                    data = base64.b64decode(buf.uri.split(",", 1)[1])
                except (IndexError, ValueError) as e:
                    raise FacepuppetError(f"{self.path}: buffer {index} has a bad data URI") from e
            else:
                data = read_external(self.path, buf.uri, buf.byteLength, f"buffer {index}")
            if len(data) < buf.byteLength:
                raise FacepuppetError(f"{self.path}: buffer {index} holds {len(data)} bytes, "
                                      f"needs {buf.byteLength}")
            self._buffers[index] = data
        return self._buffers[index]

    def _view(self, view_index: int, offset: int, count: int, dtype, width: int, stride: int | None = None):
        view = self.gltf.bufferViews[_index(view_index, self.gltf.bufferViews, "buffer view", self.path)]
        data = self.buffer(_index(view.buffer, self.gltf.buffers, "buffer", self.path))
        start = (view.byteOffset or 0) + offset
        item = np.dtype(dtype).itemsize * width
        stride = stride or view.byteStride or item
        if start < 0 or count < 0 or stride <= 0 or offset < 0:
            raise FacepuppetError(f"{self.path}: buffer view {view_index} has a negative offset, count or stride")
        end = start + (count - 1) * stride + item if count else start
        if end > (view.byteOffset or 0) + view.byteLength or end > len(data):
            raise FacepuppetError(f"{self.path}: accessor data runs past buffer view {view_index}")
        raw = np.ndarray((count, width), dtype=np.dtype(dtype).newbyteorder("<"), buffer=data, offset=start,
                         strides=(stride, np.dtype(dtype).itemsize))
        return raw.copy()

    def accessor(self, index: int) -> np.ndarray:
        """Decode accessor ``index`` to an (N, k) array: float64 for float/normalised data, else int64."""
        acc = self.gltf.accessors[_index(index, self.gltf.accessors, "accessor", self.path)]
        if not isinstance(acc.count, int) or not 0 <= acc.count <= _MAX_COUNT:
            raise FacepuppetError(f"{self.path}: accessor {index} has count {acc.count!r} (0 to {_MAX_COUNT})")
        if acc.componentType not in _DTYPE or acc.type not in _WIDTH:
            raise FacepuppetError(f"{self.path}: accessor {index} has unsupported type "
                                  f"{acc.type}/{acc.componentType}")
        dtype, width = _DTYPE[acc.componentType], _WIDTH[acc.type]
        if acc.bufferView is not None:
            out = self._view(acc.bufferView, acc.byteOffset or 0, acc.count, dtype, width)
        else:
            out = np.zeros((acc.count, width), dtype=dtype)
        if acc.sparse is not None and acc.sparse.count:
            sp = acc.sparse
            idx_type = np.dtype(_DTYPE[sp.indices.componentType])
            idx = self._view(sp.indices.bufferView, sp.indices.byteOffset or 0, sp.count, idx_type, 1,
                             stride=idx_type.itemsize)[:, 0].astype(np.int64)
            if idx.size and (idx.min() < 0 or idx.max() >= acc.count):
                raise FacepuppetError(f"{self.path}: sparse accessor {index} indexes past its {acc.count} items")
            out[idx] = self._view(sp.values.bufferView, sp.values.byteOffset or 0, sp.count, dtype, width,
                                  stride=np.dtype(dtype).itemsize * width)
        if acc.componentType == 5126:
            return out.astype(np.float64)
        if acc.normalized:
            return np.maximum(out.astype(np.float64) / _NORM[acc.componentType], -1.0)
        return out.astype(np.int64)

    def mesh(self, index: int, matrix: np.ndarray):
        """Positions (V, 3), deltas (M, V, 3), names, faces (T, 3) or None of mesh ``index`` in scene space."""
        m = self.gltf.meshes[index]
        label = f"{self.path}: mesh {m.name or index}"
        positions, deltas, faces, names, offset = [], [], [], None, 0
        n_targets = len(m.primitives[0].targets or []) if m.primitives else 0
        for p_index, prim in enumerate(m.primitives):
            if prim.attributes.POSITION is None:
                raise FacepuppetError(f"{label} primitive {p_index} has no POSITION")
            pos = self.accessor(prim.attributes.POSITION).astype(np.float64)
            if pos.shape[1] != 3:
                raise FacepuppetError(f"{label} primitive {p_index}: POSITION is not VEC3")
            targets = prim.targets or []
            if len(targets) != n_targets:
                raise FacepuppetError(f"{label}: primitive {p_index} has {len(targets)} morph targets, "
                                      f"primitive 0 has {n_targets}")
            d = np.zeros((n_targets, len(pos), 3))
            for t, target in enumerate(targets):
                t_pos = target.get("POSITION") if isinstance(target, dict) else target.POSITION
                if t_pos is None:
                    continue
                delta = self.accessor(t_pos)
                if delta.shape != pos.shape:
                    raise FacepuppetError(f"{label} primitive {p_index}: morph target {t} has {len(delta)} "
                                          f"vertices, the mesh has {len(pos)}")
                d[t] = delta
            faces_p = self._faces(prim, len(pos), label, p_index)
            if faces_p is not None:
                faces.append(faces_p + offset)
            positions.append(pos)
            deltas.append(d)
            offset += len(pos)
            names = names or _target_names(prim.extras)
        if n_targets == 0:
            raise FacepuppetError(f"{label} has no morph targets (key-models)")
        names = _target_names(m.extras) or names or [f"target_{i}" for i in range(n_targets)]
        if len(names) != n_targets:
            raise FacepuppetError(f"{label}: extras.targetNames lists {len(names)} names for {n_targets} "
                                  f"morph targets")
        pos = np.concatenate(positions)
        d = np.concatenate(deltas, axis=1)
        linear, shift = matrix[:3, :3], matrix[:3, 3]
        pos = pos @ linear.T + shift
        d = d @ linear.T
        return pos, d, list(names), (np.concatenate(faces) if faces else None)

    def _faces(self, prim, n_vertices: int, label: str, p_index: int) -> np.ndarray | None:
        mode = 4 if prim.mode is None else prim.mode
        if mode not in (4, 5, 6):
            return None  # points and lines have no faces
        if prim.indices is not None:
            idx = self.accessor(prim.indices)[:, 0]
        else:
            idx = np.arange(n_vertices)
        if idx.size and (idx.min() < 0 or idx.max() >= n_vertices):
            raise FacepuppetError(f"{label} primitive {p_index}: indices past its {n_vertices} vertices")
        if mode == 4:
            return idx[: len(idx) // 3 * 3].reshape(-1, 3)
        k = np.arange(len(idx) - 2)
        if mode == 6:  # fan
            return np.stack([np.full_like(k, idx[0]), idx[k + 1], idx[k + 2]], axis=1)
        tri = np.stack([idx[k], idx[k + 1], idx[k + 2]], axis=1)  # strip: flip every other triangle
        tri[1::2, [1, 2]] = tri[1::2, [2, 1]]
        return tri


def _index(i, items, what: str, path: Path) -> int:
    """``i`` if it indexes ``items`` (a glTF array), else FacepuppetError naming the file."""
    if not isinstance(i, int) or isinstance(i, bool) or not 0 <= i < len(items or ()):
        raise FacepuppetError(f"{path}: {what} {i!r} does not exist (the file has {len(items or ())})")
    return i


def _target_names(extras) -> list[str] | None:
    if isinstance(extras, dict) and isinstance(extras.get("targetNames"), list):
        return [str(n) for n in extras["targetNames"]]
    return None


def _find_mesh(gltf, mesh: str | int, path: Path) -> int:
    if isinstance(mesh, int):
        if not 0 <= mesh < len(gltf.meshes):
            raise ValueError(f"mesh index {mesh} out of range: {path} has {len(gltf.meshes)} meshes")
        return mesh
    names = [m.name for m in gltf.meshes]
    if mesh not in names:
        raise ValueError(f"no mesh named {mesh!r} in {path}; it has {', '.join(map(str, names))}")
    return names.index(mesh)


def _node_matrix(node) -> np.ndarray:
    if node.matrix is not None and len(node.matrix) == 16:
        return np.asarray(node.matrix, dtype=np.float64).reshape(4, 4).T  # stored column-major
    t = np.eye(4)
    if node.translation is not None:
        t[:3, 3] = node.translation
    r = np.eye(4)
    if node.rotation is not None:
        r[:3, :3] = quaternion_matrix(node.rotation)
    s = np.eye(4)
    if node.scale is not None:
        s[:3, :3] = np.diag(node.scale)
    return t @ r @ s


def quaternion_matrix(q) -> np.ndarray:
    """(3, 3) rotation of a glTF quaternion (x, y, z, w), normalised first; ValueError for a quaternion of zero
    or non-finite length (no rotation)."""
    q = np.asarray(q, dtype=np.float64)
    norm = float(np.linalg.norm(q)) if q.shape == (4,) else 0.0
    if not (np.isfinite(norm) and norm > 0):
        raise ValueError(f"rotation {q.tolist()} is not a quaternion of finite, non-zero length")
    x, y, z, w = q / norm
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _mesh_instances(gltf) -> list[tuple[int, np.ndarray]]:
    """(mesh index, world matrix) of every node with a mesh, depth first from the scene's roots."""
    nodes = gltf.nodes or []
    if gltf.scenes:
        roots = gltf.scenes[gltf.scene or 0].nodes or []
    else:
        children = {c for n in nodes for c in (n.children or [])}
        roots = [i for i in range(len(nodes)) if i not in children]
    out, stack, seen = [], [(r, np.eye(4)) for r in reversed(roots)], set()
    while stack:
        i, parent = stack.pop()
        if i in seen or not 0 <= i < len(nodes):
            continue
        seen.add(i)
        world = parent @ _node_matrix(nodes[i])
        if nodes[i].mesh is not None:
            # a skinned mesh ignores its node's transform (glTF 2.0 §3.7.3): its bind pose is scene space
            out.append((nodes[i].mesh, np.eye(4) if nodes[i].skin is not None else world))
        stack.extend((c, world) for c in reversed(nodes[i].children or []))
    if not nodes:
        out = [(i, np.eye(4)) for i in range(len(gltf.meshes or []))]
    return out


def _character_name(gltf, chosen, path: Path) -> str:
    names = [gltf.meshes[m].name for m, _ in chosen]
    return names[0] if len(chosen) == 1 and names[0] else path.stem


def _join(parts, *, name: str, path: Path) -> Character:
    """Concatenate mesh parts; key-models are joined by name in first-seen order."""
    if len(parts) == 1:
        pos, d, names, faces = parts[0]
    else:
        log.info("%s: joining %d meshes with morph targets", path, len(parts))
        names = list(dict.fromkeys(n for part in parts for n in part[2]))
        pos = np.concatenate([p[0] for p in parts])
        d = np.zeros((len(names), len(pos), 3))
        faces, offset = [], 0
        for p_pos, p_d, p_names, p_faces in parts:
            for j, n in enumerate(p_names):
                d[names.index(n), offset:offset + len(p_pos)] = p_d[j]
            if p_faces is not None:
                faces.append(p_faces + offset)
            offset += len(p_pos)
        faces = np.concatenate(faces) if faces else None
    if len(set(names)) != len(names):
        dup = sorted({n for n in names if names.count(n) > 1})
        raise FacepuppetError(f"{path}: morph target names repeat: {', '.join(dup)}")
    return Character(neutral=pos, targets=pos[None] + d, names=tuple(names), faces=faces, name=name)
