"""Affine alignment of a small grey crop on a reference crop by maximising the enhanced correlation coefficient
(ECC; Evangelidis & Psarakis, "Parametric image alignment using enhanced correlation coefficient maximization",
PAMI 2008), as a compiled kernel for the crops of a few dozen pixels the follower aligns.

The steps are those of :func:`cv2.findTransformECC` with an affine motion, no mask and a Gaussian
pre-blur of 3 x 3: both images blurred (kernel (1, 2, 1) / 4, borders reflected without the edge pixel), the input's
gradients by central differences, and per step the input and its gradients warped back onto the template's grid
(bilinear, outside the input: 0; a pixel counts where its nearest input pixel is inside), both zero-meaned over the
pixels that count, and the Gauss-Newton step of the ECC criterion with its photometric scale λ. The template's blur
is done once per reference (:func:`blur3`), not per frame. Each row of the template's grid is warped in two loops
without branches (the input and its gradients padded with zeros, the indices clamped into the padding): one
places the pixels (their bilinear weights and the flat index of their upper left neighbour, vectorised), one
reads the neighbours; the row's sums are then taken in a third; the sums are free to be reordered (vectorised),
so the warp found may differ from a strictly ordered sum's in the last bits.

Conventions: images (h, w) float32 grey; the warp (2, 3) maps template pixels (x, y, 1) to input pixels; its
parameters are updated in the order (a00, a10, a01, a11, a02, a12). The returned correlation is the criterion at
the warp before the last step (as OpenCV's), in [-1, 1].
"""

from __future__ import annotations

import numba as nb
import numpy as np

from facepuppet._util.jit import INNER, KERNEL

__all__ = ["PAD", "blur3", "ecc_affine"]

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


#: Zero pixels around the input and its gradients, so that a warped pixel's four neighbours are read without tests.
PAD = 2


@nb.njit(**INNER)
def _warp_row(img: np.ndarray, gx: np.ndarray, gy: np.ndarray, stride: int, template: np.ndarray, y: int,
              m00: float, rx: float, m10: float, ry: float, W: int, H: int, v: np.ndarray, a: np.ndarray,
              b: np.ndarray, m: np.ndarray, t: np.ndarray, weights: np.ndarray, at: np.ndarray) -> None:
    """Row ``y`` of the template's grid warped onto the input: pixel x sits at (m00 x + rx, m10 x + ry) in the
    input (W x H). ``img``, ``gx``, ``gy``: the input and its gradients padded with zeros (H + 2 PAD rows of
    ``stride`` = W + 2 PAD float32), flattened row by row. Writes per pixel the bilinear input ``v``, gradients
    ``a``, ``b`` (0 outside the input), whether the pixel counts ``m`` (1.0 where its nearest input pixel is
    inside, else 0.0) and the template times it ``t``; ``weights`` (4, w) float64 and ``at`` (w,) int64 are
    scratch (the bilinear weights, the flat index of the upper left neighbour)."""
    lo, hi_x, hi_y = -float(PAD), float(W), float(H)
    for x in range(len(v)):
        xx = float(x)
        X = m00 * xx + rx
        Y = m10 * xx + ry
        fX, fY = np.floor(X), np.floor(Y)
        fx, fy = X - fX, Y - fY
        weights[0, x], weights[1, x] = (1.0 - fy) * (1.0 - fx), (1.0 - fy) * fx
        weights[2, x], weights[3, x] = fy * (1.0 - fx), fy * fx
        # Beyond the padding both neighbours of a row or column are padding too.
        ix = int(min(max(fX, lo), hi_x)) + PAD
        iy = int(min(max(fY, lo), hi_y)) + PAD
        at[x] = iy * stride + ix
        nX, nY = np.floor(X + 0.5), np.floor(Y + 0.5)
        inside = 1.0 if (0.0 <= nX) & (nX < hi_x) & (0.0 <= nY) & (nY < hi_y) else 0.0
        m[x] = inside
        t[x] = float(template[y, x]) * inside
    for x in range(len(v)):
        i, j = at[x], at[x] + stride
        w00, w01, w10, w11 = weights[0, x], weights[1, x], weights[2, x], weights[3, x]
        v[x] = w00 * img[i] + w01 * img[i + 1] + w10 * img[j] + w11 * img[j + 1]
        a[x] = w00 * gx[i] + w01 * gx[i + 1] + w10 * gx[j] + w11 * gx[j + 1]
        b[x] = w00 * gy[i] + w01 * gy[i + 1] + w10 * gy[j] + w11 * gy[j + 1]


@nb.njit(nogil=True, fastmath={"reassoc", "nsz", "contract"})
def _row_sums(v: np.ndarray, a: np.ndarray, b: np.ndarray, m: np.ndarray, t: np.ndarray, xs: np.ndarray,
              si: float, st: float, sii: float, stt: float, sit: float):
    """One row's sums of :func:`ecc_affine` from :func:`_warp_row`'s arrays (``xs``: the columns as floats): the
    products of the gradients and the input weighted by 1, x, x^2 over all pixels, and those with the template
    and the pixel count over the pixels that count; the image sums (si, st, sii, stt, sit) carried on from the
    rows before."""
    aa0 = aa1 = aa2 = ab0 = ab1 = ab2 = bb0 = bb1 = bb2 = 0.0
    av0 = av1 = bv0 = bv1 = at0 = at1 = bt0 = bt1 = a0 = a1 = b0 = b1 = 0.0
    n = 0.0
    for x in range(len(v)):
        xx, vx, ax, bx, mx, tx = xs[x], v[x], a[x], b[x], m[x], t[x]
        q = ax * ax
        aa0 += q
        aa1 += q * xx
        aa2 += q * xx * xx
        q = ax * bx
        ab0 += q
        ab1 += q * xx
        ab2 += q * xx * xx
        q = bx * bx
        bb0 += q
        bb1 += q * xx
        bb2 += q * xx * xx
        q = ax * vx
        av0 += q
        av1 += q * xx
        q = bx * vx
        bv0 += q
        bv1 += q * xx
        vm, am, bm = vx * mx, ax * mx, bx * mx           # 0 where the pixel does not count
        n += mx
        si += vm
        st += tx
        sii += vm * vx
        stt += tx * tx
        sit += vm * tx
        q = am * tx
        at0 += q
        at1 += q * xx
        q = bm * tx
        bt0 += q
        bt1 += q * xx
        a0 += am
        a1 += am * xx
        b0 += bm
        b1 += bm * xx
    return (aa0, aa1, aa2, ab0, ab1, ab2, bb0, bb1, bb2, av0, av1, bv0, bv1, at0, at1, bt0, bt1, a0, a1, b0, b1,
            n, si, st, sii, stt, sit)


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
    blurred = blur3(image)
    stride = W + 2 * PAD
    flat_img = np.zeros((H + 2 * PAD) * stride, np.float32)
    flat_gx = np.zeros((H + 2 * PAD) * stride, np.float32)
    flat_gy = np.zeros((H + 2 * PAD) * stride, np.float32)
    img = flat_img.reshape((H + 2 * PAD, stride))
    gx = flat_gx.reshape((H + 2 * PAD, stride))
    gy = flat_gy.reshape((H + 2 * PAD, stride))
    for y in range(H):
        ym, yp = _reflect(y - 1, H), _reflect(y + 1, H)
        for x in range(W):
            img[y + PAD, x + PAD] = blurred[y, x]
            gx[y + PAD, x + PAD] = np.float32(0.5) * (blurred[y, _reflect(x + 1, W)] - blurred[y, _reflect(x - 1, W)])
            gy[y + PAD, x + PAD] = np.float32(0.5) * (blurred[yp, x] - blurred[ym, x])
    G = np.empty((6, 6))
    rv, ra, rb, rm, rt = np.empty(w), np.empty(w), np.empty(w), np.empty(w), np.empty(w)
    weights, at = np.empty((4, w)), np.empty(w, np.int64)
    xs = np.arange(w).astype(np.float64)
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
            _warp_row(flat_img, flat_gx, flat_gy, stride, template, y, m00, rx, m10, ry, W, H, rv, ra, rb, rm, rt,
                      weights, at)
            (aa0, aa1, aa2, ab0, ab1, ab2, bb0, bb1, bb2, av0, av1, bv0, bv1, at0, at1, bt0, bt1, a0, a1, b0, b1,
             cnt, si, st, sii, stt, sit) = _row_sums(rv, ra, rb, rm, rt, xs, si, st, sii, stt, sit)
            n += int(cnt)
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
