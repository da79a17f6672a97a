"""The animated character as one GLB: key-models as morph targets, one animation of their weights.

The morph targets are T_i - T_B, so a glTF viewer's own morphing, T_B + Σ w_i (T_i - T_B), is the paper's
Eq. 14. The animation has one key per video frame (time = frame / fps seconds, LINEAR interpolation): a
``weights`` channel whose output holds F × M values, frame after frame, and, when a head rotation is given, a
``rotation`` channel of unit quaternions on a parent node whose origin is the rotation's pivot.

Rotations are in the character's frame (glTF: y up, the face looking along +z, right-handed), as rotations
applied to the rest pose. A frame with non-finite weights is written as neutral (all zero) and one with a
non-finite rotation as the rest pose; smoothing and the hold of lost frames happen before this.
"""

from __future__ import annotations

import os

import numpy as np

from facepuppet import __version__
from facepuppet.export.take import TakeRows, as_take
from facepuppet.io.character import Character
from facepuppet.io.glb import GltfBuilder
from facepuppet.io.gltf import add_character

__all__ = ["write_animated_glb", "rotation_quaternions"]


def write_animated_glb(path: str | os.PathLike, character: Character, weights: np.ndarray | TakeRows, fps: float, *,
                       head_rotation: np.ndarray | None = None, pivot: np.ndarray | None = None,
                       normals: bool = False, name: str = "performance", times: np.ndarray | None = None) -> None:
    """Write ``character`` with one animation of its morph weights (and head rotation) as a GLB, atomically.

    Parameters
    ----------
    path : str or PathLike
        Output .glb file.
    character : Character
        Its M key-models become the morph targets, in order.
    weights : (F, M) float, or TakeRows
        Morph weights per frame; or the whole take as :class:`~facepuppet.export.take.TakeRows` (weights,
        times and head rotations read chunk by chunk as the file is written: memory flat in the take's length;
        ``head_rotation`` and ``times`` are then not given).
    fps : float
        Frames per second of the source video; frame f is keyed at f / fps seconds.
    head_rotation : (F, 3, 3) float, optional
        Head rotation per frame in the character's frame (see the module notes).
    pivot : (3,) float, optional
        The point the head turns about, in the character's coordinates; defaults to the centre of the neutral
        mesh's bounding box.
    normals : bool
        Also store vertex normals of the neutral (needs faces).
    name : str
        The animation's name.
    times : (F,) float, optional
        Each frame's time in seconds, increasing (a live recording with dropped frames); ``f / fps`` if None.
    """
    m = len(character.names)
    rows = as_take(weights, m, fps, times=times, head_rotation=head_rotation)
    if m == 0:
        raise ValueError("the character has no key-models to animate")
    f = rows.frames

    def key_times():
        for chunk in rows.times_checked():
            yield chunk.times.astype(np.float32)

    def key_weights():
        for chunk in rows.read():
            w = chunk.weights
            yield np.where(np.all(np.isfinite(w), axis=1, keepdims=True), w, 0.0).astype(np.float32).reshape(-1)

    builder = GltfBuilder(generator=f"facepuppet {__version__}")
    mesh_node = add_character(builder, character, normals=normals)
    times_acc = builder.add_streamed_accessor(f, 1, key_times, min_max=True)
    samplers = [{"input": times_acc, "interpolation": "LINEAR",
                 "output": builder.add_streamed_accessor(f * m, 1, key_weights)}]
    channels = [{"sampler": 0, "target": {"node": mesh_node, "path": "weights"}}]
    root = mesh_node
    if rows.has_rotation:
        if pivot is None:
            neutral = np.asarray(character.neutral)
            pivot = (neutral.min(axis=0) + neutral.max(axis=0)) / 2
        pivot = np.asarray(pivot, dtype=np.float64).reshape(3)
        builder.json["nodes"][mesh_node]["translation"] = [float(x) for x in -pivot]
        root = builder.add_node({"name": "head", "translation": [float(x) for x in pivot],
                                 "children": [mesh_node]})

        def key_rotations():
            previous = None
            for chunk in rows.read():
                q = rotation_quaternions(chunk.rotation, previous=previous)
                if len(q):
                    previous = q[-1]
                yield q.astype(np.float32)

        samplers.append({"input": times_acc, "interpolation": "LINEAR",
                         "output": builder.add_streamed_accessor(f, 4, key_rotations)})
        channels.append({"sampler": 1, "target": {"node": root, "path": "rotation"}})
    builder.add_animation({"name": name, "samplers": samplers, "channels": channels})
    builder.json["scenes"] = [{"name": character.name, "nodes": [root]}]
    builder.json["scene"] = 0
    builder.write(path)


def rotation_quaternions(rotation: np.ndarray, *, previous: np.ndarray | None = None) -> np.ndarray:
    """Unit quaternions (F, 4) as glTF stores them, (x, y, z, w), of rotation matrices (F, 3, 3).

    Non-finite or far-from-orthonormal matrices give the identity. Consecutive quaternions are kept in the
    same hemisphere (q and -q are the same rotation), so LINEAR interpolation turns the short way; the first
    one in the hemisphere of ``previous`` (4,), the quaternion before it, when given (a take in chunks).
    """
    r = np.asarray(rotation, dtype=np.float64)
    ok = np.all(np.isfinite(r), axis=(1, 2))
    r = np.where(ok[:, None, None], r, np.eye(3))
    ok &= np.abs(np.linalg.det(r) - 1) < 1e-3
    r = np.where(ok[:, None, None], r, np.eye(3))
    # Shepperd's method: build from the largest of the four squared components, for accuracy.
    tr = np.trace(r, axis1=1, axis2=2)
    d = np.stack([r[:, 0, 0], r[:, 1, 1], r[:, 2, 2], tr], axis=1)
    k = np.argmax(d, axis=1)
    q = np.empty((len(r), 4))
    for i in range(len(r)):
        a = r[i]
        if k[i] == 3:
            s = 2 * np.sqrt(1 + tr[i])
            q[i] = [(a[2, 1] - a[1, 2]) / s, (a[0, 2] - a[2, 0]) / s, (a[1, 0] - a[0, 1]) / s, s / 4]
        elif k[i] == 0:
            s = 2 * np.sqrt(max(1 + a[0, 0] - a[1, 1] - a[2, 2], 1e-300))
            q[i] = [s / 4, (a[0, 1] + a[1, 0]) / s, (a[0, 2] + a[2, 0]) / s, (a[2, 1] - a[1, 2]) / s]
        elif k[i] == 1:
            s = 2 * np.sqrt(max(1 + a[1, 1] - a[0, 0] - a[2, 2], 1e-300))
            q[i] = [(a[0, 1] + a[1, 0]) / s, s / 4, (a[1, 2] + a[2, 1]) / s, (a[0, 2] - a[2, 0]) / s]
        else:
            s = 2 * np.sqrt(max(1 + a[2, 2] - a[0, 0] - a[1, 1], 1e-300))
            q[i] = [(a[0, 2] + a[2, 0]) / s, (a[1, 2] + a[2, 1]) / s, s / 4, (a[1, 0] - a[0, 1]) / s]
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    if previous is not None and len(q) and np.dot(q[0], previous) < 0:
        q[0] = -q[0]
    for i in range(1, len(q)):
        if np.dot(q[i], q[i - 1]) < 0:
            q[i] = -q[i]
    return q
