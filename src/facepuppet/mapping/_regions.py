"""Regions of a character from its key-models alone, and which feature points belong to which region.

Region masks (the mapping's arrays-only stand-in for the wires' influence, ``synthesis.region_masks``):
greedily, with m_i(v) = ||T_i(v) - T_B(v)|| and the uncovered motion c = m (initially), each step takes the
key-model i0 and vertex v0 of largest c; its core C is the set of vertices with m_i0 >= ``core`` * m_i0(v0);
its influence is F(v) = f(dist(v, C) / rho), f the wires' falloff (1 - x^2)^2 on [0, 1), dist the distance to
the nearest core vertex on T_B and rho = ``reach`` times the core's radius (largest distance of a core vertex
from the core's centroid). Then c is multiplied by 1 - F and key-model i0 is done. A region is named
after the key-model that placed it (:func:`region_name`: ``jaw``, ``mouth_L``, ``eye_R``, ``brow``;
``region<k>`` without key-model names). The masks are those of
``synthesis.region_masks``:

    M_k = F_k / max(1, sum_j F_j),    M_0 = 1 - sum_k M_k     (M_0 the background)

Feature point -> region (learnt from the examples): point p's motion profile a_p(i) = ||S_i(p) - S_B(p)||
and region k's b_k(i) = max_v M_k(v) m_i(v) (both over the M examples); p belongs to the region k >= 1 whose
profile has the largest cosine similarity with its own. In region k the point weighs 1 if it belongs to k,
``leak`` otherwise; the background weighs every point 1 (the global mapping).
"""

from __future__ import annotations

import re

import numpy as np

__all__ = ["motion_regions", "region_name", "masks_from_influence", "point_weights", "region_support",
           "region_shares"]


def _falloff(x: np.ndarray) -> np.ndarray:
    """f(x) = (1 - x^2)^2 on [0, 1), 0 beyond (the wires' default falloff)."""
    x = np.clip(np.abs(x), 0.0, 1.0)
    return (1.0 - x * x) ** 2


def region_name(key_name: str) -> str:
    """A region's name from the key-model that placed it: its leading lowercase word and its side.

    ``jawOpen`` -> ``jaw``, ``mouthSmile_L`` -> ``mouth_L``, ``eyeBlink_R`` -> ``eye_R``, ``browInnerUp`` ->
    ``brow``; a name without a lowercase start is kept whole.
    """
    side = key_name[-2:] if key_name.endswith(("_L", "_R")) else ""
    word = re.match(r"[a-z]+", key_name)
    return (word.group(0) if word else key_name[: len(key_name) - len(side)]) + side


def masks_from_influence(influence: np.ndarray) -> np.ndarray:
    """(n, V) influence in [0, 1] -> (n + 1, V) masks, background first, columns summing to 1."""
    total = influence.sum(axis=0)
    m = influence / np.maximum(total, 1.0)
    return np.concatenate([np.clip(1.0 - m.sum(axis=0), 0.0, 1.0)[None], m])


def motion_regions(base: np.ndarray, deltas: np.ndarray, names: tuple[str, ...] | None, *, n_regions: int,
                   core: float = 0.5, reach: float = 0.6, min_motion: float = 0.05
                   ) -> tuple[np.ndarray, tuple[str, ...]]:
    """Region masks of a character from its key-models (module docstring).

    Parameters
    ----------
    base : (V, 3) float
        T_B.
    deltas : (M, V, 3) float
        T_i - T_B.
    names : tuple of M str, optional
        Key-model names; a region is named after the key-model that placed it (else ``region<k>``).
    n_regions : int
        Most regions besides the background.
    core, reach, min_motion : float
        Core threshold (share of the key-model's largest motion), reach of the influence (times the core's
        radius) and the stopping share of the largest motion of all key-models (all dimensionless).

    Returns
    -------
    masks : (R, V) float
        Background first; R <= n_regions + 1.
    region_names : tuple of R str
        ``"background"`` first.
    """
    from scipy.spatial import cKDTree  # here, not at import: loading a fitted rig needs no scipy.spatial

    motion = np.linalg.norm(deltas, axis=2)                                  # (M, V)
    uncovered = motion.copy()
    stop = min_motion * motion.max()
    influence, out_names = [], ["background"]
    for k in range(n_regions):
        i0, v0 = np.unravel_index(int(np.argmax(uncovered)), uncovered.shape)
        if uncovered[i0, v0] <= max(stop, 0.0):
            break
        members = np.flatnonzero(motion[i0] >= core * motion[i0, v0])
        pts = base[members]
        radius = float(np.linalg.norm(pts - pts.mean(axis=0), axis=1).max())
        rho = reach * max(radius, 1e-9 * float(np.ptp(base, axis=0).max()) + 1e-12)
        dist = cKDTree(pts).query(base, distance_upper_bound=rho)[0]
        f = _falloff(np.where(np.isfinite(dist), dist / rho, 1.0))
        influence.append(f)
        uncovered *= 1.0 - f[None]
        uncovered[i0] = 0.0
        name = base_name = region_name(str(names[i0])) if names else f"region{k + 1}"
        n = 2
        while name in out_names:
            name, n = f"{base_name}_{n}", n + 1
        out_names.append(name)
    if not influence:
        return np.ones((1, len(base))), ("background",)
    return masks_from_influence(np.array(influence)), tuple(out_names)


def region_support(deltas: np.ndarray, masks: np.ndarray, tol: float) -> np.ndarray:
    """(R, M) bool: key-model i moves region k (max_v M_k(v) m_i(v) > tol * max_v m_i(v)); background all True."""
    motion = np.linalg.norm(deltas, axis=2)
    peak = motion.max(axis=1)
    regional = (masks[:, None, :] * motion[None]).max(axis=2)
    out = (regional > tol * peak[None]) & (peak[None] > 0)
    out[0] = True
    return out


def region_shares(deltas: np.ndarray, masks: np.ndarray) -> np.ndarray:
    """(R, M) share of each key-model's squared displacement in each region.

    share_ki = sum_v M_k(v) ||d_i(v)||^2 / sum_v ||d_i(v)||^2 (columns sum to 1 with masks summing to 1; a
    key-model that moves nothing has all its share in the background).

    Parameters
    ----------
    deltas : (M, V, 3) float
        T_i - T_B.
    masks : (R, V) float
        Background first.
    """
    energy = np.einsum("mvc,mvc->mv", deltas, deltas)
    total = energy.sum(axis=1)
    out = np.asarray(masks, dtype=float) @ energy.T / np.where(total > 0, total, 1.0)[None]
    out[0, total <= 0] = 1.0
    return out


def point_weights(source_deltas: np.ndarray, deltas: np.ndarray, masks: np.ndarray, leak: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Per-region weight of each feature point, learnt from the examples (module docstring).

    Parameters
    ----------
    source_deltas : (M, P, D) float
        S_i - S_B.
    deltas : (M, V, 3) float
        T_i - T_B.
    masks : (R, V) float
        Background first.
    leak : float
        Weight in region k of a point that belongs to another region.

    Returns
    -------
    weights : (R, P) float
    owner : (P,) int
        The region (>= 1) each point belongs to; 0 when there is no region but the background.
    """
    a = np.linalg.norm(source_deltas, axis=2).T                              # (P, M)
    motion = np.linalg.norm(deltas, axis=2)
    b = (masks[:, None, :] * motion[None]).max(axis=2)                       # (R, M)
    R, P = len(masks), a.shape[0]
    if R == 1:
        return np.ones((1, P)), np.zeros(P, dtype=int)
    an = a / np.maximum(np.linalg.norm(a, axis=1, keepdims=True), 1e-300)
    bn = b[1:] / np.maximum(np.linalg.norm(b[1:], axis=1, keepdims=True), 1e-300)
    owner = 1 + np.argmax(an @ bn.T, axis=1)
    w = np.full((R, P), float(leak))
    w[owner, np.arange(P)] = 1.0
    w[0] = 1.0
    return w, owner
