"""Affine alignment of a small grey crop on a reference crop by maximising the enhanced correlation coefficient
(ECC; Evangelidis & Psarakis, "Parametric image alignment using enhanced correlation coefficient maximization",
PAMI 2008), as a compiled kernel for the crops of a few dozen pixels the follower aligns.

The steps are those of :func:`cv2.findTransformECC` with an affine motion, no mask and a Gaussian
pre-blur of 3 x 3: both images blurred (kernel (1, 2, 1) / 4, borders reflected without the edge pixel), the input's
gradients by central differences, and per step the input and its gradients warped back onto the template's grid
(bilinear, outside the input: 0; a pixel counts where its nearest input pixel is inside), both zero-meaned over the
pixels that count, and the Gauss-Newton step of the ECC criterion with its photometric scale λ. The template's blur
is done once per reference (:func:`blur3`), not per frame.

Conventions: images (h, w) float32 grey; the warp (2, 3) maps template pixels (x, y, 1) to input pixels; its
parameters are updated in the order (a00, a10, a01, a11, a02, a12). The returned correlation is the criterion at
the warp before the last step (as OpenCV's), in [-1, 1].
"""

from __future__ import annotations

import numba as nb
import numpy as np

from facepuppet._util.jit import INNER, KERNEL

__all__ = ["blur3", "ecc_affine"]

@nb.njit(**INNER)
def _reflect(i: int, n: int) -> int:
    """Index ``i`` reflected into 0..n-1 without repeating the edge pixel (n >= 2)."""
    if i < 0:
        return -i
    if i >= n:
        return 2 * n - 2 - i
    return i


@nb.njit(**KERNEL)
def blur3(img: np.ndarray) -> np.ndarray:
    """(h, w) float32 image blurred by the 3 x 3 Gaussian (1, 2, 1) / 4 in each direction, edges reflected
    without the edge pixel; (h, w) float32."""
    h, w = img.shape
    tmp = np.empty((h, w), np.float32)
    for y in range(h):
        for x in range(w):
            tmp[y, x] = np.float32(0.25) * img[y, _reflect(x - 1, w)] + np.float32(0.5) * img[y, x] + \
                np.float32(0.25) * img[y, _reflect(x + 1, w)]
    out = np.empty((h, w), np.float32)
    for y in range(h):
        ym, yp = _reflect(y - 1, h), _reflect(y + 1, h)
        for x in range(w):
            out[y, x] = np.float32(0.25) * tmp[ym, x] + np.float32(0.5) * tmp[y, x] + np.float32(0.25) * tmp[yp, x]
    return out


@nb.njit(**INNER)
def _floor(v: float) -> int:
    """The largest integer <= ``v``."""
    i = int(v)
    return i - 1 if v < i else i


@nb.njit(**INNER)
def _at(img: np.ndarray, x: int, y: int) -> float:
    """Pixel (x, y) of ``img``, 0 outside it."""
    h, w = img.shape
    return img[y, x] if 0 <= y < h and 0 <= x < w else 0.0


@nb.njit(**KERNEL)
def ecc_affine(template: np.ndarray, image: np.ndarray, warp: np.ndarray, iterations: int, eps: float):
    """Align ``image`` on ``template`` (the template already blurred, :func:`blur3`) by affine ECC.

    Parameters
    ----------
    template : (h, w) float32
        The reference, blurred.
    image : (H, W) float32
        The input, not blurred.
    warp : (2, 3) float
        First guess: template pixels -> input pixels.
    iterations : int
        Most Gauss-Newton steps.
    eps : float
        Steps stop once the correlation changes by less.

    Returns
    -------
    ok : bool
        False when the criterion is undefined (a flat crop) or a step would lower it (uncorrelated images).
    rho : float
        The correlation (see the module's conventions).
    warp : (2, 3) float64
        The warp found.
    """
    h, w = template.shape
    H, W = image.shape
    M = np.empty((2, 3))
    for i in range(2):
        for j in range(3):
            M[i, j] = warp[i, j]
    img = blur3(image)
    gx = np.empty((H, W), np.float32)
    gy = np.empty((H, W), np.float32)
    for y in range(H):
        ym, yp = _reflect(y - 1, H), _reflect(y + 1, H)
        for x in range(W):
            gx[y, x] = np.float32(0.5) * (img[y, _reflect(x + 1, W)] - img[y, _reflect(x - 1, W)])
            gy[y, x] = np.float32(0.5) * (img[yp, x] - img[ym, x])
    G = np.empty((6, 6))
    pa = np.empty(6)        # sum of J * (warped input), all pixels
    pt = np.empty(6)        # sum of J * template, pixels that count
    pn = np.empty(6)        # sum of J, pixels that count
    rho, last = -1.0, -eps
    for _ in range(iterations):
        if abs(rho - last) < eps:
            break
        # One pass: the input and its gradients (a, b) warped back onto the template's grid, and the sums from
        # which the zero-mean terms follow (the means are subtracted afterwards, over the pixels that count).
        # The Jacobian's row at pixel (x, y) is (a x, b x, a y, b y, a, b): each row of pixels sums its products
        # weighted by 1, x, x^2, and the rows' sums are weighted by 1, y, y^2.
        G[:] = 0.0
        pa[:] = 0.0
        pt[:] = 0.0
        pn[:] = 0.0
        n = 0
        si = st = sii = stt = sit = 0.0
        m00, m01, m02, m10, m11, m12 = M[0, 0], M[0, 1], M[0, 2], M[1, 0], M[1, 1], M[1, 2]
        for y in range(h):
            rx = m01 * y + m02
            ry = m11 * y + m12
            aa0 = aa1 = aa2 = ab0 = ab1 = ab2 = bb0 = bb1 = bb2 = 0.0
            av0 = av1 = bv0 = bv1 = at0 = at1 = bt0 = bt1 = a0 = a1 = b0 = b1 = 0.0
            for x in range(w):
                xx = float(x)
                X = m00 * xx + rx
                Y = m10 * xx + ry
                ix, iy = _floor(X), _floor(Y)
                fx, fy = X - ix, Y - iy
                w00, w01, w10, w11 = (1.0 - fy) * (1.0 - fx), (1.0 - fy) * fx, fy * (1.0 - fx), fy * fx
                if 0 <= ix < W - 1 and 0 <= iy < H - 1:
                    v = w00 * img[iy, ix] + w01 * img[iy, ix + 1] + w10 * img[iy + 1, ix] + w11 * img[iy + 1, ix + 1]
                    a = w00 * gx[iy, ix] + w01 * gx[iy, ix + 1] + w10 * gx[iy + 1, ix] + w11 * gx[iy + 1, ix + 1]
                    b = w00 * gy[iy, ix] + w01 * gy[iy, ix + 1] + w10 * gy[iy + 1, ix] + w11 * gy[iy + 1, ix + 1]
                else:
                    v = w00 * _at(img, ix, iy) + w01 * _at(img, ix + 1, iy) + w10 * _at(img, ix, iy + 1) + \
                        w11 * _at(img, ix + 1, iy + 1)
                    a = w00 * _at(gx, ix, iy) + w01 * _at(gx, ix + 1, iy) + w10 * _at(gx, ix, iy + 1) + \
                        w11 * _at(gx, ix + 1, iy + 1)
                    b = w00 * _at(gy, ix, iy) + w01 * _at(gy, ix + 1, iy) + w10 * _at(gy, ix, iy + 1) + \
                        w11 * _at(gy, ix + 1, iy + 1)
                q = a * a
                aa0 += q
                aa1 += q * xx
                aa2 += q * xx * xx
                q = a * b
                ab0 += q
                ab1 += q * xx
                ab2 += q * xx * xx
                q = b * b
                bb0 += q
                bb1 += q * xx
                bb2 += q * xx * xx
                q = a * v
                av0 += q
                av1 += q * xx
                q = b * v
                bv0 += q
                bv1 += q * xx
                nx, ny = _floor(X + 0.5), _floor(Y + 0.5)
                if 0 <= nx < W and 0 <= ny < H:
                    t = float(template[y, x])
                    n += 1
                    si += v
                    st += t
                    sii += v * v
                    stt += t * t
                    sit += v * t
                    q = a * t
                    at0 += q
                    at1 += q * xx
                    q = b * t
                    bt0 += q
                    bt1 += q * xx
                    a0 += a
                    a1 += a * xx
                    b0 += b
                    b1 += b * xx
            yy = float(y)
            y2 = yy * yy
            # The Hessian's upper triangle (parameters a00, a10, a01, a11, a02, a12).
            G[0, 0] += aa2
            G[0, 1] += ab2
            G[0, 2] += yy * aa1
            G[0, 3] += yy * ab1
            G[0, 4] += aa1
            G[0, 5] += ab1
            G[1, 1] += bb2
            G[1, 2] += yy * ab1
            G[1, 3] += yy * bb1
            G[1, 4] += ab1
            G[1, 5] += bb1
            G[2, 2] += y2 * aa0
            G[2, 3] += y2 * ab0
            G[2, 4] += yy * aa0
            G[2, 5] += yy * ab0
            G[3, 3] += y2 * bb0
            G[3, 4] += yy * ab0
            G[3, 5] += yy * bb0
            G[4, 4] += aa0
            G[4, 5] += ab0
            G[5, 5] += bb0
            pa[0] += av1
            pa[1] += bv1
            pa[2] += yy * av0
            pa[3] += yy * bv0
            pa[4] += av0
            pa[5] += bv0
            pt[0] += at1
            pt[1] += bt1
            pt[2] += yy * at0
            pt[3] += yy * bt0
            pt[4] += at0
            pt[5] += bt0
            pn[0] += a1
            pn[1] += b1
            pn[2] += yy * a0
            pn[3] += yy * b0
            pn[4] += a0
            pn[5] += b0
        if n == 0:
            return False, -1.0, M
        mi, mt = si / n, st / n
        img_norm2 = max(sii - n * mi * mi, 0.0)
        tmp_norm2 = max(stt - n * mt * mt, 0.0)
        corr = sit - n * mi * mt
        pi = pa - mi * pn          # J . (input, zero-mean where the pixels count, as warped elsewhere)
        pz = pt - mt * pn          # J . (template zero-mean where the pixels count, 0 elsewhere)
        for p in range(6):
            for q in range(p):
                G[p, q] = G[q, p]
        last = rho
        denom = np.sqrt(img_norm2 * tmp_norm2)
        if not denom > 0.0:
            return False, -1.0, M
        rho = corr / denom
        Gi = np.linalg.inv(G)
        gpi = Gi @ pi
        lam_n = img_norm2 - pi @ gpi
        lam_d = corr - pz @ gpi
        if not lam_d > 0.0:
            return False, -1.0, M
        lam = lam_n / lam_d
        # The step: projection of the error lambda * template - input onto the Jacobian, through the inverse.
        dp = Gi @ (lam * pz - pi)
        M[0, 0] += dp[0]
        M[1, 0] += dp[1]
        M[0, 1] += dp[2]
        M[1, 1] += dp[3]
        M[0, 2] += dp[4]
        M[1, 2] += dp[5]
    return True, rho, M
