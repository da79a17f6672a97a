"""Painting the digital performer (:mod:`facepuppet.demo.performer`): skin head by ray casting, features by
anti-aliased polygons of projected 3D outlines, camera noise.

The head, jaw, cheeks, nose, alae, ears and neck are ellipsoids in head coordinates (cm), ray cast on a grid
three times coarser than the frame over the head's bounding box, with Lambert shading under a light fixed to
the camera, and blended over a background with a shirt; the silhouettes' coverage comes from the interpolated
signed distance to them, so the edges stay sharp and smooth at full resolution.

The features are painted on top: brows (thick strokes around the brow curves), eyes (sclera and iris clipped
to the lid opening, a lash band on the upper lid margin, a lower lid line), lips (red between the outer
curves, a dark opening between the inner curves) and nostrils (dark strokes around the nostril curves). Every
outline is a 3D curve of the performer projected with the true pose.
"""

from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np

from facepuppet.capture.curves import CURVE_NAMES, bernstein
from facepuppet.capture.pose import HeadPose
from facepuppet.demo.script import KEY_NAMES

_C = {name: i for i, name in enumerate(CURVE_NAMES)}
_K = {name: i for i, name in enumerate(KEY_NAMES)}
_SHIFT = 4
_ONE = 1 << _SHIFT
_AA = cv2.LINE_AA

# colours, RGB 0..255
SKIN = np.array([226.0, 184.0, 158.0])
HAIR = np.array([92.0, 64.0, 46.0])
_BROW = (56, 40, 33)
_SCLERA = (232, 228, 222)
_IRIS = (92, 66, 48)
_PUPIL = (18, 14, 14)
_LASH = (34, 24, 24)
_LOWER_LID = (128, 82, 76)
_CREASE = (176, 132, 114)
_LIPS = (176, 92, 98)
_LIP_LINE = (110, 38, 48)
_MOUTH = (52, 18, 24)
_NOSTRIL = (82, 44, 44)
_BACKGROUND = ((96, 110, 128), (62, 72, 88))  # top, bottom
_SHIRT = (72, 96, 132)
_NOISE_SIGMA = 2.5

_TO_LIGHT = np.array([-0.45, -0.55, -0.70])  # camera coordinates (x right, y down, z forward): upper left front
_TO_LIGHT /= np.linalg.norm(_TO_LIGHT)
_AMBIENT, _DIFFUSE = 0.5, 0.58

# Ellipsoids of the head: centre (3,), radii (3,), part (0 skin, 1 skin with hair above the hairline, 2 neck).
_CRANIUM = ((0.0, 0.3, -7.6), (7.3, 10.0, 9.0), 1)
_JAW = ((0.0, -6.6, -4.9), (4.3, 4.3, 6.3), 0)
_CHIN = ((0.0, -9.4, -0.6), (2.0, 1.5, 1.4), 0)
_BRIDGE = ((0.0, -1.4, 0.2), (0.62, 2.3, 1.1), 0)
_TIP = ((0.0, -3.3, 1.6), (0.82, 0.7, 0.78), 0)
_ALA = ((1.1, -4.0, 0.2), (0.6, 0.5, 0.65), 0)
_CHEEK = ((3.4, -4.6, -4.2), (2.4, 2.3, 2.2), 0)
_EAR = ((7.0, -2.0, -7.4), (0.9, 2.8, 1.7), 0)
_NECK = ((0.0, -19.0, -7.2), (5.4, 12.0, 4.8), 2)
_SMOOTH = 9  # the face's ellipsoids (the first ones of _ellipsoids), whose creases are smoothed in the shading
_BLEND = 4.0  # sharpness of the smooth union of their normals
_RING = 1.5  # coarse pixels outside a silhouette that still get a colour
_SUB = 3  # the head is ray cast on a grid this many times coarser than the frame

_UNIT = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)  # box corners
_S24 = np.linspace(0.0, 1.0, 24)
_B24 = bernstein(_S24)


def _mirror(e):
    (cx, cy, cz), r, part = e
    return (-cx, cy, cz), r, part


def _ellipsoids(w: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, int]]:
    """The head's ellipsoids for weights ``w``: the jaw drops with jawOpen, the cheeks puff with cheekPuff."""
    jaw, puff, smile = w[_K["jawOpen"]], w[_K["cheekPuff"]], w[_K["mouthSmile"]]
    out = [_CRANIUM]
    (jc, jr, jp) = _JAW
    out.append(((jc[0], jc[1] - 1.0 * jaw, jc[2] - 0.2 * jaw), (jr[0] + 0.5 * puff, jr[1] + 0.6 * jaw, jr[2]), jp))
    (cc, cr, cp) = _CHIN
    out.append(((cc[0], cc[1] - 1.7 * jaw, cc[2] - 0.3 * jaw), cr, cp))
    cc, cr, cp = _CHEEK
    for side in (1.0, -1.0):
        c = (side * (cc[0] + 0.6 * puff + 0.2 * smile), cc[1] + 0.5 * smile - 0.3 * puff,
             cc[2] + 0.9 * puff + 0.4 * smile)
        r = tuple(x * (1.0 + 0.2 * puff) for x in cr)
        out.append((c, r, cp))
    out += [_BRIDGE, _TIP, _ALA, _mirror(_ALA), _EAR, _mirror(_EAR), _NECK]
    return [(np.asarray(c, float), np.asarray(r, float), p) for c, r, p in out]


@lru_cache(maxsize=4)
def _backdrop(w: int, h: int) -> np.ndarray:
    """Background wall (vertical gradient); read-only (H, W, 3) uint8."""
    top, bottom = (np.asarray(c, np.float32) for c in _BACKGROUND)
    t = np.linspace(0.0, 1.0, h, dtype=np.float32)[:, None, None]
    img = np.ascontiguousarray(np.broadcast_to(top * (1 - t) + bottom * t, (h, w, 3)).astype(np.uint8))
    img.setflags(write=False)
    return img


@lru_cache(maxsize=4)
def _noise_tiles(w: int, h: int) -> tuple[np.ndarray, np.ndarray]:
    """Camera noise (positive and negative parts, uint8) on a tile 32 px larger than the frame each way."""
    n = np.random.default_rng(12345).normal(0.0, _NOISE_SIGMA, (h + 32, w + 32, 3))
    n = np.round(n)
    pos, neg = np.clip(n, 0, 255).astype(np.uint8), np.clip(-n, 0, 255).astype(np.uint8)
    pos.setflags(write=False)
    neg.setflags(write=False)
    return pos, neg


def _shade_head(img: np.ndarray, w: np.ndarray, pose: HeadPose) -> None:
    """Ray cast the head's ellipsoids on a coarse grid over their bounding box and blend them into ``img``.

    Two layers, composited with their anti-aliased coverage: behind, the ears and neck; in front, the face's
    ellipsoids (head, jaw, chin, cheeks, nose), whose normals are blended by a soft minimum of their implicit
    functions, so they merge without shading creases.
    """
    h_img, w_img = img.shape[:2]
    ells = _ellipsoids(w)
    boxes = pose.project(np.concatenate([c + r * _UNIT for c, r, _ in ells])).reshape(len(ells), 8, 2)
    lo, hi = boxes.min(1), boxes.max(1)
    f = _SUB
    x0, y0 = np.maximum((np.floor(lo.min(0)).astype(int) - 4) // f * f, 0)
    x1 = min((int(np.ceil(hi[:, 0].max())) + 4 + f) // f * f, w_img // f * f)
    y1 = min((int(np.ceil(hi[:, 1].max())) + 4 + f) // f * f, h_img // f * f)
    if x1 <= x0 or y1 <= y0:
        return
    grid = (x0, y0, (x1 - x0) // f, (y1 - y0) // f)
    rgb_f, d_f = _cast(ells[:_SMOOTH], lo[:_SMOOTH], hi[:_SMOOTH], pose, grid, smooth=True)
    rgb_b, d_b = _cast(ells[_SMOOTH:], lo[_SMOOTH:], hi[_SMOOTH:], pose, grid, smooth=False)
    a_f = np.clip(d_f + 0.5, 0.0, 1.0)[..., None]
    rgb = np.where((d_b > -_RING)[..., None], rgb_f * a_f + rgb_b * (1.0 - a_f), rgb_f)
    layer = np.concatenate([rgb, np.maximum(d_f, d_b)[..., None]], axis=2)
    big = cv2.resize(layer, (x1 - x0, y1 - y0), interpolation=cv2.INTER_LINEAR)
    # the silhouette's coverage from the interpolated signed distance: sharp and smooth at full resolution
    alpha = np.clip(big[..., 3:] * np.float32(f) + np.float32(0.5), 0.0, 1.0)
    roi = img[y0:y1, x0:x1]
    out = roi.astype(np.float32)
    out += alpha * (big[..., :3] - out)
    np.copyto(roi, out, casting="unsafe")


def _cast(ells, lo, hi, pose: HeadPose, grid, smooth: bool) -> tuple[np.ndarray, np.ndarray]:
    """Shade the nearest ellipsoid along the ray through each pixel of the coarse grid.

    Returns
    -------
    rgb : (ny, nx, 3) float32
        Shaded colour; also on a ring of :data:`_RING` coarse pixels outside the silhouette (shaded at the
        ray's closest approach), so that interpolation across the edge never mixes in an undefined colour.
    distance : (ny, nx) float32
        Signed distance to the silhouette in coarse pixels, positive inside (about; exact near the edge).
    """
    x0, y0, nx, ny = grid
    R, t, K = pose.rotation, pose.translation, pose.camera_matrix
    u = (x0 + _SUB * np.arange(nx) + (_SUB - 1) / 2.0).astype(np.float32)  # centres of the coarse pixels
    v = (y0 + _SUB * np.arange(ny) + (_SUB - 1) / 2.0).astype(np.float32)
    A = (R.T @ np.linalg.inv(K)).astype(np.float32)  # ray direction in head coordinates: A @ (u, v, 1)
    o = (-R.T @ t).astype(np.float32)  # camera centre in head coordinates
    f_sub = K[0, 0] / _SUB
    best = np.full((ny, nx), np.inf, np.float32)
    which = np.full((ny, nx), -1, np.int8)
    ring_s = np.full((ny, nx), np.inf, np.float32)
    ring_which = np.full((ny, nx), -1, np.int8)
    distance = np.full((ny, nx), -3.0, np.float32)
    rgb = np.zeros((ny, nx, 3), np.float32)
    for e, (c, r, _) in enumerate(ells):
        i0 = int(np.clip((lo[e, 0] - x0) // _SUB - 2, 0, nx))
        i1 = int(np.clip((hi[e, 0] - x0) // _SUB + 3, 0, nx))
        j0 = int(np.clip((lo[e, 1] - y0) // _SUB - 2, 0, ny))
        j1 = int(np.clip((hi[e, 1] - y0) // _SUB + 3, 0, ny))
        if i1 <= i0 or j1 <= j0:
            continue
        ri = (1.0 / r).astype(np.float32)
        oo = (o - c.astype(np.float32)) * ri
        # d / r as outer sums of the window's u and v terms: d_k = A_k0 u + A_k1 v + A_k2
        dd = [(A[k, 0] * ri[k]) * u[None, i0:i1] + ((A[k, 1] * ri[k]) * v[j0:j1, None] + A[k, 2] * ri[k])
              for k in range(3)]
        a = dd[0] * dd[0] + dd[1] * dd[1] + dd[2] * dd[2]
        b = oo[0] * dd[0] + oo[1] * dd[1] + oo[2] * dd[2]
        disc = b * b - a * float(oo @ oo - 1.0)
        # 1 - rho^2 = disc / a, rho the ray's closest approach in the unit sphere's frame; times half the radius
        # in pixels it is the distance to the silhouette near the edge
        r_px = float(r.min()) * f_sub / max(float(np.linalg.norm(o - c)), 1e-6)
        delta = disc / a * np.float32(r_px * 0.5)
        s = (-b - np.sqrt(np.maximum(disc, 0.0))) / a
        win = (slice(j0, j1), slice(i0, i1))
        np.maximum(distance[win], delta, out=distance[win])
        hit = (disc >= 0) & (s < best[win])
        best[win][hit] = s[hit]
        which[win][hit] = e
        ring = (disc < 0) & (delta > -_RING) & (s < ring_s[win])
        ring_s[win][ring] = s[ring]
        ring_which[win][ring] = e
    empty = which < 0
    best[empty] = ring_s[empty]
    which[empty] = ring_which[empty]
    jj, ii = np.nonzero(which >= 0)
    if len(jj) == 0:
        return rgb, distance
    d = A @ np.stack([u[ii], v[jj], np.ones(len(ii), np.float32)])  # (3, M)
    p = o[:, None] + d * best[jj, ii]
    idx = which[jj, ii].astype(int)
    centres = np.stack([c for c, _, _ in ells]).astype(np.float32)
    inv_r = np.stack([1.0 / r for _, r, _ in ells]).astype(np.float32)
    if smooth:
        # soft union: normals of all ellipsoids weighted by exp(-k f), f the implicit function at the hit point;
        # each ellipsoid counts only near itself (its box, 1.6 times its radii), where its weight is not tiny
        grid = np.zeros((3, ny, nx), np.float32)
        grid[:, jj, ii] = p
        acc = np.zeros_like(grid)
        total = np.full((ny, nx), 1e-20, np.float32)
        for e, (c, r, _) in enumerate(ells):
            if e == 0:
                win = (slice(None), slice(None))
            else:
                near = pose.project(c + 1.6 * r * _UNIT)
                i0, j0 = np.clip(((near.min(0) - (x0, y0)) // _SUB).astype(int), 0, (nx, ny))
                i1, j1 = np.clip(((near.max(0) - (x0, y0)) // _SUB).astype(int) + 2, 0, (nx, ny))
                if i1 <= i0 or j1 <= j0:
                    continue
                win = (slice(j0, j1), slice(i0, i1))
            q = grid[(slice(None), *win)]
            rel = (q - centres[e][:, None, None]) * inv_r[e][:, None, None]
            f = (rel * rel).sum(0) - 1.0
            g = rel * inv_r[e][:, None, None]
            wgt = np.exp(-_BLEND * np.maximum(f, 0.0)) / np.sqrt((g * g).sum(0))
            acc[(slice(None), *win)] += g * wgt
            total[win] += wgt
        normal = acc[:, jj, ii] / total[jj, ii]
    else:
        normal = (p - centres[idx].T) * (inv_r[idx] ** 2).T
    normal /= np.sqrt((normal * normal).sum(0))
    lambert = np.clip(_TO_LIGHT.astype(np.float32) @ (R.astype(np.float32) @ normal), 0.0, None)
    shade = _AMBIENT + _DIFFUSE * lambert
    part = np.array([q for _, _, q in ells])[idx]
    shade[part == 2] *= 0.78  # the neck in the head's shadow
    # hair above the hairline, lower at the sides and back, with a soft edge of about 0.6 cm
    hair = np.clip(((p[1] - 6.2) + 0.35 * np.clip(-p[2] - 2.0, 0.0, None)) / 0.6 + 0.5, 0.0, 1.0)
    hair[part != 1] = 0.0
    base = SKIN.astype(np.float32) + hair[:, None] * (HAIR - SKIN).astype(np.float32)
    rgb[jj, ii] = shade[:, None] * base
    return rgb, distance


def _fix(points: np.ndarray) -> np.ndarray:
    return np.round(points * _ONE).astype(np.int32)


def _fill(img, pts, color) -> None:
    cv2.fillPoly(img, [_fix(pts)], color, _AA, _SHIFT)


def _band(curve: np.ndarray, below: np.ndarray, above: np.ndarray) -> np.ndarray:
    """Outline (2S, 3) of a band around a 3D curve (S, 3): ``below``/``above`` (S,) cm along head y."""
    up = curve.copy()
    up[:, 1] += above
    down = curve.copy()
    down[:, 1] -= below
    return np.concatenate([up, down[::-1]])


def _circle(centre, radius: float, n: int = 20) -> np.ndarray:
    a = 2.0 * np.pi * np.arange(n) / n
    return np.asarray(centre, float) + radius * np.stack([np.cos(a), np.sin(a), np.zeros(n)], -1)


def _eye(img: np.ndarray, opening: np.ndarray, iris: np.ndarray, pupil: np.ndarray, glint: np.ndarray) -> None:
    """Sclera, iris, pupil and catch-light, clipped to the lid opening (image polygons, pixels)."""
    h, w = img.shape[:2]
    x0, y0 = np.floor(opening.min(0)).astype(int) - 2
    x1, y1 = np.ceil(opening.max(0)).astype(int) + 3
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
    if x1 - x0 < 1 or y1 - y0 < 1:
        return
    off = np.array([x0, y0], float)
    mask = np.zeros((y1 - y0, x1 - x0), np.uint8)
    cv2.fillPoly(mask, [_fix(opening - off)], 255, _AA, _SHIFT)
    patch = np.empty((y1 - y0, x1 - x0, 3), np.uint8)
    patch[:] = _SCLERA
    cv2.fillPoly(patch, [_fix(iris - off)], _IRIS, _AA, _SHIFT)
    cv2.fillPoly(patch, [_fix(pupil - off)], _PUPIL, _AA, _SHIFT)
    cv2.fillPoly(patch, [_fix(glint - off)], (245, 245, 245), _AA, _SHIFT)
    a = mask[..., None].astype(np.float32) * np.float32(1.0 / 255.0)
    roi = img[y0:y1, x0:x1]
    roi[:] = (roi * (1.0 - a) + patch * a).astype(np.uint8)


def paint(w: np.ndarray, ctrl3: np.ndarray, pose: HeadPose, size: tuple[int, int],
          rng: np.random.Generator | None) -> np.ndarray:
    """One RGB frame (H, W, 3) uint8 of the performer with curves ``ctrl3`` (C, 4, 3) seen with ``pose``."""
    width, height = size
    img = _backdrop(width, height).copy()
    _shade_head(img, w, pose)
    # the shirt over the bottom of the neck: shoulders that stay still while the head moves
    centre = (int(width / 2 * _ONE), int(height * 1.09 * _ONE))
    axes = (int(width * 0.54 * _ONE), int(height * 0.22 * _ONE))
    cv2.ellipse(img, centre, axes, 0, 180, 360, _SHIRT, -1, _AA, _SHIFT)

    curves = np.einsum("sj,cjd->csd", _B24, ctrl3)  # (C, 24, 3)
    s = _S24
    bell = np.sin(np.pi * s)
    shapes: list[np.ndarray] = []

    def add(points: np.ndarray) -> int:
        shapes.append(points)
        return len(shapes) - 1

    brows = [add(_band(curves[_C[f"brow_{side}"]], 0.26 * (1 - s) + 0.12 * s + 0.06 * bell,
                       0.26 * (1 - s) + 0.10 * s + 0.08 * bell)) for side in ("left", "right")]
    eyes = []
    for side, sign in (("left", 1.0), ("right", -1.0)):
        up, lo = curves[_C[f"eye_{side}_upper"]], curves[_C[f"eye_{side}_lower"]]
        centre = (up[0] + up[-1]) / 2.0
        centre = np.array([centre[0] - sign * 0.08, centre[1] + 0.02, 0.25])
        eyes.append(dict(
            crease=add(up + np.stack([np.zeros_like(s), 0.05 + 0.42 * bell**0.7, 0.1 * bell], -1)),
            opening=add(np.concatenate([up, lo[::-1]])),
            iris=add(_circle(centre, 0.58)),
            pupil=add(_circle(centre, 0.23)),
            glint=add(_circle(centre + np.array([-0.2, 0.2, 0.0]), 0.08, 8)),
            lash=add(_band(up, 0.03 + 0.02 * bell, 0.05 + 0.06 * s + 0.04 * bell)),
            lower=add(_band(lo, 0.035 * bell + 0.01, 0.035 * bell + 0.01)),
        ))
    lips = add(np.concatenate([curves[_C["lip_upper_outer"]], curves[_C["lip_lower_outer"]][::-1]]))
    ui, li = curves[_C["lip_upper_inner"]], curves[_C["lip_lower_inner"]]
    mouth = add(np.concatenate([ui, li[::-1]]))
    lip_line = [add(ui), add(li)]
    thick = 0.01 + 0.15 * bell**1.5
    nostrils = [add(_band(curves[_C[f"nostril_{side}"]], thick, 0.5 * thick)) for side in ("left", "right")]

    flat = pose.project(np.concatenate(shapes))
    splits = np.cumsum([len(p) for p in shapes])[:-1]
    uv = np.split(flat, splits)

    px_per_cm = pose.camera_matrix[0, 0] / max(float(pose.translation[2]), 1e-6)
    line = max(1, int(round(0.06 * px_per_cm)))
    for e in eyes:
        cv2.polylines(img, [_fix(uv[e["crease"]])], False, _CREASE, line, _AA, _SHIFT)
    for b in brows:
        _fill(img, uv[b], _BROW)
    _fill(img, uv[lips], _LIPS)
    _fill(img, uv[mouth], _MOUTH)
    cv2.polylines(img, [_fix(uv[i]) for i in lip_line], False, _LIP_LINE, line, _AA, _SHIFT)
    for n in nostrils:
        _fill(img, uv[n], _NOSTRIL)
    for e in eyes:
        _eye(img, uv[e["opening"]], uv[e["iris"]], uv[e["pupil"]], uv[e["glint"]])
        _fill(img, uv[e["lower"]], _LOWER_LID)
        _fill(img, uv[e["lash"]], _LASH)

    pos, neg = _noise_tiles(width, height)
    ox, oy = (0, 0) if rng is None else rng.integers(0, 33, 2)
    cv2.add(img, pos[oy:oy + height, ox:ox + width], dst=img)
    cv2.subtract(img, neg[oy:oy + height, ox:ox + width], dst=img)
    return img
