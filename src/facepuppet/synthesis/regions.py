"""Regional (non-uniform) blending: the wires' influence as a partition of unity over the face.

With F_k (n_wires, V) the wires' influence (:meth:`WireDeformer.influence`), the region masks are

    M_k = F_k / max(1, sum_j F_j)       k = 1 .. n_wires
    M_0 = 1 - sum_k M_k                 (the background: what no wire reaches fully)

so M_k >= 0 and sum_k M_k = 1 at every vertex; they are continuous (C1 wherever sum_j F_j != 1). Each region
gets its own weights w_ik of the key-models, and the blend

    T = T_B + sum_k sum_i M_k (.) w_ik (T_i - T_B)                  ((.) per vertex)

stays linear in the key-models: it is Eq. 14 with the per-vertex weights W(v)_i = sum_k M_k(v) w_ik, and a
glTF file plays it with the morph targets M_k (.) (T_i - T_B) (:func:`split_targets`) and weights w_ik.
With w_ik = w_i in every region it is Eq. 14 itself, so the neutral face maps to T_B and a key expression
(w = e_i everywhere) to T_i exactly.
"""

from __future__ import annotations

import numpy as np

__all__ = ["region_masks", "region_support", "regional_blend", "split_targets"]


def _check_masks(masks, n_vertices: int | None = None) -> np.ndarray:
    m = np.asarray(masks, dtype=float)
    if m.ndim != 2 or (n_vertices is not None and m.shape[1] != n_vertices):
        want = f"(R, {n_vertices})" if n_vertices is not None else "(R, V)"
        raise ValueError(f"masks must have shape {want}, got {np.shape(masks)}")
    if not np.isfinite(m).all():
        raise ValueError("masks must be finite")
    return m


def region_masks(influence) -> np.ndarray:
    """Region masks from the wires' influence: a partition of unity with a background region first.

    Parameters
    ----------
    influence : (n_wires, V) array_like
        F_k(v) in [0, 1].

    Returns
    -------
    (n_wires + 1, V) float
        Row 0 the background M_0, row k the mask M_k of wire k - 1 (module docstring); columns sum to 1.
    """
    f = np.asarray(influence, dtype=float)
    if f.ndim != 2 or not np.isfinite(f).all() or (f < 0).any() or (f > 1).any():
        raise ValueError(f"influence must be a finite (n_wires, V) array in [0, 1], got shape {np.shape(influence)}")
    total = f.sum(axis=0)
    m = f / np.maximum(total, 1.0)
    return np.concatenate([np.clip(1.0 - m.sum(axis=0), 0.0, 1.0)[None], m])


def region_support(deltas, masks, *, tol: float = 1e-3) -> np.ndarray:
    """Which key-models move which regions.

    Parameters
    ----------
    deltas : (M, V, 3) array_like
        T_i - T_B.
    masks : (R, V) array_like
        Region masks.
    tol : float
        Key-model i moves region k when max_v M_k(v) ||T_i(v) - T_B(v)|| > tol * max_v ||T_i(v) - T_B(v)||.

    Returns
    -------
    (R, M) bool
        A region a key-model does not move should take no weight from it (w_ik = 0).
    """
    d = np.asarray(deltas, dtype=float)
    if d.ndim != 3 or d.shape[2] != 3:
        raise ValueError(f"deltas must have shape (M, V, 3), got {np.shape(deltas)}")
    m = _check_masks(masks, d.shape[1])
    motion = np.linalg.norm(d, axis=2)                                   # (M, V)
    peak = motion.max(axis=1)                                            # (M,)
    regional = (m[:, None, :] * motion[None]).max(axis=2)                # (R, M)
    return (regional > tol * peak[None]) & (peak[None] > 0)


def regional_blend(neutral, deltas, masks, weights) -> np.ndarray:
    """T = T_B + sum_k sum_i M_k (.) w_ik (T_i - T_B).

    Parameters
    ----------
    neutral : (V, 3) array_like
        T_B.
    deltas : (M, V, 3) array_like
        T_i - T_B.
    masks : (R, V) array_like
        Region masks (a partition of unity, e.g. :func:`region_masks`).
    weights : (R, M) array_like, or (F, R, M) for F frames
        w_ik per region and key-model.

    Returns
    -------
    (V, 3) float, or (F, V, 3)
    """
    tb = np.asarray(neutral, dtype=float)
    d = np.asarray(deltas, dtype=float)
    if tb.ndim != 2 or tb.shape[1] != 3:
        raise ValueError(f"neutral must have shape (V, 3), got {np.shape(neutral)}")
    if d.shape[1:] != tb.shape or d.ndim != 3:
        raise ValueError(f"deltas must have shape (M, {len(tb)}, 3), got {np.shape(deltas)}")
    m = _check_masks(masks, len(tb))
    w = np.asarray(weights, dtype=float)
    if w.shape[-2:] != (len(m), len(d)) or w.ndim not in (2, 3):
        raise ValueError(f"weights must have shape ({len(m)}, {len(d)}) or (F, {len(m)}, {len(d)}), "
                         f"got {np.shape(weights)}")
    per_vertex = np.einsum("rv,...ri->...vi", m, w)                      # W(v)_i = sum_k M_k(v) w_ik
    return tb + np.einsum("...vi,ivc->...vc", per_vertex, d)


def split_targets(deltas, masks) -> np.ndarray:
    """Morph targets split by region: M_k (.) (T_i - T_B), region-major.

    Parameters
    ----------
    deltas : (M, V, 3) array_like
    masks : (R, V) array_like

    Returns
    -------
    (R * M, V, 3) float
        Target k * M + i is region k's part of key-model i; with the weights ``w.reshape(-1)`` of an (R, M)
        array, T_B + sum of weight times target equals :func:`regional_blend`.
    """
    d = np.asarray(deltas, dtype=float)
    if d.ndim != 3 or d.shape[2] != 3:
        raise ValueError(f"deltas must have shape (M, V, 3), got {np.shape(deltas)}")
    m = _check_masks(masks, d.shape[1])
    return (m[:, None, :, None] * d[None]).reshape(-1, *d.shape[1:])
