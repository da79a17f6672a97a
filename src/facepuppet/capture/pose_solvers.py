"""The head-pose solvers of :func:`~facepuppet.capture.pose.estimate_pose`: the upright pose's closed-form
start and Gauss-Newton refinement, the free pose's Gauss-Newton refinement, and the reprojection error.

Conventions: ``xyz`` (N, 3) generic-face landmarks in head coordinates (cm), ``uv`` (N, 2) their image points
(pixels), ``K`` (3, 3) the camera matrix; a pose maps ``x_cam = R @ x_head + t``.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from facepuppet._util.jit import INNER, KERNEL

__all__ = ["upright_start", "refine_upright", "solve_spd", "refine_pose", "reprojection_error"]


def upright_start(K: np.ndarray, xyz: np.ndarray, uv: np.ndarray) -> tuple[float, np.ndarray]:
    """A first upright pose, ``R = FRONTAL_ROTATION @ Rz(roll)`` (no yaw or pitch), as (roll, t).

    With that R, ``R X = (c X_x − s X_y, −s X_x − c X_y, −X_z)`` (c, s the roll's cosine and sine): the points'
    (X_x, −X_y) turned by −roll. The roll is the angle of the 2-D similarity that best takes the points'
    (X_x, −X_y) onto their image points (both centred; Procrustes), whatever the face's proportions. Then each
    point's projection ``u = f_x (R X + t)_x / (R X + t)_z + c_x`` (v alike), multiplied out, is linear in t:
    ``f_x t_x − (u − c_x) t_z = −(u − c_x) X_z − f_x (c X_x − s X_y)`` and
    ``f_y t_y − (v − c_y) t_z = −(v − c_y) X_z − f_y (−s X_x − c X_y)``, solved by least squares; a start for
    :func:`refine_upright` (exact in t for the points of an upright head at that roll).
    """
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    X, Y, Z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    du, dv = uv[:, 0] - cx, uv[:, 1] - cy
    px, py = X - X.mean(), -(Y - Y.mean())
    qx, qy = du - du.mean(), dv - dv.mean()
    roll = -float(np.arctan2(np.sum(px * qy - py * qx), np.sum(px * qx + py * qy)))
    c, s = np.cos(roll), np.sin(roll)
    n = len(xyz)
    zero, one = np.zeros(n), np.ones(n)
    A = np.vstack([np.column_stack([fx * one, zero, -du]), np.column_stack([zero, fy * one, -dv])])
    rest = np.concatenate([-du * Z - fx * (c * X - s * Y), -dv * Z - fy * (-s * X - c * Y)])
    return roll, np.linalg.lstsq(A, rest, rcond=None)[0]


@nb.njit(**KERNEL)
def refine_upright(xyz: np.ndarray, uv: np.ndarray, K: np.ndarray, roll: float, t: np.ndarray,
                    iterations: int = 10, tol: float = 1e-6):
    """Gauss-Newton on the reprojection error over (roll, t) of the upright pose ``FRONTAL_ROTATION @ Rz(roll)``.

    ``R X + t = (c X_x − s X_y + t_x, −s X_x − c X_y + t_y, t_z − X_z)``; its derivative in the roll is
    ``(−s X_x − c X_y, −c X_x + s X_y, 0)``. Returns (roll, t, converged).
    """
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    JtJ = np.empty((4, 4))
    Jtr = np.empty(4)
    j = np.empty(4)
    for _ in range(iterations):
        c, s = np.cos(roll), np.sin(roll)
        JtJ[:] = 0.0
        Jtr[:] = 0.0
        for i in range(len(xyz)):
            X, Y, Z = xyz[i, 0], xyz[i, 1], xyz[i, 2]
            px, py, pz = c * X - s * Y + t[0], -s * X - c * Y + t[1], t[2] - Z
            if pz <= 0.0:
                return roll, t, False
            iz = 1.0 / pz
            for axis in range(2):
                if axis == 0:
                    f, p, dp, r = fx, px, -s * X - c * Y, fx * px * iz + cx - uv[i, 0]
                    j[1], j[2] = f * iz, 0.0
                else:
                    f, p, dp, r = fy, py, -c * X + s * Y, fy * py * iz + cy - uv[i, 1]
                    j[1], j[2] = 0.0, f * iz
                j[0] = f * dp * iz
                j[3] = -f * p * iz * iz
                for a in range(4):
                    Jtr[a] += j[a] * r
                    for b in range(4):
                        JtJ[a, b] += j[a] * j[b]
        step = solve_spd(JtJ, -Jtr)
        roll += step[0]
        t = t + step[1:]
        if abs(step[0]) < tol and np.sqrt(step[1] ** 2 + step[2] ** 2 + step[3] ** 2) < tol * max(abs(t[2]), 1.0):
            return roll, t, True
    return roll, t, False


@nb.njit(**INNER)
def solve_spd(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x with A x = b for a small symmetric positive definite A (Cholesky, A = L Lᵀ)."""
    n = len(b)
    L = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1):
            s = A[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = np.sqrt(max(s, 1e-300)) if i == j else s / L[j, j]
    y = np.empty(n)
    for i in range(n):
        s = b[i]
        for k in range(i):
            s -= L[i, k] * y[k]
        y[i] = s / L[i, i]
    x = np.empty(n)
    for i in range(n - 1, -1, -1):
        s = y[i]
        for k in range(i + 1, n):
            s -= L[k, i] * x[k]
        x[i] = s / L[i, i]
    return x


@nb.njit(**KERNEL)
def refine_pose(xyz: np.ndarray, uv: np.ndarray, K: np.ndarray, R0: np.ndarray, t0: np.ndarray,
                 iterations: int = 10, tol: float = 1e-5):
    """Gauss-Newton on the reprojection error Σ |π(K (R X + t)) − u|² from (R0, t0).

    Steps are (ω, δt) with R ← exp([ω]×) R, t ← t + δt; ∂P/∂ω = −[R X]×, ∂P/∂t = I for the camera point
    P = R X + t. Returns (R, t, converged); not converged when a point falls behind the camera or the steps
    do not settle (then the caller starts over with the full solver). Settled: a step under ``tol`` radians
    and ``tol`` of the depth (with a performer's own layout the residual stays large and Gauss-Newton converges
    only linearly, so a tighter ``tol`` sends frames back to the full solver).
    """
    n = len(xyz)
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    R = R0.copy()
    t = t0.copy()
    JtJ = np.empty((6, 6))
    Jtr = np.empty(6)
    J = np.empty((2, 6))
    q = np.empty(3)
    for _ in range(iterations):
        JtJ[:] = 0.0
        Jtr[:] = 0.0
        for i in range(n):
            for r in range(3):
                q[r] = R[r, 0] * xyz[i, 0] + R[r, 1] * xyz[i, 1] + R[r, 2] * xyz[i, 2]
            px, py, pz = q[0] + t[0], q[1] + t[1], q[2] + t[2]
            if pz <= 1e-9:
                return R, t, False
            iz = 1.0 / pz
            res0 = fx * px * iz + cx - uv[i, 0]
            res1 = fy * py * iz + cy - uv[i, 1]
            # d(u, v)/dP, then dP/dω = -[q]x (columns e_k x q) and dP/dt = I.
            a0, a2 = fx * iz, -fx * px * iz * iz
            b1, b2 = fy * iz, -fy * py * iz * iz
            J[0, 0], J[0, 1], J[0, 2] = a2 * q[1], a0 * q[2] - a2 * q[0], -a0 * q[1]
            J[1, 0], J[1, 1], J[1, 2] = -b1 * q[2] + b2 * q[1], -b2 * q[0], b1 * q[0]
            J[0, 3], J[0, 4], J[0, 5] = a0, 0.0, a2
            J[1, 3], J[1, 4], J[1, 5] = 0.0, b1, b2
            for k in range(6):
                Jtr[k] += J[0, k] * res0 + J[1, k] * res1
                for m in range(6):
                    JtJ[k, m] += J[0, k] * J[0, m] + J[1, k] * J[1, m]
        for k in range(6):
            JtJ[k, k] += 1e-9
        step = solve_spd(JtJ, -Jtr)
        w0, w1, w2 = step[0], step[1], step[2]
        theta = np.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
        W = np.array([[0.0, -w2, w1], [w2, 0.0, -w0], [-w1, w0, 0.0]])
        if theta > 1e-12:
            E = np.eye(3) + np.sin(theta) / theta * W + (1.0 - np.cos(theta)) / theta ** 2 * (W @ W)
        else:
            E = np.eye(3) + W
        R = E @ R
        t = t + step[3:]
        if theta < tol and np.sqrt(step[3] ** 2 + step[4] ** 2 + step[5] ** 2) < tol * max(abs(t[2]), 1.0):
            return R, t, True
    return R, t, False


@nb.njit(**KERNEL)
def reprojection_error(xyz: np.ndarray, uv: np.ndarray, K: np.ndarray, R: np.ndarray, t: np.ndarray) -> float:
    """Mean distance (pixels) between the image points uv (N, 2) and the head points xyz (N, 3) projected."""
    total = 0.0
    p = np.empty(3)
    for i in range(len(xyz)):
        for r in range(3):
            p[r] = R[r, 0] * xyz[i, 0] + R[r, 1] * xyz[i, 1] + R[r, 2] * xyz[i, 2] + t[r]
        z = K[2, 0] * p[0] + K[2, 1] * p[1] + K[2, 2] * p[2]
        du = (K[0, 0] * p[0] + K[0, 1] * p[1] + K[0, 2] * p[2]) / z - uv[i, 0]
        dv = (K[1, 0] * p[0] + K[1, 1] * p[1] + K[1, 2] * p[2]) / z - uv[i, 1]
        total += np.sqrt(du * du + dv * dv)
    return total / len(xyz)
