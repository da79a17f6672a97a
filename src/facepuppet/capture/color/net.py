"""The colour-weight network of §3.1: 11 sub-area means -> 10 sigmoid units -> Eq. 1's weights (w1..w4).

Conventions: face crops as made by the colour tracker (upright, ``px`` pixels per face unit, extent
:data:`~facepuppet.capture.color.face.CROP_EXTENT`), RGB uint8.

The paper feeds the network "11 representative intensity values for subareas of each facial feature (skin,
eyes, eyelids, nostrils, a mouth, and so on)". Ours (:data:`SUBAREAS`): the mean luma (0..1) of nine sub-areas
(both cheeks, forehead, both eyes, both upper lids, nostrils, mouth) and, so that the network sees the colour
of the light and not only its strength, the red and blue chromaticity R/(R+G+B), B/(R+G+B) of the cheeks.

Training (:meth:`ColourNet.fit`) averages :data:`N_RESTARTS` 11-10-4 networks fitted from seeded starts. Each
(:func:`fit_member`) minimises, in float64, the mean squared error of the outputs plus a weight decay
``L2_PENALTY`` (Σ w² of both layers and the hidden biases, per sample, so its strength does not shrink as frames
are added), with SciPy's L-BFGS-B run until the gradient vanishes (no loss-change stop). The decay keeps each
minimum isolated and its basin wide, so the fit is deterministic and inputs that differ by rounding (two OpenCV
builds) give the same Eq. 1 weights (a hidden unit in saturation may still drift along a direction that leaves
the outputs unchanged), once each network's hidden units are put in a canonical order and sign
(:func:`canonical_units`: a path that differs by rounding may reach a copy of the minimum with its units
permuted); the average keeps the weights predicted for unseen crops from hanging on one start. The fit runs
BLAS on one thread: a product's sums shared among threads differ in their last bits with the thread count.
The fitted layers are kept as plain arrays, so evaluating needs only numpy and a profile loads without pickle.
Training targets come from :func:`separating_weights` (see :mod:`facepuppet.capture.color.train`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from facepuppet.capture.color.face import CROP_EXTENT

log = logging.getLogger(__name__)

__all__ = ["SUBAREAS", "N_INPUTS", "WEIGHT_SCALE", "ColourNet", "subarea_means", "separating_weights",
           "constrain_weights", "fisher_separation", "fit_member", "canonical_units", "N_RESTARTS"]

#: Sub-areas in face units (x0, y0, x1, y1); the first nine give mean luma, "cheeks" also the chromaticity.
SUBAREAS: dict[str, tuple[float, float, float, float]] = {
    "cheek_left": (0.40, 0.45, 0.75, 0.75),
    "cheek_right": (-0.75, 0.45, -0.40, 0.75),
    "forehead": (-0.40, -0.75, 0.40, -0.50),
    "eye_left": (0.30, -0.10, 0.70, 0.08),
    "eye_right": (-0.70, -0.10, -0.30, 0.08),
    "lid_left": (0.30, -0.24, 0.70, -0.12),
    "lid_right": (-0.70, -0.24, -0.30, -0.12),
    "nostrils": (-0.25, 0.68, 0.25, 0.85),
    "mouth": (-0.35, 1.05, 0.35, 1.35),
}
N_INPUTS = 11

#: Sum of |w_i| every weight vector is scaled to (the contrast C makes the scale irrelevant; this fixes it).
WEIGHT_SCALE = 2.4

_LUMA = np.array([0.299, 0.587, 0.114], dtype=np.float32)

# Tuning constants            unit        what it does
N_HIDDEN = 10                 # units       hidden sigmoid units of the network (§3.1: 11-10-4)
MIN_VALUE_WEIGHT = 0.05       # fraction    of WEIGHT_SCALE the value weight w3 stays below zero by
L2_PENALTY = 3e-4             # 1/sample    weight decay 0.5 L2_PENALTY Σ w² (no output bias) + 0.5 mean Σ (out − y)²
MAX_ITERATIONS = 20000        # steps       most L-BFGS iterations of the training
GRADIENT_TOLERANCE = 1e-9     # -           the training stops when every gradient component is below this
N_RESTARTS = 5                # networks    seeded 11-10-4 fits whose outputs are averaged
MIN_INPUT_STD = 1e-3          # -           floor of an input's standard deviation in the normalisation


def _box(box, px, shape):
    h, w = shape[:2]
    x0 = min(max(int(round((box[0] - CROP_EXTENT[0]) * px)), 0), w - 1)
    y0 = min(max(int(round((box[1] - CROP_EXTENT[1]) * px)), 0), h - 1)
    x1 = min(max(int(round((box[2] - CROP_EXTENT[0]) * px)), x0 + 1), w)
    y1 = min(max(int(round((box[3] - CROP_EXTENT[1]) * px)), y0 + 1), h)
    return x0, y0, x1, y1


def subarea_means(crop: np.ndarray, px: float) -> np.ndarray:
    """The network's 11 inputs for one face crop.

    Parameters
    ----------
    crop : (H, W, 3) uint8
        Upright face crop, ``px`` pixels per face unit.
    px : float

    Returns
    -------
    (11,) float32
    """
    out = np.empty(N_INPUTS, dtype=np.float32)
    cheeks = []
    for k, (name, box) in enumerate(SUBAREAS.items()):
        x0, y0, x1, y1 = _box(box, px, crop.shape)
        mean_rgb = crop[y0:y1, x0:x1].reshape(-1, 3).mean(axis=0) / 255.0
        out[k] = float(mean_rgb @ _LUMA)
        if name.startswith("cheek"):
            cheeks.append(mean_rgb)
    c = np.mean(cheeks, axis=0)
    s = max(float(c.sum()), 1e-6)
    out[9], out[10] = c[0] / s, c[2] / s
    return out


def constrain_weights(w: np.ndarray) -> np.ndarray:
    """Eq. 1's signs (w1, w2, w4 >= 0, w3 < 0) and the fixed scale :data:`WEIGHT_SCALE`.

    Parameters
    ----------
    w : (..., 4) float

    Returns
    -------
    (..., 4) float32
    """
    w = np.array(w, dtype=np.float64)
    w[..., [0, 1, 3]] = np.maximum(w[..., [0, 1, 3]], 0.0)
    w[..., 2] = np.minimum(w[..., 2], -MIN_VALUE_WEIGHT * WEIGHT_SCALE)
    w *= WEIGHT_SCALE / np.abs(w).sum(axis=-1, keepdims=True)
    return w.astype(np.float32)


def separating_weights(feature: np.ndarray, skin: np.ndarray, ridge: float = 1e-3) -> np.ndarray:
    """The weights of Eq. 1 that best separate feature pixels from skin pixels (Fisher's discriminant).

    w ∝ (Σ_f + Σ_s + ridge I)⁻¹ (μ_f − μ_s) over the channels (M, K, V, G(H)), then :func:`constrain_weights`.
    Since K = 1 − V the covariance is singular; the ridge splits the V direction evenly between w2 and w3.

    Parameters
    ----------
    feature, skin : (N, 4) float
        Channel values (M, K, V, G) of feature pixels and of skin pixels.
    ridge : float

    Returns
    -------
    (4,) float32
    """
    f, s = np.asarray(feature, dtype=float), np.asarray(skin, dtype=float)
    cov = np.cov(f.T) + np.cov(s.T) + ridge * np.eye(4)
    w = np.linalg.solve(cov, f.mean(axis=0) - s.mean(axis=0))
    return constrain_weights(w)


def fisher_separation(intensity_feature: np.ndarray, intensity_skin: np.ndarray) -> float:
    """Fisher's separation (μ_f − μ_s)² / (σ_f² + σ_s²) of feature and skin intensities (higher is better)."""
    a, b = np.asarray(intensity_feature, dtype=float), np.asarray(intensity_skin, dtype=float)
    return float((a.mean() - b.mean()) ** 2 / max(a.var() + b.var(), 1e-12))


@dataclass(frozen=True)
class ColourNet:
    """The trained 11-10-4 network as arrays (standardised inputs, logistic hidden layer, linear outputs).

    Attributes
    ----------
    w0 : (11, H) float
    b0 : (H,) float
    w1 : (H, 4) float
        H = 10 per averaged 11-10-4 network (:data:`N_RESTARTS` of them; a multiple of 10 is read).
    b1 : (4,) float
    x_mean, x_std : (11,) float
        Input standardisation.
    """

    w0: np.ndarray
    b0: np.ndarray
    w1: np.ndarray
    b1: np.ndarray
    x_mean: np.ndarray
    x_std: np.ndarray

    def predict(self, x: np.ndarray) -> np.ndarray:
        """Weights (w1..w4) for inputs ``x`` (11,) or (N, 11) -> (4,) or (N, 4) float32, constrained."""
        z = (np.asarray(x, dtype=float) - self.x_mean) / self.x_std
        h = 1.0 / (1.0 + np.exp(-(z @ self.w0 + self.b0)))
        return constrain_weights(h @ self.w1 + self.b1)

    def to_arrays(self) -> dict[str, np.ndarray]:
        return {k: np.asarray(getattr(self, k), dtype=np.float64) for k in ("w0", "b0", "w1", "b1", "x_mean", "x_std")}

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> ColourNet:
        """Rebuild from :meth:`to_arrays`; raises ValueError naming a missing or misshapen array."""
        hidden = int(np.shape(arrays["b0"])[0]) if "b0" in arrays and np.ndim(arrays["b0"]) == 1 else N_HIDDEN
        if hidden < N_HIDDEN or hidden % N_HIDDEN:
            raise ValueError(f"colour network: array 'b0' must hold a multiple of {N_HIDDEN} hidden units, got "
                             f"{hidden}")
        shapes = {"w0": (N_INPUTS, hidden), "b0": (hidden,), "w1": (hidden, 4), "b1": (4,), "x_mean": (N_INPUTS,),
                  "x_std": (N_INPUTS,)}
        out = {}
        for k, shape in shapes.items():
            if k not in arrays:
                raise ValueError(f"colour network: array {k!r} is missing")
            a = np.asarray(arrays[k], dtype=float)
            if a.shape != shape:
                raise ValueError(f"colour network: array {k!r} must have shape {shape}, got {a.shape}")
            out[k] = a
        return cls(**out)

    @classmethod
    def fit(cls, x: np.ndarray, y: np.ndarray, *, seed: int = 0) -> ColourNet:
        """Train on inputs (N, 11) and target weights (N, 4): the average of :data:`N_RESTARTS` 11-10-4 networks
        (:func:`fit_member`, seeds ``seed``, ``seed + 1``, ...), kept as one network whose hidden layer holds
        theirs side by side and whose output layer is the mean of theirs (the same outputs as averaging them).
        """
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        if x.ndim != 2 or x.shape[1] != N_INPUTS or y.shape != (len(x), 4) or len(x) < 1:
            raise ValueError(f"x must be (N, {N_INPUTS}) and y (N, 4), got {x.shape} and {y.shape}")
        from threadpoolctl import threadpool_limits

        mean, std = x.mean(axis=0), np.maximum(x.std(axis=0), MIN_INPUT_STD)
        # One BLAS thread whatever the process allows (a batch worker's one, a many-core machine's): the same fit.
        with threadpool_limits(limits=1, user_api="blas"):
            members = [fit_member((x - mean) / std, y, seed + k) for k in range(N_RESTARTS)]
        w0 = np.concatenate([m[0] for m in members], axis=1)
        b0 = np.concatenate([m[1] for m in members])
        w1 = np.concatenate([m[2] for m in members]) / N_RESTARTS
        b1 = np.mean([m[3] for m in members], axis=0)
        return cls(w0, b0, w1, b1, mean, std)


def fit_member(z: np.ndarray, y: np.ndarray, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One 11-10-4 network on standardised inputs ``z`` (N, 11) and targets ``y`` (N, 4): (w0, b0, w1, b1).

    Minimises 0.5 mean Σ (out − y)² + 0.5 ``L2_PENALTY`` Σ w² (all weights and the hidden biases) with SciPy's
    L-BFGS-B until the gradient vanishes; deterministic: the start is drawn from ``seed`` (input weights
    N(0, 1/11), output weights N(0, 1/10), hidden biases 0, output biases the targets' mean).
    """
    from scipy.optimize import minimize

    n = len(z)
    sizes = (N_INPUTS * N_HIDDEN, N_HIDDEN, N_HIDDEN * 4, 4)
    cuts = np.cumsum(sizes)[:-1]

    def unpack(theta):
        w0, b0, w1, b1 = np.split(theta, cuts)
        return w0.reshape(N_INPUTS, N_HIDDEN), b0, w1.reshape(N_HIDDEN, 4), b1

    def loss_and_gradient(theta):
        w0, b0, w1, b1 = unpack(theta)
        h = 1.0 / (1.0 + np.exp(-(z @ w0 + b0)))
        e = (h @ w1 + b1 - y) / n
        decay = float(np.sum(w0 * w0) + np.sum(b0 * b0) + np.sum(w1 * w1))
        loss = 0.5 * n * float(np.sum(e * e)) + 0.5 * L2_PENALTY * decay
        dh = (e @ w1.T) * h * (1.0 - h)
        grad = np.concatenate([(z.T @ dh + L2_PENALTY * w0).ravel(), dh.sum(axis=0) + L2_PENALTY * b0,
                               (h.T @ e + L2_PENALTY * w1).ravel(), e.sum(axis=0)])
        return loss, grad

    rng = np.random.default_rng(seed)
    start = np.concatenate([rng.normal(size=sizes[0]) / np.sqrt(N_INPUTS), np.zeros(N_HIDDEN),
                            rng.normal(size=sizes[2]) / np.sqrt(N_HIDDEN), y.mean(axis=0)])
    result = minimize(loss_and_gradient, start, jac=True, method="L-BFGS-B",
                      options={"maxiter": MAX_ITERATIONS, "maxfun": 2 * MAX_ITERATIONS, "ftol": 0.0,
                               "gtol": GRADIENT_TOLERANCE, "maxcor": 30})
    if not result.success:
        log.warning("colour network: the fit stopped before its gradient vanished (%s)", result.message)
    return canonical_units(*unpack(result.x))


def canonical_units(w0: np.ndarray, b0: np.ndarray, w1: np.ndarray, b1: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The same network (w0 (11, H), b0 (H,), w1 (H, 4), b1 (4,)) with its hidden units in a canonical form.

    A sigmoid layer computes the same outputs, at the same weight decay, with its units in any order and any
    unit's sign flipped (σ(−a) = 1 − σ(a): w0, b0, w1 of the unit negated and its w1 added to b1), so fits
    that differ only by rounding may land on such copies of one minimum. Each unit is turned so that its input
    weight of largest magnitude is positive, and the units are ordered by the norm of their input weights and
    bias, largest first.
    """
    w0, b0, w1, b1 = (np.array(a, dtype=np.float64) for a in (w0, b0, w1, b1))
    flip = w0[np.argmax(np.abs(w0), axis=0), np.arange(w0.shape[1])] < 0
    b1 = b1 + w1[flip].sum(axis=0)
    sign = np.where(flip, -1.0, 1.0)
    w0, b0, w1 = w0 * sign, b0 * sign, w1 * sign[:, None]
    order = np.argsort(-np.hypot(np.linalg.norm(w0, axis=0), b0), kind="stable")
    return w0[:, order], b0[order], w1[order], b1
