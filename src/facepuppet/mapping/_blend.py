"""Compiled regional blending: T = T_B + sum_k sum_i M_k (.) w_ik (T_i - T_B), per vertex.

The masks are mostly zero (a vertex lies in the background and one or two regions), so they are kept as a
sparse per-vertex list (CSR: for vertex v, ``regions[indptr[v]:indptr[v+1]]`` and their mask values); each
vertex then costs (its regions + 3) x M multiply-adds.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from facepuppet._util.jit import KERNEL

__all__ = ["sparse_masks", "blend_regions"]


def sparse_masks(masks: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(R, V) masks -> (indptr (V+1,) int64, regions (nnz,) int64, values (nnz,) float64), by vertex."""
    mt = np.ascontiguousarray(masks.T)
    v, r = np.nonzero(mt)
    indptr = np.zeros(mt.shape[0] + 1, dtype=np.int64)
    np.cumsum(np.bincount(v, minlength=mt.shape[0]), out=indptr[1:])
    return indptr, r.astype(np.int64), mt[v, r].astype(np.float64)


@nb.njit(**KERNEL)
def _blend(base, deltas, indptr, regions, values, weights, out):
    n_frames, _, n_keys = weights.shape
    n_vertices = base.shape[0]
    acc = np.empty(n_keys)
    for f in range(n_frames):
        for v in range(n_vertices):
            acc[:] = 0.0
            for j in range(indptr[v], indptr[v + 1]):
                k, m = regions[j], values[j]
                for i in range(n_keys):
                    acc[i] += m * weights[f, k, i]
            x, y, z = base[v, 0], base[v, 1], base[v, 2]
            for i in range(n_keys):
                a = acc[i]
                if a != 0.0:
                    x += a * deltas[i, v, 0]
                    y += a * deltas[i, v, 1]
                    z += a * deltas[i, v, 2]
            out[f, v, 0], out[f, v, 1], out[f, v, 2] = x, y, z


def blend_regions(base: np.ndarray, deltas: np.ndarray, sparse: tuple, weights: np.ndarray) -> np.ndarray:
    """Regional blend of F frames.

    Parameters
    ----------
    base : (V, 3) float64
    deltas : (M, V, 3) float64 (C-contiguous)
    sparse : the output of :func:`sparse_masks`
    weights : (F, R, M) float

    Returns
    -------
    (F, V, 3) float64
    """
    w = np.ascontiguousarray(weights, dtype=np.float64)
    out = np.empty((len(w), base.shape[0], 3))
    _blend(base, deltas, *sparse, w, out)
    return out
