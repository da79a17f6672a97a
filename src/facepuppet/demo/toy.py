"""The demo's "Toy" (paper §6): a stylised, non-human character whose mesh and key-models are made by code.

A round mint-green head with a red button nose, button eyes, thick dark brows, a big lip ring around a dark
mouth, round ears and two antennae. It has one key-model per key of :data:`~facepuppet.demo.script.KEY_NAMES`,
authored with its own personality: its smile is a huge grin that lifts the cheeks and narrows the eyes, its
blink squashes the whole eye, its brows travel about twice as far as a person's and its antennae perk up when
the outer brows rise, its cheeks puff into balloons.

Units are centimetres, y up, +z out of the face (towards a viewer in front), x to the character's own left.
Every key-model moves only the vertices of the parts listed for it in :data:`KEY_REGIONS`, by smooth
displacement fields with compact support, so it is exactly the neutral mesh elsewhere.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache

import numpy as np

from facepuppet.demo.script import KEY_NAMES
from facepuppet.io.character import Character

__all__ = ["PARTS", "KEY_REGIONS", "toy_character", "toy_colors", "toy_parts"]

#: Parts of the toy's mesh and their colours (RGB in [0, 1]).
PARTS: dict[str, tuple[float, float, float]] = {
    "skin": (0.45, 0.80, 0.68),
    "mouth": (0.20, 0.04, 0.08),
    "lips": (0.86, 0.22, 0.26),
    "eye_white": (0.97, 0.97, 0.95),
    "pupil": (0.06, 0.06, 0.10),
    "brow": (0.18, 0.12, 0.10),
    "nose": (0.90, 0.25, 0.20),
    "ear": (0.38, 0.70, 0.60),
    "stalk": (0.55, 0.55, 0.60),
    "bulb": (1.00, 0.80, 0.15),
}

#: Parts each key-model may move (all other vertices equal the neutral mesh).
KEY_REGIONS: dict[str, tuple[str, ...]] = {
    "jawOpen": ("skin", "mouth", "lips"),
    "mouthSmile": ("skin", "mouth", "lips", "eye_white", "pupil"),
    "mouthFrown": ("skin", "mouth", "lips"),
    "mouthPucker": ("skin", "mouth", "lips"),
    "mouthFunnel": ("skin", "mouth", "lips"),
    "mouthStretch": ("skin", "mouth", "lips"),
    "mouthRollLower": ("skin", "mouth", "lips"),
    "cheekPuff": ("skin", "mouth", "lips"),
    "browInnerUp": ("brow",),
    "browDown": ("brow", "eye_white", "pupil"),
    "browOuterUp": ("brow", "stalk", "bulb"),
    "eyeBlink": ("eye_white", "pupil", "brow"),
    "eyeWide": ("eye_white", "pupil", "brow"),
}

# Head ellipsoid semi-axes and the places of the features on it.
_HEAD = np.array([10.0, 9.0, 8.5])
_MOUTH_Y, _MOUTH_RX, _MOUTH_RY, _LIP_R = -4.6, 4.2, 1.4, 0.7
_EYE_X, _EYE_Y, _EYE_R = 3.6, 1.5, np.array([1.8, 2.1, 0.6])
_BROW_X, _BROW_Y, _BROW_R = 3.7, 4.7, np.array([2.3, 0.55, 0.55])
_NOSE_Y, _NOSE_R = -1.0, 1.3
_ANTENNA_BASE, _ANTENNA_TIP = np.array([3.0, 8.0, -1.0]), np.array([4.6, 12.6, -1.2])


def _surface_z(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """z of the head's front surface above (x, y)."""
    a, b, c = _HEAD
    return c * np.sqrt(np.clip(1.0 - (x / a) ** 2 - (y / b) ** 2, 0.0, None))


def _grid_faces(n_u: int, n_v: int, wrap_v: bool) -> np.ndarray:
    """Two triangles per cell of a (n_u, n_v) vertex grid, row-major; u is never wrapped."""
    i, j = np.meshgrid(np.arange(n_u - 1), np.arange(n_v if wrap_v else n_v - 1), indexing="ij")
    a = i * n_v + j
    b = i * n_v + (j + 1) % n_v
    c = (i + 1) * n_v + j
    d = (i + 1) * n_v + (j + 1) % n_v
    return np.concatenate([np.stack([a, c, b], -1), np.stack([b, c, d], -1)]).reshape(-1, 3)


def _orient(verts: np.ndarray, faces: np.ndarray, outward: np.ndarray) -> np.ndarray:
    """Flip the faces whose normal points against ``outward`` (T, 3), so the mesh is counter-clockwise outside."""
    p = verts[faces]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    flip = np.einsum("ij,ij->i", n, outward) < 0
    faces = faces.copy()
    faces[flip] = faces[flip][:, ::-1]
    return faces


@lru_cache(maxsize=8)
def _unit_sphere(n_lat: int, n_lon: int) -> tuple[np.ndarray, np.ndarray]:
    """A UV sphere: poles on the y axis, longitude 0 facing +z; outward-wound faces."""
    theta = np.pi * np.arange(1, n_lat) / n_lat
    phi = 2.0 * np.pi * np.arange(n_lon) / n_lon
    th, ph = np.meshgrid(theta, phi, indexing="ij")
    ring = np.stack([np.sin(th) * np.sin(ph), np.cos(th), np.sin(th) * np.cos(ph)], -1).reshape(-1, 3)
    verts = np.vstack([[0.0, 1.0, 0.0], ring, [0.0, -1.0, 0.0]])
    body = _grid_faces(n_lat - 1, n_lon, wrap_v=True) + 1
    j = np.arange(n_lon)
    top = np.stack([np.zeros(n_lon, int), 1 + j, 1 + (j + 1) % n_lon], -1)
    last = len(verts) - 1
    base = 1 + (n_lat - 2) * n_lon
    bottom = np.stack([np.full(n_lon, last), base + (j + 1) % n_lon, base + j], -1)
    faces = np.vstack([top, body, bottom])
    return verts, _orient(verts, faces, verts[faces].mean(1))


def _ellipsoid(center, radii, n_lat: int, n_lon: int, rotation: np.ndarray | None = None):
    unit, faces = _unit_sphere(n_lat, n_lon)
    v = unit * np.asarray(radii, dtype=float)
    if rotation is not None:
        v = v @ rotation.T
    return v + np.asarray(center, dtype=float), faces.copy()


def _lip_ring(n_u: int = 64, n_v: int = 8):
    """The lip ring: a tube around the elliptical mouth outline, lying on the head's surface.

    Returns vertices, faces and the angle u of each vertex's point on the outline.
    """
    u = 2.0 * np.pi * np.arange(n_u) / n_u
    v = 2.0 * np.pi * np.arange(n_v) / n_v
    uu, vv = np.meshgrid(u, v, indexing="ij")
    # on a circular canonical torus first, to wind the faces outward
    canon = np.stack([(2 + np.cos(vv)) * np.cos(uu), (2 + np.cos(vv)) * np.sin(uu), np.sin(vv)], -1)
    canon = canon.reshape(-1, 3)
    faces = _grid_faces(n_u, n_v, wrap_v=True)
    seam = np.stack([(n_u - 1) * n_v + np.arange(n_v), np.arange(n_v)], -1)  # close the tube along u
    a, b = seam[:, 0], seam[:, 1]
    a1, b1 = np.roll(a, -1), np.roll(b, -1)
    faces = np.vstack([faces, np.stack([a, b, a1], -1), np.stack([a1, b, b1], -1)])
    cen = canon[faces].mean(1)
    axis = cen.copy()
    axis[:, 2] = 0.0
    axis *= 2.0 / np.linalg.norm(axis, axis=1, keepdims=True)
    faces = _orient(canon, faces, cen - axis)
    x = (_MOUTH_RX + _LIP_R * np.cos(vv)) * np.cos(uu)
    y = _MOUTH_Y + (_MOUTH_RY + _LIP_R * np.cos(vv)) * np.sin(uu)
    z = _surface_z(x, y) + 0.5 * _LIP_R + _LIP_R * np.sin(vv)
    return np.stack([x, y, z], -1).reshape(-1, 3), faces, uu.ravel()


def _mouth_disk(n_rho: int = 6, n_u: int = 64):
    """The dark mouth: an elliptical disk filling the lip ring, just proud of the skin, facing +z."""
    rho = np.arange(1, n_rho + 1) / n_rho
    u = 2.0 * np.pi * np.arange(n_u) / n_u
    rr, uu = np.meshgrid(rho, u, indexing="ij")
    x = np.r_[0.0, (_MOUTH_RX * rr * np.cos(uu)).ravel()]
    y = _MOUTH_Y + np.r_[0.0, (_MOUTH_RY * rr * np.sin(uu)).ravel()]
    verts = np.stack([x, y, _surface_z(x, y) + 0.6], -1)
    j = np.arange(n_u)
    fan = np.stack([np.zeros(n_u, int), 1 + j, 1 + (j + 1) % n_u], -1)
    faces = np.vstack([fan, _grid_faces(n_rho, n_u, wrap_v=True) + 1])
    return verts, _orient(verts, faces, np.tile([0.0, 0.0, 1.0], (len(faces), 1)))


def _rot_z(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@lru_cache(maxsize=1)
def _build() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Neutral vertices (V, 3), faces (T, 3), part index per vertex (V,), lip-ring angle per vertex (V,)."""
    pieces: list[tuple[np.ndarray, np.ndarray, str, np.ndarray | None]] = []
    v, f = _ellipsoid((0, 0, 0), _HEAD, 30, 48)
    pieces.append((v, f, "skin", None))
    v, f = _mouth_disk()
    pieces.append((v, f, "mouth", None))
    v, f, u = _lip_ring()
    pieces.append((v, f, "lips", u))
    for side in (1.0, -1.0):
        ex, ey = side * _EYE_X, _EYE_Y
        ez = float(_surface_z(np.array(ex), np.array(ey))) - 0.05
        pieces.append((*_ellipsoid((ex, ey, ez), _EYE_R, 10, 16), "eye_white", None))
        pupil = (ex - side * 0.2, ey - 0.25, ez + 0.45)
        pieces.append((*_ellipsoid(pupil, (0.85, 1.0, 0.3), 8, 14), "pupil", None))
        bx = side * _BROW_X
        bz = float(_surface_z(np.array(bx), np.array(_BROW_Y))) + 0.05
        tilt = _rot_z(side * -0.12)
        pieces.append((*_ellipsoid((bx, _BROW_Y, bz), _BROW_R, 8, 16, tilt), "brow", None))
        pieces.append((*_ellipsoid((side * 9.6, 0.5, -1.0), (1.3, 2.6, 2.4), 8, 14), "ear", None))
        base, tip = _ANTENNA_BASE * [side, 1, 1], _ANTENNA_TIP * [side, 1, 1]
        axis = tip - base
        length = float(np.linalg.norm(axis))
        rot = _rot_z(np.arctan2(axis[1], axis[0]) - np.pi / 2.0)
        pieces.append((*_ellipsoid((base + tip) / 2.0, (0.22, length / 2.0, 0.22), 6, 10, rot), "stalk", None))
        pieces.append((*_ellipsoid(tip, (0.9, 0.9, 0.9), 8, 12), "bulb", None))
    nz = float(_surface_z(np.array(0.0), np.array(_NOSE_Y))) + 0.6
    pieces.append((*_ellipsoid((0.0, _NOSE_Y, nz), (_NOSE_R, _NOSE_R * 0.9, _NOSE_R), 10, 14), "nose", None))

    names = list(PARTS)
    verts, faces, part, angle = [], [], [], []
    offset = 0
    for v, f, name, u in pieces:
        verts.append(v)
        faces.append(f + offset)
        part.append(np.full(len(v), names.index(name)))
        angle.append(np.full(len(v), np.nan) if u is None else u)
        offset += len(v)
    out = (np.vstack(verts), np.vstack(faces).astype(np.int64), np.concatenate(part), np.concatenate(angle))
    for a in out:
        a.setflags(write=False)
    return out


# ---------------------------------------------------------------- key-model displacement fields


def _compact(d: np.ndarray) -> np.ndarray:
    """Smooth falloff with compact support: 1 at d = 0, 0 for d >= 1 (C1)."""
    return np.clip(1.0 - d**2, 0.0, None) ** 2


class _Geo:
    """Per-vertex quantities the displacement fields are written in."""

    def __init__(self) -> None:
        self.v, _, part, angle = _build()
        self.mask = {name: part == i for i, name in enumerate(PARTS)}
        x, y = self.v[:, 0], self.v[:, 1]
        p, q = x / _MOUTH_RX, (y - _MOUTH_Y) / _MOUTH_RY
        ring = self.mask["lips"]
        p[ring], q[ring] = np.cos(angle[ring]), np.sin(angle[ring])  # the outline point of each tube vertex
        self.rho = np.hypot(p, q)
        safe = np.maximum(self.rho, 1e-9)
        self.p, self.q = p / safe, q / safe  # direction around the mouth
        # how much a vertex follows the mouth outline: rho inside, 1 on the ring, a falloff on the skin around
        around = np.where(self.rho <= 1.25, 1.0, _compact((self.rho - 1.25) / 0.9))
        self.follow = np.where(self.rho <= 1.0, self.rho, around)
        self.follow[ring] = 1.0
        mouthy = self.mask["mouth"] | ring | (self.mask["skin"] & (self.v[:, 2] > 1e-6))
        self.follow[~mouthy] = 0.0
        self.side = np.sign(x)
        # brow coordinate: -1 at the inner end, +1 at the outer end
        self.s = np.clip((np.abs(x) - _BROW_X) / _BROW_R[0], -1.0, 1.0)
        self.eye_centre_y = _EYE_Y


def _mouth_field(g: _Geo, dx, dy, dz) -> np.ndarray:
    """Displacement of the mouth area from a field on the outline, given as functions of (p, q)."""
    d = np.stack([dx(g.p, g.q), dy(g.p, g.q), dz(g.p, g.q)], -1)
    return d * g.follow[:, None]


def _jaw(g: _Geo) -> np.ndarray:
    drop = 4.5
    d = _mouth_field(g, lambda p, q: 0 * p, lambda p, q: -drop * np.clip(-q, 0, None), lambda p, q: 0 * p)
    # the skin of the whole lower face drops with the jaw
    skin = g.mask["skin"]
    x, y, z = g.v[:, 0], g.v[:, 1], g.v[:, 2]
    below = np.clip(-(y - _MOUTH_Y) / _MOUTH_RY, 0.0, 1.0)
    hx = np.where(np.abs(x) <= _MOUTH_RX + _LIP_R, 1.0, _compact((np.abs(x) - _MOUTH_RX - _LIP_R) / 4.0))
    hz = np.clip((z + 3.0) / 5.0, 0.0, 1.0) ** 2 * (3.0 - 2.0 * np.clip((z + 3.0) / 5.0, 0.0, 1.0))
    d[skin] = 0.0
    d[skin, 1] = -drop * (below * hx * hz)[skin]
    return d


def _bump_at(g: _Geo, part: str, centre, radius: float, disp) -> np.ndarray:
    """A displacement ``disp`` (3,) at ``centre`` fading to zero at ``radius``, on the vertices of ``part``."""
    w = _compact(np.linalg.norm(g.v - np.asarray(centre, float), axis=1) / radius) * g.mask[part]
    return w[:, None] * np.asarray(disp, float)[None]


def _smile(g: _Geo) -> np.ndarray:
    d = _mouth_field(
        g,
        lambda p, q: 1.4 * p * np.abs(p),
        lambda p, q: 2.6 * p**2 - 0.9 * np.clip(-q, 0, None),
        lambda p, q: -0.6 * p**2,
    )
    for side in (1.0, -1.0):
        d += _bump_at(g, "skin", (side * 5.6, _MOUTH_Y + 1.8, 6.0), 3.6, (side * 0.3, 1.2, 1.1))
    d += _squash_eyes(g, bottom=0.35, top=0.0)
    return d


def _squash_eyes(g: _Geo, bottom: float, top: float) -> np.ndarray:
    """Move each eye's lower half up by ``bottom`` and upper half down by ``top`` (fractions of its height)."""
    eye = g.mask["eye_white"] | g.mask["pupil"]
    dy = g.v[:, 1] - _EYE_Y
    h = _EYE_R[1]
    d = np.zeros_like(g.v)
    lower = eye & (dy < 0)
    upper = eye & (dy >= 0)
    d[lower, 1] = bottom * h * np.clip(-dy[lower] / h, 0, 1) ** 0.5 * 1.0
    d[upper, 1] = -top * h * np.clip(dy[upper] / h, 0, 1) ** 0.5
    return d


def _frown(g: _Geo) -> np.ndarray:
    return _mouth_field(
        g,
        lambda p, q: -0.4 * p * np.abs(p),
        lambda p, q: -2.2 * p**2 + 0.4 * np.clip(-q, 0, None) * (1 - p**2),
        lambda p, q: 0.3 * (1 - p**2),
    )


def _pucker(g: _Geo) -> np.ndarray:
    return _mouth_field(
        g, lambda p, q: -0.6 * _MOUTH_RX * p, lambda p, q: -0.15 * _MOUTH_RY * q, lambda p, q: 2.2 + 0 * p
    )


def _funnel(g: _Geo) -> np.ndarray:
    return _mouth_field(
        g, lambda p, q: -0.4 * _MOUTH_RX * p, lambda p, q: 0.9 * _MOUTH_RY * q, lambda p, q: 1.6 + 0 * p
    )


def _stretch(g: _Geo) -> np.ndarray:
    return _mouth_field(
        g,
        lambda p, q: 1.8 * p,
        lambda p, q: -0.5 * np.clip(-q, 0, None) - 0.4 * p**2,
        lambda p, q: -0.5 * p**2,
    )


def _roll_lower(g: _Geo) -> np.ndarray:
    return _mouth_field(
        g,
        lambda p, q: -0.1 * p * np.clip(-q, 0, None),
        lambda p, q: 1.0 * _MOUTH_RY * np.clip(-q, 0, None),
        lambda p, q: -0.9 * np.clip(-q, 0, None),
    )


def _cheek_puff(g: _Geo) -> np.ndarray:
    d = _mouth_field(g, lambda p, q: -0.2 * _MOUTH_RX * p, lambda p, q: 0 * p, lambda p, q: 0.6 + 0 * p)
    skin = g.mask["skin"]
    normal = g.v / _HEAD**2
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    for side in (1.0, -1.0):
        centre = np.array([side * 6.3, _MOUTH_Y + 0.8, 0.0])
        centre[2] = float(_surface_z(centre[0], centre[1]))
        w = _compact(np.linalg.norm(g.v - centre, axis=1) / 5.0) * skin
        d += 2.6 * w[:, None] * normal
    return d


def _brows(g: _Geo, inner: float, outer: float, knit: float = 0.0) -> np.ndarray:
    """Brow displacement: ``inner``/``outer`` cm up at the inner/outer ends, ``knit`` cm towards the middle."""
    brow = g.mask["brow"]
    t = (g.s + 1.0) / 2.0  # 0 inner .. 1 outer
    d = np.zeros_like(g.v)
    d[brow, 1] = (inner * (1 - t) + outer * t)[brow]
    d[brow, 0] = (-g.side * knit * (1 - t))[brow]
    return d


def _brow_inner_up(g: _Geo) -> np.ndarray:
    return _brows(g, inner=2.6, outer=0.2)


def _brow_down(g: _Geo) -> np.ndarray:
    return _brows(g, inner=-2.0, outer=-0.6, knit=0.9) + _squash_eyes(g, bottom=0.0, top=0.25)


def _brow_outer_up(g: _Geo) -> np.ndarray:
    d = _brows(g, inner=0.3, outer=2.6)
    # the antennae perk up: rotate about their bases, outward and taller
    for side in (1.0, -1.0):
        base = _ANTENNA_BASE * [side, 1, 1]
        sel = (g.mask["stalk"] | g.mask["bulb"]) & (g.side == side)
        rel = g.v[sel] - base
        rot = _rot_z(-side * 0.35)
        d[sel] = rel @ rot.T * 1.15 - rel
    return d


def _eye_blink(g: _Geo) -> np.ndarray:
    eye = g.mask["eye_white"] | g.mask["pupil"]
    d = np.zeros_like(g.v)
    d[eye, 1] = -0.9 * (g.v[eye, 1] - _EYE_Y)  # the whole button eye squashes flat
    return d + _brows(g, inner=-0.5, outer=-0.5)


def _eye_wide(g: _Geo) -> np.ndarray:
    eye = g.mask["eye_white"] | g.mask["pupil"]
    d = np.zeros_like(g.v)
    centre_x = g.side * _EYE_X
    d[eye, 0] = 0.3 * (g.v[eye, 0] - centre_x[eye])
    d[eye, 1] = 0.4 * (g.v[eye, 1] - _EYE_Y)
    d[eye, 2] = 0.8
    return d + _brows(g, inner=1.2, outer=1.2)


_FIELDS: dict[str, Callable[[_Geo], np.ndarray]] = {
    "jawOpen": _jaw,
    "mouthSmile": _smile,
    "mouthFrown": _frown,
    "mouthPucker": _pucker,
    "mouthFunnel": _funnel,
    "mouthStretch": _stretch,
    "mouthRollLower": _roll_lower,
    "cheekPuff": _cheek_puff,
    "browInnerUp": _brow_inner_up,
    "browDown": _brow_down,
    "browOuterUp": _brow_outer_up,
    "eyeBlink": _eye_blink,
    "eyeWide": _eye_wide,
}


@lru_cache(maxsize=1)
def _targets() -> np.ndarray:
    g = _Geo()
    out = np.empty((len(KEY_NAMES), *g.v.shape))
    for i, key in enumerate(KEY_NAMES):
        d = _FIELDS[key](g)
        allowed = np.zeros(len(g.v), bool)
        for part in KEY_REGIONS[key]:
            allowed |= g.mask[part]
        d[~allowed] = 0.0
        out[i] = g.v + d
    out.setflags(write=False)
    return out


def toy_character() -> Character:
    """The Toy: neutral mesh, one key-model per demo key (absolute positions), triangles.

    Returns
    -------
    Character
        ``neutral`` (V, 3) with V ≈ 3,900, ``targets`` (13, V, 3), ``names`` = :data:`KEY_NAMES`,
        ``faces`` (T, 3) wound counter-clockwise seen from outside, ``name="toy"``.
    """
    v, faces, _, _ = _build()
    return Character(v.copy(), _targets().copy(), tuple(KEY_NAMES), faces.copy(), name="toy")


def toy_parts() -> tuple[tuple[str, ...], np.ndarray]:
    """Part names and the part index of each vertex, ``(names, (V,) int)``."""
    return tuple(PARTS), _build()[2].copy()


def toy_colors() -> np.ndarray:
    """(V, 3) float: the colour of each vertex of the Toy, RGB in [0, 1]."""
    table = np.asarray(list(PARTS.values()))
    return table[_build()[2]]
