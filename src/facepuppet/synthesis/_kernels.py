"""The wire deformer's per-frame pass, compiled: every bound (wire, point) pair in one loop, then combined.

The same formulas as :func:`facepuppet.synthesis.wire.displace` and the displacement-weighted combination of
:mod:`facepuppet.synthesis.deformer` (their numpy versions are the reference the tests compare with), in
float64, without temporaries: for each pair the wire point W(u_p) and tangent W'(u_p) (lerp of the curve's
unit vertex tangents, normalised), the scale about R(u_p), the rotation by F theta about R'(u_p) x W'(u_p)
(Rodrigues), the translation F (W(u_p) - R(u_p)), and the pair's share ||Delta p||^m of its point.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from facepuppet._util.jit import KERNEL

__all__ = ["TINY_NORM", "deform_pairs"]

#: Norms (tangents, R' x W') below this count as zero: no tangent, no rotation (mesh units / dimensionless).
TINY_NORM = 1e-12


@nb.njit(**KERNEL)
def deform_pairs(points, pair_point, pair_wire, seg, t, closest, offset, rtan, influence, active_only, wpts, wtan,
                 scales, exponent, out):
    """Write the deformed points into ``out`` (N, 3).

    Parameters
    ----------
    points : (N, 3) float64
    pair_point, pair_wire, seg : (P,) int64
        The pair's point, wire and segment index into the concatenated curves.
    t : (P,) float64
        Position of u_p in its segment.
    closest, offset, rtan : (3, P) float64
        R(u_p), p - R(u_p), unit R'(u_p).
    influence : (P,) float64
        F of each pair.
    active_only : bool
        Count only pairs with F > 0 in the combination (radii smaller than the bound ones).
    wpts, wtan : (sum K, 3) float64
        Wire curve points and unit vertex tangents, concatenated.
    scales : (n_wires,) float64
    exponent : float
    out : (N, 3) float64
    """
    n = points.shape[0]
    num = np.zeros((n, 3))
    den = np.zeros(n)
    for p in range(pair_point.shape[0]):
        f = influence[p]
        if active_only and f <= 0.0:
            continue
        j = seg[p]
        b = t[p]
        a = 1.0 - b
        tx = a * wpts[j, 0] + b * wpts[j + 1, 0] - closest[0, p]
        ty = a * wpts[j, 1] + b * wpts[j + 1, 1] - closest[1, p]
        tz = a * wpts[j, 2] + b * wpts[j + 1, 2] - closest[2, p]
        bx = a * wtan[j, 0] + b * wtan[j + 1, 0]
        by = a * wtan[j, 1] + b * wtan[j + 1, 1]
        bz = a * wtan[j, 2] + b * wtan[j + 1, 2]
        nb_ = math.sqrt(bx * bx + by * by + bz * bz)
        if nb_ > TINY_NORM:
            bx, by, bz = bx / nb_, by / nb_, bz / nb_
        else:
            bx, by, bz = 0.0, 0.0, 0.0
        g = 1.0 + (scales[pair_wire[p]] - 1.0) * f
        ox, oy, oz = offset[0, p], offset[1, p], offset[2, p]
        vx, vy, vz = ox * g, oy * g, oz * g
        ax, ay, az = rtan[0, p], rtan[1, p], rtan[2, p]
        kx = ay * bz - az * by
        ky = az * bx - ax * bz
        kz = ax * by - ay * bx
        sn = math.sqrt(kx * kx + ky * ky + kz * kz)
        cs = ax * bx + ay * by + az * bz
        if sn > TINY_NORM:
            kx, ky, kz = kx / sn, ky / sn, kz / sn
            phi = math.atan2(sn, cs) * f
        else:
            kx, ky, kz, phi = 0.0, 0.0, 0.0, 0.0
        c, s = math.cos(phi), math.sin(phi)
        kv = (kx * vx + ky * vy + kz * vz) * (1.0 - c)
        dx = vx * c + (ky * vz - kz * vy) * s + kx * kv + tx * f - ox
        dy = vy * c + (kz * vx - kx * vz) * s + ky * kv + ty * f - oy
        dz = vz * c + (kx * vy - ky * vx) * s + kz * kv + tz * f - oz
        sq = dx * dx + dy * dy + dz * dz
        if exponent == 0.0:
            w = 1.0
        elif exponent == 1.0:
            w = math.sqrt(sq)
        elif exponent == 2.0:
            w = sq
        else:
            w = sq ** (0.5 * exponent)
        i = pair_point[p]
        num[i, 0] += w * dx
        num[i, 1] += w * dy
        num[i, 2] += w * dz
        den[i] += w
    for i in range(n):
        if den[i] > 0.0:
            out[i, 0] = points[i, 0] + num[i, 0] / den[i]
            out[i, 1] = points[i, 1] + num[i, 1] / den[i]
            out[i, 2] = points[i, 2] + num[i, 2] / den[i]
        else:
            out[i, 0], out[i, 1], out[i, 2] = points[i, 0], points[i, 1], points[i, 2]
