"""The Monkey: a built-in character that is not human (the paper's Fig. 7 drives a monkey from one performance).

A head made of ellipsoid shells (fur cranium, pale face and a wide muzzle, big ears, a heavy brow ridge, eyes,
nostrils, a dark mouth slit) with the demo's 13 ARKit-named key-models (:data:`KEY_NAMES`), each a displacement
field sculpted here with its own personality: the jaw hinges down further than the Toy's (a rotation about a
hinge behind the muzzle), the smile pulls the wide muzzle's corners far out, the brows lift high on the
ridge. Units as the Toy's (the head is about 20 wide), y up, the face looking along +z.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from facepuppet.io.character_type import Character

__all__ = ["MONKEY_PARTS", "KEY_NAMES", "monkey_character", "monkey_colors"]

#: The key-models, as the demo's performer names its key expressions.
KEY_NAMES = ("jawOpen", "mouthSmile", "mouthFrown", "mouthPucker", "mouthFunnel", "mouthStretch",
             "mouthRollLower", "cheekPuff", "browInnerUp", "browDown", "browOuterUp", "eyeBlink", "eyeWide")

#: Parts of the Monkey's mesh and their colours (RGB in [0, 1]).
MONKEY_PARTS: dict[str, tuple[float, float, float]] = {
    "fur": (0.42, 0.26, 0.14), "face": (0.86, 0.68, 0.50), "muzzle": (0.90, 0.74, 0.56),
    "mouth": (0.25, 0.05, 0.07), "eye_white": (0.97, 0.96, 0.92), "pupil": (0.08, 0.05, 0.04),
    "brow": (0.30, 0.18, 0.10), "ear": (0.80, 0.60, 0.45), "nostril": (0.20, 0.10, 0.08),
}

#: Shells: part, centre, radii, (latitude, longitude) resolution; ``±`` entries come in a left/right pair.
_MOUTH_Y = -4.6
_SHELLS = (
    ("fur", (0.0, 1.5, -0.5), (9.0, 9.5, 8.5), (24, 40), False),
    ("face", (0.0, 2.0, 4.0), (6.5, 5.5, 4.6), (16, 28), False),
    ("muzzle", (0.0, -4.0, 5.2), (7.2, 4.2, 4.6), (20, 36), False),
    ("mouth", (0.0, _MOUTH_Y, 9.2), (4.6, 0.45, 0.9), (8, 24), False),
    ("eye_white", (2.8, 2.3, 7.7), (1.5, 1.7, 0.8), (8, 14), True),
    ("pupil", (2.7, 2.1, 8.4), (0.7, 0.8, 0.3), (6, 10), True),
    ("brow", (3.0, 4.7, 7.2), (2.7, 0.75, 0.9), (6, 14), True),
    ("ear", (9.4, 1.5, 0.0), (1.2, 3.3, 3.1), (8, 14), True),
    ("nostril", (0.9, -1.7, 9.5), (0.45, 0.3, 0.3), (4, 8), True),
)
_HINGE = np.array([0.0, -2.2, 0.5])   # the jaw's axis is x through this point
_JAW_ANGLE = 0.75                     # radians at jawOpen = 1 (a deep drop)


def _ellipsoid(centre, radii, n_lat: int, n_lon: int) -> tuple[np.ndarray, np.ndarray]:
    """A UV ellipsoid, poles on y, outward-wound triangles."""
    theta = np.pi * np.arange(1, n_lat) / n_lat
    phi = 2.0 * np.pi * np.arange(n_lon) / n_lon
    th, ph = np.meshgrid(theta, phi, indexing="ij")
    ring = np.stack([np.sin(th) * np.sin(ph), np.cos(th), np.sin(th) * np.cos(ph)], -1).reshape(-1, 3)
    unit = np.vstack([[0.0, 1.0, 0.0], ring, [0.0, -1.0, 0.0]])
    i, j = np.meshgrid(np.arange(n_lat - 2), np.arange(n_lon), indexing="ij")
    a, b = 1 + i * n_lon + j, 1 + i * n_lon + (j + 1) % n_lon
    c, d = a + n_lon, b + n_lon
    k = np.arange(n_lon)
    last, base = len(unit) - 1, 1 + (n_lat - 2) * n_lon
    faces = np.concatenate([np.stack([np.zeros(n_lon, int), 1 + k, 1 + (k + 1) % n_lon], -1),
                            np.stack([a, c, b], -1).reshape(-1, 3), np.stack([b, c, d], -1).reshape(-1, 3),
                            np.stack([np.full(n_lon, last), base + (k + 1) % n_lon, base + k], -1)])
    p = unit[faces]
    flip = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p.mean(1)) < 0
    faces[flip] = faces[flip][:, ::-1]
    return unit * np.asarray(radii, float) + np.asarray(centre, float), faces


@lru_cache(maxsize=1)
def _build() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Neutral vertices (V, 3), faces (T, 3), part index (V,), shell centre of each vertex (V, 3)."""
    names = list(MONKEY_PARTS)
    verts, faces, part, centre, offset = [], [], [], [], 0
    for name, c, r, (n_lat, n_lon), paired in _SHELLS:
        for side in ((1.0, -1.0) if paired else (1.0,)):
            cc = np.array(c) * [side, 1.0, 1.0]
            v, f = _ellipsoid(cc, r, n_lat, n_lon)
            verts.append(v)
            faces.append(f + offset)
            part.append(np.full(len(v), names.index(name)))
            centre.append(np.repeat(cc[None], len(v), axis=0))
            offset += len(v)
    out = (np.vstack(verts), np.vstack(faces).astype(np.int64), np.concatenate(part), np.vstack(centre))
    for a in out:
        a.setflags(write=False)
    return out


def _falloff(d: np.ndarray) -> np.ndarray:
    """1 at d = 0, 0 from d = 1 on, smooth (C1)."""
    return np.clip(1.0 - d**2, 0.0, None) ** 2


def _fields(v: np.ndarray, part: np.ndarray, centre: np.ndarray) -> dict[str, np.ndarray]:
    """(V, 3) displacement of each key-model at weight 1."""
    names = list(MONKEY_PARTS)
    is_ = {n: part == names.index(n) for n in names}
    x, y, z = v[:, 0], v[:, 1], v[:, 2]
    side = np.sign(x) + (x == 0)
    front = (z > 3.0).astype(float)
    lower_face = is_["muzzle"] | is_["mouth"]
    out = {k: np.zeros_like(v) for k in KEY_NAMES}

    # jawOpen: the lower muzzle and the mouth's lower half turn down about the hinge
    below = np.clip((_MOUTH_Y + 0.35 - y) / 1.2, 0.0, 1.0) * lower_face
    angle = _JAW_ANGLE * below  # about +x: the chin (in front of the hinge) swings down
    rel = v - _HINGE
    cos, sin = np.cos(angle), np.sin(angle)
    turned = np.stack([rel[:, 0], cos * rel[:, 1] - sin * rel[:, 2], sin * rel[:, 1] + cos * rel[:, 2]], -1)
    out["jawOpen"] = turned - rel

    corner = np.stack([4.6 * side, np.full_like(x, _MOUTH_Y), np.full_like(x, 8.2)], -1)
    near_corner = _falloff(np.linalg.norm(v - corner, axis=1) / 3.8) * lower_face
    out["mouthSmile"] = near_corner[:, None] * np.stack([1.1 * side, 1.4 + 0 * x, -0.5 + 0 * x], -1)
    out["mouthFrown"] = near_corner[:, None] * np.stack([0.3 * side, -1.3 + 0 * x, -0.2 + 0 * x], -1)
    out["mouthStretch"] = near_corner[:, None] * np.stack([1.6 * side, -0.6 + 0 * x, -0.4 + 0 * x], -1)

    lips = _falloff(np.hypot(x / 5.2, (y - _MOUTH_Y) / 1.8)) * lower_face * front
    out["mouthPucker"] = lips[:, None] * np.stack([-0.45 * x, -0.1 * (y - _MOUTH_Y), 1.6 + 0 * x], -1)
    out["mouthFunnel"] = lips[:, None] * np.stack([-0.25 * x, 0.9 * np.tanh(2.0 * (y - _MOUTH_Y)),
                                                   1.1 + 0 * x], -1)
    lower_lip = lips * (y < _MOUTH_Y)
    out["mouthRollLower"] = lower_lip[:, None] * np.array([0.0, 0.6, -1.1])

    cheek_centre = np.stack([4.8 * side, np.full_like(x, -3.0), np.full_like(x, 6.0)], -1)
    cheek = _falloff(np.linalg.norm(v - cheek_centre, axis=1) / 3.6) * is_["muzzle"]
    radial = v - np.array([0.0, -4.0, 5.2])
    radial /= np.maximum(np.linalg.norm(radial, axis=1, keepdims=True), 1e-9)
    out["cheekPuff"] = (1.7 * cheek)[:, None] * radial

    brow = is_["brow"].astype(float)
    forehead = _falloff(np.hypot((np.abs(x) - 3.0) / 3.5, (y - 4.7) / 1.6)) * is_["face"] * 0.6
    lift = brow + forehead
    inner = np.clip((4.6 - np.abs(x)) / 3.2, 0.0, 1.0)
    outer = np.clip((np.abs(x) - 1.6) / 3.2, 0.0, 1.0)
    out["browInnerUp"] = (lift * inner)[:, None] * np.array([0.0, 3.4, 0.2])     # brows lift high
    out["browOuterUp"] = (lift * outer)[:, None] * np.array([0.0, 3.0, 0.0])
    out["browDown"] = lift[:, None] * np.stack([-0.5 * side, -1.3 + 0 * x, 0.4 + 0 * x], -1)

    eyes = (is_["eye_white"] | is_["pupil"]).astype(float)
    eye_y = np.where(eyes > 0, centre[:, 1], y)
    out["eyeBlink"] = (eyes * 0.9 * (eye_y - y))[:, None] * np.array([0.0, 1.0, 0.0])
    out["eyeWide"] = (eyes * 0.35 * (y - eye_y))[:, None] * np.array([0.0, 1.0, 0.0]) \
        + (0.7 * lift)[:, None] * np.array([0.0, 1.0, 0.0])
    return out


@lru_cache(maxsize=1)
def _targets() -> np.ndarray:
    v, _, part, centre = _build()
    fields = _fields(v, part, centre)
    out = np.stack([v + fields[k] for k in KEY_NAMES])
    out.setflags(write=False)
    return out


def monkey_character() -> Character:
    """The Monkey: neutral (V, 3), 13 key-models (absolute positions), triangles; ``name="monkey"``."""
    v, faces, _, _ = _build()
    return Character(v.copy(), _targets().copy(), KEY_NAMES, faces.copy(), name="monkey")


def monkey_colors() -> np.ndarray:
    """(V, 3) float: the colour of each vertex of the Monkey, RGB in [0, 1]."""
    return np.asarray(list(MONKEY_PARTS.values()))[_build()[2]]
