"""Feature curves as Bezier snakes (paper §3.3, Eqs. 2-4), minimised for many curves at once.

Conventions: image pixels, x right, y down. A curve is four control points (4, 2); a batch is (C, 4, 2).

Each curve v(s) minimises

    E(v) = Σ_s  -w_edge |∇I(v(s))|²  +  w_out I(v_out(s))  -  w_in I(v_in(s))          (Eqs. 2-4)

where I is the (blurred) feature intensity of Eq. 1, and v_in / v_out are the offset curves made by shifting
the two middle control points by ±``offset`` pixels along the head's up-vector: for the upper boundary of a
feature (curve A of the paper's Fig. 3) the inner curve lies below it (against the up-vector), for a lower
boundary (curve B) above it. With w_in > w_out the constraint term is negative only where the inner curve
lies in the feature and the outer one on skin, which tells curve A from curve B although both sit on edges.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import cv2
import numba as nb
import numpy as np

from facepuppet._util.jit import INNER, KERNEL
from facepuppet.capture.color.rules.kernels import median
from facepuppet.capture.curves import CURVE_NAMES, bernstein

__all__ = ["SnakeConfig", "SnakeSolver", "snake_fields", "snake_energy", "minimise_snakes", "box_guess", "lip_field",
           "UPPER", "LOWER"]

_LIP_IDX = {n: i for i, n in enumerate(CURVE_NAMES) if n.startswith("lip_")}

#: The feature lies below the curve (the curve is its upper boundary, curve A of Fig. 3).
UPPER = 1.0
#: The feature lies above the curve (the curve is its lower boundary, curve B of Fig. 3).
LOWER = -1.0


@dataclass(frozen=True)
class SnakeConfig:
    """Options of the snake minimisation.

    Attributes
    ----------
    w_edge : float
        w of Eq. 3, on |∇I|² (I in [0, 1] per pixel).
    w_in, w_out : float
        Eq. 4's weights of the inner and outer offset curves (w_in > w_out).
    offset : float
        How far the middle control points are shifted to make the offset curves, pixels.
    samples : int
        Samples along each curve (the integral of Eq. 2 becomes a sum).
    iterations : int
        Downhill steps.
    step : float
        Length of the first step in pixels; steps shrink geometrically to ``step * decay**iterations``.
    decay : float
    move_ends : bool
        Let the end control points move too (else only the middle two).
    """

    w_edge: float = 4.0
    w_in: float = 1.0
    w_out: float = 0.6
    offset: float = 2.0
    samples: int = 12
    iterations: int = 8
    step: float = 1.5
    decay: float = 0.8
    move_ends: bool = True


def snake_fields(intensity: np.ndarray, blur: int = 5) -> np.ndarray:
    """Blurred intensity and the derivatives the downhill steps need, stacked for one bilinear lookup.

    Parameters
    ----------
    intensity : (H, W) float32
        I of Eq. 1 (after contrast enhancement).
    blur : int
        Odd Gaussian kernel size (0 or 1: no blur). Blurring widens the basin of each edge (§3.3).

    Returns
    -------
    (H, W, 5) float32
        I, ∂I/∂x, ∂I/∂y, ∂|∇I|²/∂x, ∂|∇I|²/∂y.
    """
    img = np.ascontiguousarray(intensity, dtype=np.float32)
    if img.ndim != 2 or min(img.shape) < 2:
        raise ValueError(f"intensity must be a 2-D image of at least 2 x 2 pixels, got shape {img.shape}")
    return _fields(img, _taps(int(blur)))


@lru_cache(maxsize=8)
def _taps(blur: int) -> np.ndarray:
    """OpenCV's Gaussian kernel of ``blur`` taps (sigma from the size), float32; one tap of 1 for ``blur <= 1``."""
    taps = cv2.getGaussianKernel(blur, 0).ravel() if blur > 1 else np.ones(1)
    return taps.astype(np.float32)              # shared by the calls: not to be modified


@nb.njit(**INNER)
def _reflect(i: int, n: int) -> int:
    """Index ``i`` reflected into [0, n) without repeating the edge (OpenCV's BORDER_REFLECT_101)."""
    if i < 0:
        i = -i
    if i >= n:
        i = 2 * n - 2 - i
    return min(max(i, 0), n - 1)


@nb.njit(**INNER)
def _central(img: np.ndarray, out: np.ndarray, cx: int, cy: int) -> None:
    """Central differences (f(+1) - f(-1)) / 2 along x into channel ``cx`` and along y into ``cy`` (reflected
    borders)."""
    h, w = img.shape
    for y in range(h):
        ym, yp = _reflect(y - 1, h), _reflect(y + 1, h)
        for x in range(w):
            xm = x - 1 if x > 0 else _reflect(-1, w)
            xp = x + 1 if x < w - 1 else _reflect(w, w)
            out[y, x, cx] = 0.5 * (img[y, xp] - img[y, xm])
            out[y, x, cy] = 0.5 * (img[yp, x] - img[ym, x])


@nb.njit(**KERNEL)
def _fields(img: np.ndarray, taps: np.ndarray) -> np.ndarray:
    """The stack of :func:`snake_fields`: separable Gaussian blur, then central differences (both with
    reflected borders, as OpenCV's GaussianBlur and Sobel with ksize=1 and scale 1/2)."""
    h, w = img.shape
    n = len(taps)
    r = n // 2
    # Along the rows (each row padded by reflection), then along the columns (rows read reflected).
    row = np.empty(w + 2 * r, np.float32)
    tmp = np.zeros((h, w), np.float32)
    for y in range(h):
        for x in range(w + 2 * r):
            row[x] = img[y, _reflect(x - r, w)]
        for k in range(n):
            t = taps[k]
            for x in range(w):
                tmp[y, x] += t * row[x + k]
    blurred = np.zeros((h, w), np.float32)
    for y in range(h):
        for k in range(n):
            t = taps[k]
            src = tmp[_reflect(y + k - r, h)]
            for x in range(w):
                blurred[y, x] += t * src[x]
    out = np.empty((h, w, 5), np.float32)
    _central(blurred, out, 1, 2)
    mag = np.empty((h, w), np.float32)
    for y in range(h):
        for x in range(w):
            out[y, x, 0] = blurred[y, x]
            mag[y, x] = out[y, x, 1] * out[y, x, 1] + out[y, x, 2] * out[y, x, 2]
    _central(mag, out, 3, 4)
    return out


#: Samples per curve of the polygons :func:`lip_field` fills.
LIP_POLYGON_SAMPLES = 16


def lip_field(intensity: np.ndarray, curves: np.ndarray) -> np.ndarray:
    """The feature intensity with the mouth opening painted at the lips' own level, for the outer lips' snakes.

    An open mouth's inside (a dark opening bright in C, teeth and tongue dark in C) has edges of its own,
    often stronger than the lips' edge against the skin, and the offset curves of Eq. 4 cannot tell a
    skin-to-opening edge from a skin-to-lip one when the lip is pale. Inside the inner lips (the polygon
    between ``lip_upper_inner`` and ``lip_lower_inner``) the intensity is set to the median over the lips
    themselves (between the outer and the inner curves), so the only edge left near the outer curves is the
    lips' outline (Fig. 3's curve A above, curve B below).

    Parameters
    ----------
    intensity : (H, W) float32
        C of the crop (or a part of it).
    curves : (C, 4, 2) float
        The rules' curves in the same pixels (:data:`~facepuppet.capture.curves.CURVE_NAMES` order).

    Returns
    -------
    (H, W) float32
        A copy of ``intensity``; unchanged where the inner lips enclose less than one pixel's area.
    """
    img = np.array(intensity, dtype=np.float32)
    c = np.asarray(curves, dtype=np.float64)
    b = _Basis.get(LIP_POLYGON_SAMPLES)[0].astype(np.float64)
    ui, li, uo, lo = (b @ c[_LIP_IDX[n]] for n in ("lip_upper_inner", "lip_lower_inner", "lip_upper_outer",
                                                   "lip_lower_outer"))
    _paint_opening(img, ui, li, uo, lo)
    return img


@nb.njit(**INNER)
def _column_y(pts: np.ndarray, x: float) -> float:
    """y at ``x`` of the polyline ``pts`` (K, 2), points in increasing x (the end's y outside)."""
    if x <= pts[0, 0]:
        return pts[0, 1]
    for k in range(1, len(pts)):
        if x <= pts[k, 0]:
            dx = pts[k, 0] - pts[k - 1, 0]
            t = (x - pts[k - 1, 0]) / dx if dx > 1e-9 else 1.0
            return pts[k - 1, 1] + t * (pts[k, 1] - pts[k - 1, 1])
    return pts[len(pts) - 1, 1]


@nb.njit(**KERNEL)
def _paint_opening(img: np.ndarray, ui: np.ndarray, li: np.ndarray, uo: np.ndarray, lo: np.ndarray) -> None:
    """:func:`lip_field`'s painting in place, column by column: pixel centres between the inner lips' samples
    (K, 2) take the median of those between the outer and the inner ones (left as they are when the inner
    lips enclose less than a pixel's area or no lip pixel is found)."""
    h, w = img.shape
    xa = max(int(np.ceil(min(uo[0, 0], lo[0, 0]) - 0.5)), 0)
    xb = min(int(np.floor(max(uo[len(uo) - 1, 0], lo[len(lo) - 1, 0]) - 0.5)), w - 1)
    if xb < xa:
        return
    n = xb - xa + 1
    top_i = np.empty(n)
    bot_i = np.empty(n)
    area = 0.0
    for i in range(n):
        x = xa + i + 0.5
        inside = ui[0, 0] <= x <= ui[len(ui) - 1, 0]
        top_i[i] = _column_y(ui, x) if inside else 1e9
        bot_i[i] = _column_y(li, x) if inside else -1e9
        if inside:
            area += max(bot_i[i] - top_i[i], 0.0)
    if area < 1.0:
        return
    vals = np.empty(n * h, np.float32)
    m = 0
    for i in range(n):
        x = xa + i + 0.5
        y0 = _column_y(uo, x)
        y1 = _column_y(lo, x)
        for y in range(max(int(np.ceil(y0 - 0.5)), 0), min(int(np.floor(y1 - 0.5)), h - 1) + 1):
            if not top_i[i] <= y + 0.5 <= bot_i[i]:
                vals[m] = img[y, xa + i]
                m += 1
    if m == 0:
        return
    level = median(vals[:m])
    for i in range(n):
        for y in range(max(int(np.ceil(top_i[i] - 0.5)), 0), min(int(np.floor(bot_i[i] - 0.5)), h - 1) + 1):
            img[y, xa + i] = level


def _sample(fields: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Bilinear lookup of (N, 2) points in (H, W, K) fields -> (N, K); outside the image reads as 0."""
    p = np.ascontiguousarray(pts, dtype=np.float32).reshape(1, -1, 2)
    out = cv2.remap(fields, p, None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    return out.reshape(len(pts), -1)


class _Basis:
    """Bernstein samples and offset profile for a given sample count (cached)."""

    _cache: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    @classmethod
    def get(cls, n: int) -> tuple[np.ndarray, np.ndarray]:
        if n not in cls._cache:
            b = bernstein(np.linspace(0.0, 1.0, n)).astype(np.float32)
            cls._cache[n] = (b, b[:, 1] + b[:, 2])
        return cls._cache[n]


def _offset_dirs(side: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Direction (C, 2) from a curve towards its inner offset curve: against the up-vector for UPPER."""
    up = np.asarray(up, dtype=np.float32)
    up = up / max(float(np.linalg.norm(up)), 1e-9)
    return -np.asarray(side, dtype=np.float32)[:, None] * up[None, :]


def snake_energy(ctrl: np.ndarray, side: np.ndarray, up: np.ndarray, fields: np.ndarray,
                 config: SnakeConfig = SnakeConfig()) -> np.ndarray:
    """E(v) of Eq. 2 for each curve (sum over samples, divided by their count).

    Parameters
    ----------
    ctrl : (C, 4, 2) float
    side : (C,) float
        :data:`UPPER` or :data:`LOWER` per curve.
    up : (2,) float
        The head's up-vector in the image (x right, y down: upright head gives (0, -1)).
    fields : (H, W, 5) float32
        From :func:`snake_fields`.
    config : SnakeConfig

    Returns
    -------
    (C,) float
    """
    b, prof = _Basis.get(config.samples)
    ctrl = np.asarray(ctrl, dtype=np.float32)
    c = len(ctrl)
    inward = _offset_dirs(side, up) * np.float32(config.offset)
    pts = np.einsum("sj,cjd->csd", b, ctrl)
    shift = prof[None, :, None] * inward[:, None, :]
    allp = np.concatenate([pts, pts + shift, pts - shift]).reshape(-1, 2)
    vals = _sample(fields, allp).reshape(3, c, config.samples, 5)
    grad2 = vals[0, ..., 1] ** 2 + vals[0, ..., 2] ** 2
    e = -config.w_edge * grad2 + config.w_out * vals[2, ..., 0] - config.w_in * vals[1, ..., 0]
    return e.mean(axis=1)


def minimise_snakes(ctrl: np.ndarray, side: np.ndarray, up: np.ndarray, fields: np.ndarray,
                    config: SnakeConfig = SnakeConfig(), fixed_ends: np.ndarray | None = None) -> np.ndarray:
    """Downhill minimisation of Eq. 2 for a batch of curves, all at once.

    Each step moves every control point against the energy's gradient, normalised per curve so that the
    largest move is the current step length (a scale-free downhill step); step lengths shrink geometrically.

    Parameters
    ----------
    ctrl : (C, 4, 2) float
        Initial guesses (for example :func:`box_guess`).
    side : (C,) float
        :data:`UPPER` or :data:`LOWER` per curve.
    up : (2,) float
        The head's up-vector in image coordinates.
    fields : (H, W, 5) float32
        From :func:`snake_fields`.
    config : SnakeConfig
    fixed_ends : (C,) bool, optional
        Curves whose end control points must stay put.

    Returns
    -------
    (C, 4, 2) float32
    """
    return SnakeSolver(side, up, config, fixed_ends)(ctrl, fields)


class SnakeSolver:
    """:func:`minimise_snakes` for fixed sides, up-vector, options and fixed ends: what depends only on these
    (the offset curves' shifts, the movable control points, the Bernstein samples) is set up once, so a
    tracker that refines the same curves every frame pays only for the downhill steps.

    Parameters
    ----------
    side, up, config, fixed_ends
        As :func:`minimise_snakes`.
    """

    def __init__(self, side: np.ndarray, up: np.ndarray, config: SnakeConfig = SnakeConfig(),
                 fixed_ends: np.ndarray | None = None):
        b, prof = _Basis.get(config.samples)
        c = len(side)
        inward = _offset_dirs(side, up) * np.float32(config.offset)
        self._shift = prof[None, :, None] * inward[:, None, :]
        mask = np.ones((c, 4, 1), dtype=np.float32)
        if not config.move_ends:
            mask[:, [0, 3]] = 0.0
        if fixed_ends is not None:
            fe = np.asarray(fixed_ends, dtype=bool)
            mask[fe, 0] = 0.0
            mask[fe, 3] = 0.0
        self._mask = mask
        self._basis = b.astype(np.float64)
        self._steps = (float(config.w_edge), float(config.w_in), float(config.w_out), float(config.step),
                       float(config.decay), int(config.iterations))

    def __call__(self, ctrl: np.ndarray, fields: np.ndarray) -> np.ndarray:
        """The curves ``ctrl`` (C, 4, 2) minimised in ``fields`` (H, W, 5) -> (C, 4, 2) float32."""
        x = np.array(ctrl, dtype=np.float32)
        if len(x) == 0:
            return x
        if len(x) != len(self._mask):
            raise ValueError(f"ctrl must hold the solver's {len(self._mask)} curves, got {len(x)}")
        return _descend(x, self._shift, self._mask, self._basis, np.ascontiguousarray(fields, dtype=np.float32),
                        *self._steps)


@nb.njit(**INNER)
def _lookup(fields: np.ndarray, x: float, y: float, out: np.ndarray) -> None:
    """Bilinear lookup of all fields at (x, y); pixels outside the image read as 0."""
    h, w, k = fields.shape
    fx, fy = np.floor(x), np.floor(y)
    x0, y0 = int(fx), int(fy)
    ax, ay = x - fx, y - fy
    out[:] = 0.0
    for dy in range(2):
        yy = y0 + dy
        if yy < 0 or yy >= h:
            continue
        wy = ay if dy else 1.0 - ay
        for dx in range(2):
            xx = x0 + dx
            if xx < 0 or xx >= w:
                continue
            wgt = wy * (ax if dx else 1.0 - ax)
            for c in range(k):
                out[c] += wgt * fields[yy, xx, c]


@nb.njit(**KERNEL)
def _descend(x, shift, mask, b, fields, w_edge, w_in, w_out, step, decay, iterations):
    """The downhill steps of :func:`minimise_snakes` (x is updated in place and returned)."""
    c, n = shift.shape[0], b.shape[0]
    v0 = np.empty(5)
    vin = np.empty(5)
    vout = np.empty(5)
    g = np.empty((n, 2))
    for _ in range(iterations):
        for ci in range(c):
            for s in range(n):
                px = b[s, 0] * x[ci, 0, 0] + b[s, 1] * x[ci, 1, 0] + b[s, 2] * x[ci, 2, 0] + b[s, 3] * x[ci, 3, 0]
                py = b[s, 0] * x[ci, 0, 1] + b[s, 1] * x[ci, 1, 1] + b[s, 2] * x[ci, 2, 1] + b[s, 3] * x[ci, 3, 1]
                _lookup(fields, px, py, v0)
                _lookup(fields, px + shift[ci, s, 0], py + shift[ci, s, 1], vin)
                _lookup(fields, px - shift[ci, s, 0], py - shift[ci, s, 1], vout)
                # dE/dv at the sample (Eqs. 3-4): the offset curves move rigidly with v (constant shifts).
                for d in range(2):
                    g[s, d] = -w_edge * v0[3 + d] + w_out * vout[1 + d] - w_in * vin[1 + d]
            norm = 0.0
            grad = np.zeros((4, 2))
            for j in range(4):
                for d in range(2):
                    acc = 0.0
                    for s in range(n):
                        acc += b[s, j] * g[s, d]
                    grad[j, d] = acc * mask[ci, j, 0]
                norm = max(norm, np.sqrt(grad[j, 0] ** 2 + grad[j, 1] ** 2))
            scale = step / max(norm, 1e-12)
            for j in range(4):
                for d in range(2):
                    x[ci, j, d] -= grad[j, d] * scale
        step *= decay
    return x


def box_guess(box: np.ndarray, side: np.ndarray) -> np.ndarray:
    """The paper's initial guess: the top (UPPER) or bottom (LOWER) edge of a blob's bounding box.

    Parameters
    ----------
    box : (C, 4) float
        x0, y0, x1, y1 per curve (pixels).
    side : (C,) float

    Returns
    -------
    (C, 4, 2) float32, running from x0 to x1.
    """
    box = np.asarray(box, dtype=np.float32)
    y = np.where(np.asarray(side) > 0, box[:, 1], box[:, 3])
    t = np.array([0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0], dtype=np.float32)
    xs = box[:, [0]] + (box[:, [2]] - box[:, [0]]) * t[None, :]
    return np.stack([xs, np.repeat(y[:, None], 4, axis=1)], axis=-1)
