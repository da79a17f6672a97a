"""The regional mapping: each region of the character gets its own weights from its own feature points.

With region masks M_k (R, V), background k = 0 first (:mod:`facepuppet.mapping._regions`), region k's weights
w_k come from a :class:`~facepuppet.mapping._methods.BoundedSolver` fitted on the examples' displacements with
region k's point weights ω_k applied per coordinate (points of region k weigh 1, the others ``leak``; the
background weighs all points 1, so its weights are the global mapping's). Key-models that do not move region
k get weight 0 there (``support_tol``), and so do the examples that do not move region k's weighted points
(under ``STILL_SHARE`` of the largest): they are left out of region k's solver. The character is then

    T = T_B + sum_k sum_i M_k (.) w_ik (T_i - T_B)

linear in the key-models (morph targets M_k (.) (T_i - T_B), weights w_ik).

Region k's noise ridge divides its weighted residual by N - M, as the global solver. With ``region_share``
s < 1 a region's final weights are support_k (.) ((1 - s) w_0 + s w_k): its own solve
shrunk towards the global one (both reproduce the neutral face and the examples, so the blend does too).

Guarantees: each region's solver reproduces the neutral face (w_k = 0) and each example (w_k = e_i) exactly,
so the neutral face maps to T_B and key expression i to T_i, except for the motion of key-model i in regions
it does not move (below ``support_tol`` of its largest motion, by definition of not moving them).

Per frame all regions are solved at once: one matrix product gives every region's right-hand side and
parameters, another its weighted norm, and one compiled pass solves the R box QPs
(:mod:`facepuppet.mapping._regional_kernel`; :meth:`RegionalSolver.reference` is the same in numpy).
"""

from __future__ import annotations

import numpy as np

from facepuppet.errors import FacepuppetError
from facepuppet.mapping._boxqp import solve_box_qp
from facepuppet.mapping._params import STILL_SHARE
from facepuppet.mapping._regional_kernel import solve_regions
from facepuppet.mapping._regions import motion_regions, point_weights, region_support

__all__ = ["RegionalSolver"]


class RegionalSolver:
    """Stacked bounded solvers, one per region (module docstring)."""

    kind = "regional"
    needs_target = True

    def __init__(self, *, Fs, G, H, Hd, omega, whiten, bounds, angle_ridge, noise_ridge, support, masks,
                 region_names, owner, share=1.0) -> None:
        self.Fs, self.G, self.H, self.Hd = Fs, G, H, Hd
        self.omega, self.whiten = omega, whiten
        M = H.shape[-1]
        self.lo, self.hi = np.full(M, float(bounds[0])), np.full(M, float(bounds[1]))
        self.angle_ridge, self.noise_ridge = float(angle_ridge), float(noise_ridge)
        self.support = np.asarray(support, dtype=bool)
        self.masks = masks
        self.region_names = tuple(region_names)
        self.owner = owner
        self.share = float(share)
        self._support_f = self.support.astype(float)
        # The residual's degrees of freedom of the noise ridge: N - M in every region, as the global solver.
        self.dof = np.full(len(H), float(max(G.shape[1] - H.shape[-1], 1)))
        # A_k = diag(ω_k) whiten: the region's view of the (scaled) displacement.
        self._A = None if whiten is None else omega[:, :, None] * whiten[None]
        # The compiled path's layout: every region's d G_k and ||d_k||^2 from one product each.
        R, N, M2 = G.shape
        self._G_all = np.ascontiguousarray(G.transpose(1, 0, 2).reshape(N, R * M2))
        self._omega2 = np.ascontiguousarray((omega**2).T)
        self._A_all = None if self._A is None else np.ascontiguousarray(self._A.transpose(1, 0, 2).reshape(N, -1))
        # Examples each region's solver kept: the others have a zero column in G and an identity row in H.
        keep = (G[:, :, :M] != 0).any(axis=1) | (H != np.eye(M)[None]).any(axis=2) | (Hd != 0).any(axis=2)
        self._n_kept = keep.sum(axis=1).astype(np.int64)
        self._kept = np.zeros((R, M), dtype=np.int64)
        for k in range(R):
            self._kept[k, : self._n_kept[k]] = np.flatnonzero(keep[k])
        self._H_c, self._Hd_c = np.ascontiguousarray(H, dtype=float), np.ascontiguousarray(Hd, dtype=float)
        self(np.zeros((1, N)))  # loads the compiled kernel now (a fraction of a second), not on the first frame

    @property
    def F(self) -> np.ndarray:
        """The background's (global) feature matrix."""
        return self.Fs[0]

    @property
    def example_params(self) -> np.ndarray:
        return self._P0

    @classmethod
    def fit(cls, V: np.ndarray, opts: dict, names: tuple[str, ...] | None, *, part: type, whiten, source_deltas,
            target_deltas, target_base, masks=None, region_names=None) -> RegionalSolver:
        """Fit from V (M, N) (scaled, not whitened); ``part`` is the per-region solver class (BoundedSolver)."""
        if masks is None:
            masks, region_names = motion_regions(target_base, target_deltas, names,
                                                 n_regions=int(opts["n_regions"]))
        elif region_names is None:
            region_names = ("background",) + tuple(f"region{k}" for k in range(1, len(masks)))
        omega_p, owner = point_weights(source_deltas, target_deltas, masks, float(opts["leak"]))
        dim = source_deltas.shape[2]
        omega = np.repeat(omega_p, dim, axis=1)                              # (R, N) per coordinate
        sub = {**opts, "ridge": 0.0, "correct": False}
        M, N = V.shape
        R = len(masks)
        Fs, G, H, Hd = np.zeros((R, M, N)), np.zeros((R, N, 2 * M)), np.zeros((R, M, M)), np.zeros((R, M, M))
        keep_all = np.zeros((R, M), dtype=bool)
        for k in range(R):
            Vk = V * omega[k]
            if whiten is not None:
                Vk = Vk @ whiten
            norms = np.linalg.norm(Vk, axis=1)
            keep = norms >= STILL_SHARE * norms.max() if k else np.ones(M, dtype=bool)
            try:
                s = part.fit(Vk[keep], sub, None if names is None else tuple(np.array(names)[keep]))
            except FacepuppetError:
                if k == 0:
                    raise
                # this region's points alone cannot tell its examples apart: it takes the global weights
                omega[k], keep = 1.0, np.ones(M, dtype=bool)
                s = part.fit(V if whiten is None else V @ whiten, sub, names)
            j = np.flatnonzero(keep)
            n = len(j)
            Fs[k, :n] = s.F
            G[k][:, j], G[k][:, M + j[: s.F.shape[0]]] = s.G[:, :n], s.G[:, n:]
            H[k] = np.eye(M)                          # examples the region's points do not see: w = 0 there
            H[k][np.ix_(j, j)], Hd[k][np.ix_(j, j)] = s.H, s.Hd
            keep_all[k] = keep
            if k == 0:
                P0 = s.P
        if whiten is not None:
            G = np.einsum("nm,rmj->rnj", whiten, G)
        G = omega[:, :, None] * G
        support = region_support(target_deltas, masks, float(opts["support_tol"])) & keep_all
        solver = cls(Fs=Fs, G=G, H=H, Hd=Hd, omega=omega, whiten=whiten, bounds=opts["bounds"],
                     angle_ridge=opts["angle_ridge"], noise_ridge=opts.get("noise_ridge", 0.0), support=support,
                     masks=masks, region_names=region_names, owner=owner, share=opts.get("region_share", 1.0))
        solver._P0 = P0
        return solver

    def __call__(self, D: np.ndarray) -> np.ndarray:
        """(F, N) displacement vectors (scaled, not whitened) -> (F, R, M) weights (compiled; module notes)."""
        R, N, M2 = self.G.shape
        D = np.ascontiguousarray(D, dtype=float)
        F = len(D)
        Z = (D @ self._G_all).reshape(F, R, M2)
        if self._A_all is None:
            norm2 = (D * D) @ self._omega2
        else:
            E = (D @ self._A_all).reshape(F, R, N)
            norm2 = np.einsum("frn,frn->fr", E, E)
        out = np.empty((F, R, M2 // 2))
        status = np.empty((F, R), dtype=np.int64)
        solve_regions(Z, np.ascontiguousarray(norm2), self._H_c, self._Hd_c, self._kept, self._n_kept, self.lo,
                      self.hi, self.angle_ridge, self.noise_ridge, self.dof, self._support_f, out, status)
        hard = np.flatnonzero(status.any(axis=1))
        if hard.size:  # unsettled or not positive definite: the numpy solver finishes those frames exactly
            out[hard] = self._own_weights(D[hard])
        return self._shared(out)

    def reference(self, D: np.ndarray) -> np.ndarray:
        """The same weights as :meth:`__call__` in plain numpy: stacked products, one batched box QP."""
        return self._shared(self._own_weights(D))

    def _shared(self, w: np.ndarray) -> np.ndarray:
        """w_k = support_k ⊙ ((1 − share) w_0 + share w_k) for k >= 1 (``region_share``), in place."""
        if self.share != 1.0:
            w[:, 1:] = ((1.0 - self.share) * w[:, :1] + self.share * w[:, 1:]) * self._support_f[1:]
        return w

    def _own_weights(self, D: np.ndarray) -> np.ndarray:
        """Each region's own weights (share 1) in numpy."""
        R, N, M2 = self.G.shape
        M = M2 // 2
        Z = np.einsum("fn,rnj->frj", D, self.G)
        b, p = Z[..., :M], Z[..., M:]
        H = np.broadcast_to(self.H[None], (len(D), R, M, M))
        if self.angle_ridge or self.noise_ridge:
            Dk = D[:, None, :] * self.omega[None] if self._A is None else np.einsum("fn,rnm->frm", D, self._A)
            norm2 = np.einsum("frn,frn->fr", Dk, Dk)
            out2 = np.maximum(norm2 - np.einsum("frm,frm->fr", p, p), 0.0)
            sin = np.sqrt(out2 / np.where(norm2 > 0.0, norm2, 1.0))
            H = H + (self.angle_ridge * np.minimum(sin, 1.0))[..., None, None] * self.Hd[None]
            if self.noise_ridge:
                sigma2 = out2 / self.dof[None]
                H = H + (self.noise_ridge * sigma2)[..., None, None] * np.eye(M)
        w = solve_box_qp(np.ascontiguousarray(H).reshape(-1, M, M), b.reshape(-1, M), self.lo, self.hi)
        return w.reshape(len(D), R, M) * self._support_f

    def to_arrays(self) -> dict[str, np.ndarray]:
        out = {"Fs": self.Fs, "G": self.G, "H": self.H, "Hd": self.Hd, "omega": self.omega,
               "bounds": np.array([self.lo[0], self.hi[0]]), "angle_ridge": np.array(self.angle_ridge),
               "noise_ridge": np.array(self.noise_ridge), "support": self.support, "masks": self.masks,
               "region_names": np.array(self.region_names, dtype=str), "owner": self.owner, "P0": self._P0,
               "share": np.array(self.share)}
        if self.whiten is not None:
            out["whiten"] = self.whiten
        return out

    @classmethod
    def from_arrays(cls, a: dict[str, np.ndarray]) -> RegionalSolver:
        s = cls(Fs=a["Fs"], G=a["G"], H=a["H"], Hd=a["Hd"], omega=a["omega"], whiten=a.get("whiten"),
                bounds=a["bounds"], angle_ridge=float(a["angle_ridge"]), noise_ridge=float(a["noise_ridge"]),
                support=a["support"], masks=a["masks"], region_names=tuple(str(n) for n in a["region_names"]),
                owner=a["owner"], share=float(a.get("share", 1.0)))
        s._P0 = a["P0"]
        return s
