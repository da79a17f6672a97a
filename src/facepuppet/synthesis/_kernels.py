"""The wire deformer's per-frame pass, compiled: every bound (wire, point) pair in one loop, then combined.

The same formulas as :func:`facepuppet.synthesis.wire.displace` and the displacement-weighted combination of
:mod:`facepuppet.synthesis.deformer` (their numpy versions are the reference the tests compare with), in
float64, without temporaries: for each pair the wire point W(u_p) and tangent W'(u_p) (lerp of the curve's
unit vertex tangents, normalised), the scale about R(u_p), the rotation by F theta about R'(u_p) x W'(u_p)
(Rodrigues), the translation F (W(u_p) - R(u_p)), and the pair's share ||Delta p||^m of its point.

Layout: the pairs are sorted by point (stable, so each point's wires keep their order and its sums are the
numpy pass's), one row of :data:`PAIR_COLUMNS` per pair, so a point's combination is summed in registers and
written once. For rotation angles phi = F theta below 1 rad, cos phi is sqrt(1 - sin^2 phi) (exact to a few
units of rounding there), one transcendental call fewer per pair.
"""

from __future__ import annotations

import math

import numba as nb

from facepuppet._util.jit import KERNEL

__all__ = ["TINY_NORM", "PAIR_COLUMNS", "deform_pairs"]

#: Norms (tangents, R' x W') below this count as zero: no tangent, no rotation (mesh units / dimensionless).
TINY_NORM = 1e-12
#: The columns of a pair's row: u_p's position t in its segment, R(u_p), p - R(u_p), the unit R'(u_p).
PAIR_COLUMNS = ("t", "closest_x", "closest_y", "closest_z", "offset_x", "offset_y", "offset_z", "tangent_x",
                "tangent_y", "tangent_z")
#: Below this angle (rad) cos phi is taken as sqrt(1 - sin^2 phi) (cos 1 > 0.54: no loss of precision).
SQRT_COS_BELOW = 1.0


@nb.njit(**KERNEL)
def deform_pairs(points, pair_point, pair_wire, seg, rows, influence, active_only, wpts, wtan, scales, exponent,
                 out):
    """Write the deformed points into ``out`` (N, 3).

    Parameters
    ----------
    points : (N, 3) float64
    pair_point, pair_wire, seg : (P,) int64
        The pair's point (non-decreasing: pairs sorted by point), wire and segment index into the
        concatenated curves.
    rows : (P, 10) float64
        Per pair the columns of :data:`PAIR_COLUMNS`.
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
    for i in range(n):
        out[i, 0], out[i, 1], out[i, 2] = points[i, 0], points[i, 1], points[i, 2]
    n_pairs = pair_point.shape[0]
    p = 0
    while p < n_pairs:
        i = pair_point[p]
        nx, ny, nz, den = 0.0, 0.0, 0.0, 0.0
        while p < n_pairs and pair_point[p] == i:
            f = influence[p]
            if active_only and f <= 0.0:
                p += 1
                continue
            j = seg[p]
            b = rows[p, 0]
            a = 1.0 - b
            tx = a * wpts[j, 0] + b * wpts[j + 1, 0] - rows[p, 1]
            ty = a * wpts[j, 1] + b * wpts[j + 1, 1] - rows[p, 2]
            tz = a * wpts[j, 2] + b * wpts[j + 1, 2] - rows[p, 3]
            bx = a * wtan[j, 0] + b * wtan[j + 1, 0]
            by = a * wtan[j, 1] + b * wtan[j + 1, 1]
            bz = a * wtan[j, 2] + b * wtan[j + 1, 2]
            nb_ = math.sqrt(bx * bx + by * by + bz * bz)
            if nb_ > TINY_NORM:
                bx, by, bz = bx / nb_, by / nb_, bz / nb_
            else:
                bx, by, bz = 0.0, 0.0, 0.0
            g = 1.0 + (scales[pair_wire[p]] - 1.0) * f
            ox, oy, oz = rows[p, 4], rows[p, 5], rows[p, 6]
            vx, vy, vz = ox * g, oy * g, oz * g
            ax, ay, az = rows[p, 7], rows[p, 8], rows[p, 9]
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
            s = math.sin(phi)
            c = math.sqrt(1.0 - s * s) if phi < SQRT_COS_BELOW else math.cos(phi)
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
            nx += w * dx
            ny += w * dy
            nz += w * dz
            den += w
            p += 1
        if den > 0.0:
            out[i, 0] += nx / den
            out[i, 1] += ny / den
            out[i, 2] += nz / den
