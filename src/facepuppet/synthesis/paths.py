"""A character's wires as vertex paths: found from its key-models, or read from a small JSON file.

A vertex path is an ordered chain of vertex indices, consecutive ones joined by a mesh edge (when the mesh
has faces). On the neutral mesh T_B it is a reference curve R = T_B[path]; in key-model i the same indices
give that key-model's wire curve W_i = T_i[path].

File format of user wires (JSON, UTF-8)::

    {
      "format": "facepuppet-wires",          (optional; if present, exactly this)
      "version": 1,                          (optional; if present, 1)
      "wires": {                             (required: name -> vertex path, in order)
        "brow_L": [3250, 3251, 3262, 3270],
        "jaw":    [964, 963, 3714]
      }
    }

Each path holds >= 2 distinct vertex indices (0-based, into the character's vertices).
"""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components, dijkstra

from facepuppet.io.character import Character
from facepuppet.synthesis.wire import bind_points, falloff

__all__ = [
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "FindOptions",
    "check_paths",
    "find_wire_paths",
    "mesh_graph",
    "read_wire_paths",
    "write_wire_paths",
]

#: ``format`` field of a wire-paths file.
FORMAT_NAME = "facepuppet-wires"
#: ``version`` field of a wire-paths file.
FORMAT_VERSION = 1


@dataclass(frozen=True, kw_only=True)
class FindOptions:
    """Options of :func:`find_wire_paths`.

    Attributes
    ----------
    n_wires : int
        Most wires to find.
    threshold : float
        A wire's region: the vertices that its key-model moves by at least this fraction of its largest
        motion there (dimensionless, in (0, 1)).
    min_motion : float
        Stop when the largest motion not yet covered by a wire is below this fraction of the largest motion
        of all key-models (dimensionless).
    """

    n_wires: int = 12
    threshold: float = 0.5
    min_motion: float = 0.05


def mesh_graph(faces: np.ndarray, vertices: np.ndarray) -> sp.csr_matrix:
    """Symmetric sparse (V, V) matrix of the mesh's edges, weighted by their lengths.

    Parameters
    ----------
    faces : (T, 3) int
    vertices : (V, 3) float
    """
    f = np.asarray(faces, dtype=np.intp)
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    e = np.unique(np.sort(e, axis=1), axis=0)
    length = np.linalg.norm(vertices[e[:, 0]] - vertices[e[:, 1]], axis=1)
    length = np.maximum(length, 1e-12)          # coincident vertices stay joined
    n = len(vertices)
    g = sp.coo_matrix((length, (e[:, 0], e[:, 1])), shape=(n, n))
    return (g + g.T).tocsr()


def check_paths(paths: Mapping, n_vertices: int, faces: np.ndarray | None = None, *,
                where: str = "paths") -> dict[str, np.ndarray]:
    """Validate named vertex paths; return them as ``{name: (K,) int array}``.

    Parameters
    ----------
    paths : mapping of str to sequence of int
    n_vertices : int
        V.
    faces : (T, 3) int, optional
        When given, consecutive vertices of a path must share a mesh edge.
    where : str
        Prefix of the error messages (a file name, an argument name).

    Raises
    ------
    ValueError
        Naming ``where``, the wire and what is wrong.
    """
    if not isinstance(paths, Mapping) or not paths:
        raise ValueError(f"{where}: expected a non-empty mapping of wire names to vertex paths")
    edges = None
    if faces is not None:
        f = np.asarray(faces, dtype=np.intp)
        e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        edges = set(map(tuple, np.unique(e, axis=0).tolist()))
    out = {}
    for name, path in paths.items():
        label = f"{where}: wire {name!r}"
        if not isinstance(name, str) or not name:
            raise ValueError(f"{where}: wire names must be non-empty strings, got {name!r}")
        if isinstance(path, (str, bytes)) or not hasattr(path, "__len__"):
            raise ValueError(f"{label}: expected a list of vertex indices, got {type(path).__name__}")
        items = list(path)
        if len(items) < 2:
            raise ValueError(f"{label}: a path needs at least 2 vertices, got {len(items)}")
        if not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in items):
            raise ValueError(f"{label}: vertex indices must be integers")
        p = np.asarray(items, dtype=np.intp)
        bad = (p < 0) | (p >= n_vertices)
        if bad.any():
            raise ValueError(f"{label}: vertex {int(p[bad][0])} is out of range (the mesh has {n_vertices} "
                             f"vertices)")
        if len(np.unique(p)) != len(p):
            raise ValueError(f"{label}: a vertex appears twice in the path")
        if edges is not None:
            for a, b in zip(p[:-1], p[1:], strict=True):
                if (min(a, b), max(a, b)) not in edges:
                    raise ValueError(f"{label}: consecutive vertices {int(a)} and {int(b)} share no mesh edge")
        out[name] = p
    return out


def read_wire_paths(path: str | os.PathLike, character: Character | None = None) -> dict[str, np.ndarray]:
    """Read named vertex paths from a JSON file (format in the module docstring).

    Parameters
    ----------
    path : str or PathLike
    character : Character, optional
        When given, indices are checked against its vertices and (with faces) its edges.

    Returns
    -------
    dict of str to (K,) int array

    Raises
    ------
    ValueError
        One line naming the file and what is wrong.
    """
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ValueError(f"{path}: cannot read: {exc.strerror or exc}") from exc
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{path}: not a JSON file: {exc}") from exc
    if not isinstance(data, dict) or "wires" not in data:
        raise ValueError(f"{path}: expected a JSON object with a 'wires' field")
    if "format" in data and data["format"] != FORMAT_NAME:
        raise ValueError(f"{path}: format must be {FORMAT_NAME!r}, got {data['format']!r}")
    if "version" in data and data["version"] != FORMAT_VERSION:
        raise ValueError(f"{path}: version {data['version']!r} is not supported (expected {FORMAT_VERSION})")
    n = len(character.neutral) if character is not None else np.iinfo(np.intp).max
    faces = character.faces if character is not None else None
    return check_paths(data["wires"], n, faces, where=str(path))


def write_wire_paths(path: str | os.PathLike, paths: Mapping) -> None:
    """Write named vertex paths as JSON (format in the module docstring), atomically.

    Parameters
    ----------
    path : str or PathLike
    paths : mapping of str to sequence of int
    """
    path = Path(path)
    body = {"format": FORMAT_NAME, "version": FORMAT_VERSION,
            "wires": {str(k): [int(v) for v in p] for k, p in paths.items()}}
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            json.dump(body, fh, indent=1)
            fh.write("\n")
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def find_wire_paths(character: Character, options: FindOptions | None = None) -> dict[str, np.ndarray]:
    """Find wires on a character: vertex paths along what its key-models move most.

    Parameters
    ----------
    character : Character
        With faces (the paths follow mesh edges) and at least one key-model.
    options : FindOptions, optional

    Returns
    -------
    dict of str to (K,) int array
        Up to ``n_wires`` paths, named after the key-model that placed them (``jawOpen``, ``eyeBlink_L``),
        in the order found (largest motion first).

    Notes
    -----
    Greedy: with m_i(v) = ||T_i(v) - T_B(v)|| and the uncovered motion c_i(v) = m_i(v) (initially), each
    step takes the key-model i0 and vertex v0 of largest c, and the region S: the
    vertices connected to v0 through vertices with m_i0 >= threshold * m_i0(v0). The path is the shortest
    edge path inside S between S's two extreme vertices along S's principal axis (on T_B). Then each
    key-model's uncovered motion c_i is multiplied by 1 - a_i f(dist / rho) (f the wires' falloff, dist the
    distance to the path, rho the largest distance of S from it, a_i in [0, 1] the share of key-model i's
    motion near the path that the path's own vertices see: a wire covers what its curve moves with), set to
    0 on S, and key-model i0 is done; the next wire goes where motion is still uncovered.
    """
    opts = options or FindOptions()
    if character.faces is None:
        raise ValueError("character: finding wires needs the mesh's faces (triangles)")
    if not 0 < opts.threshold < 1:
        raise ValueError(f"options.threshold must be in (0, 1), got {opts.threshold}")
    base = np.asarray(character.neutral, dtype=float)
    motion = np.linalg.norm(np.asarray(character.targets, dtype=float) - base[None], axis=2)   # (M, V)
    if motion.size == 0:
        raise ValueError("character: finding wires needs at least one key-model")
    graph = mesh_graph(character.faces, base)
    uncovered = motion.copy()
    stop = opts.min_motion * motion.max()
    paths: dict[str, np.ndarray] = {}
    for _ in range(opts.n_wires):
        i0, v0 = np.unravel_index(int(np.argmax(uncovered)), uncovered.shape)
        if uncovered[i0, v0] <= stop or uncovered[i0, v0] <= 0:
            break
        region = _region(graph, motion[i0], int(v0), opts.threshold)
        path = _principal_path(graph, base, region, motion[i0])
        rho = _covered_radius(base, path, region)
        dist = _distance_to_path(base, base[path])
        local = motion[:, dist < rho].max(axis=1)
        seen = np.divide(motion[:, path].max(axis=1), local, out=np.zeros_like(local), where=local > 0)
        uncovered *= 1.0 - np.clip(seen, 0.0, 1.0)[:, None] * falloff(dist / rho)[None]
        uncovered[:, region] = 0.0
        uncovered[i0] = 0.0
        name = base_name = str(character.names[i0])
        n = 2
        while name in paths:
            name, n = f"{base_name}_{n}", n + 1
        paths[name] = path
    return paths


def _region(graph: sp.csr_matrix, motion: np.ndarray, v0: int, threshold: float) -> np.ndarray:
    """Vertices connected to v0 through vertices moved by >= threshold * motion[v0]."""
    keep = np.flatnonzero(motion >= threshold * motion[v0])
    sub = graph[keep][:, keep]
    _, label = connected_components(sub, directed=False)
    return keep[label == label[np.searchsorted(keep, v0)]]


def _principal_path(graph: sp.csr_matrix, base: np.ndarray, region: np.ndarray, motion: np.ndarray) -> np.ndarray:
    """Shortest edge path inside ``region`` between its extremes along the principal axis (>= 2 vertices)."""
    if len(region) == 1:
        row = graph[region[0]]
        nb = row.indices[np.argmax(motion[row.indices])]
        return np.array([region[0], nb], dtype=np.intp)
    x = base[region] - base[region].mean(axis=0)
    axis = np.linalg.svd(x, full_matrices=False)[2][0]
    proj = x @ axis
    a, b = int(np.argmin(proj)), int(np.argmax(proj))
    sub = graph[region][:, region]
    _, pred = dijkstra(sub, directed=False, indices=a, return_predecessors=True)
    chain = [b]
    while chain[-1] != a:
        chain.append(int(pred[chain[-1]]))
    return region[np.array(chain[::-1], dtype=np.intp)]


def _distance_to_path(points: np.ndarray, curve: np.ndarray) -> np.ndarray:
    return bind_points(points, curve).distance


def _covered_radius(base: np.ndarray, path: np.ndarray, region: np.ndarray) -> float:
    d = _distance_to_path(base[region], base[path]) if len(region) else np.zeros(1)
    seg = np.linalg.norm(np.diff(base[path], axis=0), axis=1).max()
    return float(max(d.max(), seg, 1e-9))
