"""`jaxloco.qp.solve_batch(..., backend="kernel")`: the whole QP solve of a batch as one
compiled CPU kernel (numba), called from JAX through XLA's FFI.

Why: under `jax.vmap` the XLA form of the interior-point method (`qp_ipm`) runs about 85
small kernels per iteration, and their overhead, not the arithmetic, bounds it on a CPU
(README, performance). Here the solve of a batch is one compiled loop: the batch is taken
W problems at a time (one 256-bit vector: 4 float64 or 8 float32), every scalar of the
method held across the W lanes (the fastest axis), so that each scalar operation can
become one SIMD instruction; multiply-adds may fuse (`fastmath` "contract").

Layout: every scratch array is a region of one flat buffer at an offset fixed at compile
time (the sizes n, m, p and W are `numba.literally` constants), so the compiler can prove
the regions disjoint and vectorize across the lanes; that needs numba's SLP vectorizer,
switched on while this module compiles its kernel (`_slp_vectorizer`; numba's default is
off). A region X of shape (d1, d2, W) is read as buf[oX + (i * d2 + j) * W + lane].

The same method and results as `jaxloco.qp.solve` up to rounding (tested: sums are taken
in another order): the problem checked for finite values, symmetrized and scaled as
`qp.solve` does, the equalities removed by a Householder QR of A^T, CVXOPT's start,
`iterations` Mehrotra steps with s and z floored at sqrt(eps), y by least squares, the
scaled residuals, ok, and the answer in the caller's units; also the scaled problem's
iterate, from which `jaxloco.qp` takes the gradient (the kernel itself computes no
derivative).

The FFI handler (`_handler`) is a numba C callback that reads XLA's call frame (the typed
FFI of `xla/ffi/api/c_api.h`, API 0.3): one handler per (n, m, p, dtype), compiled and
registered on first use (`ffi_target`); the kernel is cached on disk by numba (next to
this file, or under $NUMBA_CACHE_DIR where that is not writable), so a new process
compiles only the small handler (about 1 s) and the first process about 25 s. CPU only;
numba is the optional dependency `jaxloco[kernel]`.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools

import jax
import jax.numpy as jnp
import numba as nb
import numpy as np
from numba import types
from numba.extending import intrinsic

__all__ = ["VECTOR_BYTES", "ffi_target", "solve_batch", "solve_batch_np"]

VECTOR_BYTES = 32  # problems per SIMD pass: one 256-bit vector of the dtype (4 float64, 8 float32)
_NB = {"cache": True, "nogil": True, "error_model": "numpy", "inline": "always", "fastmath": {"contract"}}


@nb.njit(**_NB)
def _nanmax(acc, v):
    """max(acc, v), NaN once either is NaN (as jnp.max)."""
    return v if (v > acc or v != v) else acc


@nb.njit(**_NB)
def _normalize_row(buf, orow, onorm, orhs, rhs, n, one, W):
    """Divide a constraint row (n entries at orow, stride W: one lane) and its right-hand
    side `rhs` (written to orhs) by the row's 2-norm, stored at onorm (1 for a zero row)."""
    nrm = one - one
    for j in range(n):
        v = buf[orow + j * W]
        nrm = nrm + v * v
    nrm = np.sqrt(nrm)
    nrm = nrm if nrm > 0 else one
    buf[onorm] = nrm
    for j in range(n):
        buf[orow + j * W] = buf[orow + j * W] / nrm
    buf[orhs] = rhs / nrm


@nb.njit(**_NB)
def _matvec(buf, oM, ov, oout, rows, cols, W, transposed=False):
    """out = M v per lane; M (rows, cols, W), v (cols, W), out (rows, W); transposed: M is
    stored as (cols, rows, W). Accumulated column by column, so consecutive updates go to
    different rows (no dependency chain)."""
    for i in range(rows):
        for lane in range(W):
            buf[oout + i * W + lane] = 0
    for j in range(cols):
        for i in range(rows):
            at = oM + ((j * rows + i) if transposed else (i * cols + j)) * W
            for lane in range(W):
                buf[oout + i * W + lane] += buf[at + lane] * buf[ov + j * W + lane]


@nb.njit(**_NB)
def _max_step(buf, oinv, odv, oout, p, one, W):
    """out = the largest alpha in [0, 1] with v + alpha dv >= 0, per lane, from 1 / v
    (v > 0): alpha = 1 / max(1, max_r -dv_r / v_r), one division per lane. The maximum
    runs as two interleaved chains (even and odd rows) to halve the dependency."""
    for lane in range(W):
        m0 = one
        m1 = one
        for r in range(0, p - 1, 2):
            x0 = -buf[odv + r * W + lane] * buf[oinv + r * W + lane]
            x1 = -buf[odv + (r + 1) * W + lane] * buf[oinv + (r + 1) * W + lane]
            m0 = x0 if x0 > m0 else m0
            m1 = x1 if x1 > m1 else m1
        if p % 2:
            x0 = -buf[odv + (p - 1) * W + lane] * buf[oinv + (p - 1) * W + lane]
            m0 = x0 if x0 > m0 else m0
        buf[oout + lane] = one / (m0 if m0 > m1 else m1)


@nb.njit(**_NB)
def _cholesky_packed(buf, oH, oL, oinv, k, one, W):
    """L L^T = H per lane; both (k(k+1)/2, W), lower triangles packed row by row.
    Right-looking: each entry sees the same subtractions, in the same order, as in
    `linalg.cholesky_packed_scalars`. Also inv (k, W): 1 / the diagonal of L."""
    for t in range(k * (k + 1) // 2):
        for lane in range(W):
            buf[oL + t * W + lane] = buf[oH + t * W + lane]
    for j in range(k):
        jj = j * (j + 1) // 2 + j
        for lane in range(W):
            d = np.sqrt(buf[oL + jj * W + lane])
            buf[oL + jj * W + lane] = d
            buf[oinv + j * W + lane] = one / d
        for i in range(j + 1, k):
            ij = i * (i + 1) // 2 + j
            for lane in range(W):
                buf[oL + ij * W + lane] = buf[oL + ij * W + lane] * buf[oinv + j * W + lane]
        for i in range(j + 1, k):
            ij = i * (i + 1) // 2 + j
            for c in range(j + 1, i + 1):
                ic = i * (i + 1) // 2 + c
                cj = c * (c + 1) // 2 + j
                for lane in range(W):
                    buf[oL + ic * W + lane] -= buf[oL + ij * W + lane] * buf[oL + cj * W + lane]


@nb.njit(**_NB)
def _cho_solve(buf, oL, oinv, orhs, ox, k, W):
    """x with L L^T x = rhs per lane (L packed and inv as `_cholesky_packed` gives them),
    column by column."""
    for i in range(k):
        for lane in range(W):
            buf[ox + i * W + lane] = buf[orhs + i * W + lane]
    for c in range(k):
        cc = c * (c + 1) // 2 + c
        for lane in range(W):
            buf[ox + c * W + lane] = buf[ox + c * W + lane] * buf[oinv + c * W + lane]
        for i in range(c + 1, k):
            for lane in range(W):
                buf[ox + i * W + lane] -= buf[oL + (i * (i + 1) // 2 + c) * W + lane] * buf[ox + c * W + lane]
    for c in range(k - 1, -1, -1):
        cc = c * (c + 1) // 2 + c
        for lane in range(W):
            buf[ox + c * W + lane] = buf[ox + c * W + lane] * buf[oinv + c * W + lane]
        for i in range(c):
            for lane in range(W):
                buf[ox + i * W + lane] -= buf[oL + (cc - c + i) * W + lane] * buf[ox + c * W + lane]


@nb.njit(**_NB)
def _newton_rhs(buf, oGr, ow, oD, orp, oQu, oqr, orhs, p, k, W):
    """rhs = G^T (w - D r_p) - (Q u + q) per lane."""
    for a in range(k):
        for lane in range(W):
            buf[orhs + a * W + lane] = -(buf[oQu + a * W + lane] + buf[oqr + a * W + lane])
    for r in range(p):
        for a in range(k):
            for lane in range(W):
                buf[orhs + a * W + lane] += buf[oGr + (r * k + a) * W + lane] * (
                    buf[ow + r * W + lane] - buf[oD + r * W + lane] * buf[orp + r * W + lane])


@nb.njit(**_NB)
def _dot_lanes(buf, oa, sa, ob, sb, count, oacc, W):
    """acc = sum_i a[i] b[i] per lane, a_i at oa + i * sa (lane-strided regions)."""
    for lane in range(W):
        buf[oacc + lane] = 0
    for i in range(count):
        for lane in range(W):
            buf[oacc + lane] += buf[oa + i * sa + lane] * buf[ob + i * sb + lane]


@nb.njit(**_NB)
def _direction(buf, oGr, ow, oD, orp, oQu, oqr, orhs, oL, oLinv, odu, oGdu, oz, ods, odz, p, k, W):
    """The Newton step of `qp_ipm._direction` per lane, for the corrector term w (zeros:
    the predictor): du, G du, ds = -r_p - G du, dz = -(z + w) + D (r_p + G du)."""
    _newton_rhs(buf, oGr, ow, oD, orp, oQu, oqr, orhs, p, k, W)
    _cho_solve(buf, oL, oLinv, orhs, odu, k, W)
    _matvec(buf, oGr, odu, oGdu, p, k, W)
    for r in range(p):
        for lane in range(W):
            g = buf[oGdu + r * W + lane]
            rp = buf[orp + r * W + lane]
            buf[ods + r * W + lane] = -rp - g
            buf[odz + r * W + lane] = -(buf[oz + r * W + lane] + buf[ow + r * W + lane]) + buf[oD + r * W + lane] * (
                rp + g)


@nb.njit(**_NB)
def _step_length(buf, oinvs, oinvz, ods, odz, oa1, oa2, p, one, W):
    """a1 = the largest alpha in [0, 1] keeping s + alpha ds and z + alpha dz >= 0, per
    lane (a2: scratch)."""
    _max_step(buf, oinvs, ods, oa1, p, one, W)
    _max_step(buf, oinvz, odz, oa2, p, one, W)
    for lane in range(W):
        a = buf[oa1 + lane]
        b = buf[oa2 + lane]
        buf[oa1 + lane] = a if a < b else b


@nb.njit(**_NB)
def _reflect(buf, ov, obeta, ocol, stride, j, n, oacc, W):
    """col = (I - beta v v^T) col per lane for the Householder vector v (n, W; zero above
    row j) and the column at ocol (n entries, row stride `stride`)."""
    _dot_lanes(buf, ov, W, ocol, stride, n, oacc, W)
    for i in range(j, n):
        for lane in range(W):
            buf[ocol + i * stride + lane] -= (buf[obeta + lane] * buf[ov + i * W + lane]) * buf[oacc + lane]


@nb.njit(cache=True, nogil=True, error_model="numpy", fastmath={"contract"})
def solve_batch_np(Q, q, A, b, G, h, d, iterations, consts, x_out, y_out, z_out, obj_out, res_out, ok_out,
                   xs_out, ys_out, zs_out, s_out, n, m, p, W):
    """`jaxloco.qp.solve` for B problems in the caller's units: Q (B, n, n), q (B, n),
    A (B, m, n), b (B, m), G (B, p, n), h (B, p), x_scale d (B, n), all of one float
    dtype; n, m, p their sizes (compile-time constants); `consts` (same dtype): 0.5, 1,
    0.99, the floor sqrt(eps), the largest finite float, tol, p, 1e-12.

    Writes, as `qp.solve` returns them: x (B, n), y (B, m), z (B, p), the objective (B,),
    the scaled residuals (B, 3) (primal, dual, complementarity), ok (B,) (uint8); and
    the scaled problem's sanitized iterate xs, ys, zs, s (what `qp._forward` returns,
    for the gradient)."""
    nb.literally(n)
    nb.literally(W)
    nb.literally(m)
    nb.literally(p)
    nbatch = q.shape[0]
    k = n - m
    nt = k * (k + 1) // 2
    half, one, p99, floor, big, tol, pf, tiny = (consts[0], consts[1], consts[2], consts[3], consts[4],
                                                 consts[5], consts[6], consts[7])
    zero = one - one
    two = one + one
    # regions of the scratch buffer: shape, then offset
    oQ = 0                    # Q (n, n)
    oq = oQ + n * n * W       # q (n)
    oA = oq + n * W           # A (m, n)
    ob = oA + m * n * W       # b (m)
    oG = ob + m * W           # G (p, n)
    oh = oG + p * n * W       # h (p)
    oWm = oh + p * W          # A^T under the reflections (n, m)
    oV = oWm + n * m * W      # reflectors (m, n)
    obeta = oV + m * n * W    # (m)
    oE = obeta + m * W        # [Y Z] (n, n)
    oR = oE + n * n * W       # (m, m)
    owv = oR + m * m * W      # (m)
    ox0 = owv + m * W         # (n)
    otn = ox0 + n * W         # (n)
    ox = otn + n * W          # (n)
    oy = ox + n * W           # (m)
    oQZ = oy + m * W          # (n, k)
    oQr = oQZ + n * k * W     # (k, k)
    oGr = oQr + k * k * W     # (p, k)
    oqr = oGr + p * k * W     # (k)
    ohr = oqr + k * W         # (p)
    oGG = ohr + p * W         # (p, nt)
    oQlow = oGG + p * nt * W  # (nt)
    oHl = oQlow + nt * W      # (nt)
    oL = oHl + nt * W         # (nt)
    ou = oL + nt * W          # (k)
    oQu = ou + k * W
    odu = oQu + k * W
    oQdu = odu + k * W
    orhs = oQdu + k * W
    os_ = orhs + k * W        # (p) each
    oz = os_ + p * W
    oGu = oz + p * W
    orp = oGu + p * W
    oD = orp + p * W
    ods = oD + p * W
    odz = ods + p * W
    odsa = odz + p * W
    odza = odsa + p * W
    oGdu = odza + p * W
    ow = oGdu + p * W
    ozp = ow + p * W
    oa1 = ozp + p * W         # (W) each
    oa2 = oa1 + W
    oLinv = oa2 + W           # 1 / diag(L) (k)
    oinvs = oLinv + k * W     # 1 / s (p)
    oinvz = oinvs + p * W     # 1 / z (p)
    oacc = oinvz + p * W
    oacc2 = oacc + W
    od = oacc2 + W            # x_scale (n)
    ora = od + n * W          # row norms of A D (m)
    org = ora + m * W         # row norms of G D (p)
    oc = org + p * W          # objective scale (W)
    ofin = oc + W             # 1 where the inputs are finite (W)
    size = ofin + W
    buf = np.zeros(size, q.dtype)

    for start in range(0, nbatch, W):
        # ---- load W problems (the last one repeated to fill the lanes), checked and scaled
        for lane in range(W):
            bi = min(start + lane, nbatch - 1)
            # finite inputs: x - x is 0 for every finite x and NaN otherwise
            chk = zero
            dpos = True
            for i in range(n):
                dv = d[bi, i]
                dpos = dpos and dv > 0
                chk += (dv - dv) + (q[bi, i] - q[bi, i])
                for j in range(n):
                    chk += Q[bi, i, j] - Q[bi, i, j]
            for i in range(m):
                chk += b[bi, i] - b[bi, i]
                for j in range(n):
                    chk += A[bi, i, j] - A[bi, i, j]
            for r in range(p):
                hv = h[bi, r]
                if not (hv == np.inf):  # h = +inf: a disabled row (G row 0, h 1)
                    chk += hv - hv
                    for j in range(n):
                        chk += G[bi, r, j] - G[bi, r, j]
            fin = dpos and chk == 0
            buf[ofin + lane] = one if fin else zero
            # a non-finite problem is swapped for a dummy: Q = I, A = eye(m, n), G = 0, h = 1
            for i in range(n):
                buf[od + i * W + lane] = d[bi, i] if fin else one
            cmax = zero
            for i in range(n):
                di = buf[od + i * W + lane]
                for j in range(n):
                    qs = half * (Q[bi, i, j] + Q[bi, j, i]) if fin else (one if i == j else zero)
                    v = di * qs * buf[od + j * W + lane]
                    buf[oQ + (i * n + j) * W + lane] = v
                    cmax = _nanmax(cmax, abs(v))
                v = di * q[bi, i] if fin else zero
                buf[oq + i * W + lane] = v
                cmax = _nanmax(cmax, abs(v))
            c = cmax if cmax > tiny else tiny
            buf[oc + lane] = c
            for i in range(n):
                buf[oq + i * W + lane] = buf[oq + i * W + lane] / c
                for j in range(n):
                    buf[oQ + (i * n + j) * W + lane] = buf[oQ + (i * n + j) * W + lane] / c
            for i in range(m):
                for j in range(n):
                    v = A[bi, i, j] * buf[od + j * W + lane] if fin else (one if i == j else zero)
                    buf[oA + (i * n + j) * W + lane] = v
                _normalize_row(buf, oA + i * n * W + lane, ora + i * W + lane, ob + i * W + lane,
                               b[bi, i] if fin else zero, n, one, W)
            for r in range(p):
                on = fin and not (h[bi, r] == np.inf)
                for j in range(n):
                    buf[oG + (r * n + j) * W + lane] = G[bi, r, j] * buf[od + j * W + lane] if on else zero
                _normalize_row(buf, oG + r * n * W + lane, org + r * W + lane, oh + r * W + lane,
                               h[bi, r] if on else one, n, one, W)

        # ---- Householder QR of A^T (n, m): A^T = Y R, [Y Z] = E
        for i in range(n):
            for j in range(m):
                for lane in range(W):
                    buf[oWm + (i * m + j) * W + lane] = buf[oA + (j * n + i) * W + lane]
        for j in range(m):
            for i in range(n):
                for lane in range(W):
                    buf[oV + (j * n + i) * W + lane] = buf[oWm + (i * m + j) * W + lane] if i >= j else zero
            _dot_lanes(buf, oV + j * n * W, W, oV + j * n * W, W, n, oacc, W)
            for lane in range(W):
                norm = np.sqrt(buf[oacc + lane])
                alpha = -norm if buf[oWm + (j * m + j) * W + lane] >= 0 else norm
                buf[oV + (j * n + j) * W + lane] -= alpha
            _dot_lanes(buf, oV + j * n * W, W, oV + j * n * W, W, n, oacc, W)
            for lane in range(W):
                vv = buf[oacc + lane]
                buf[obeta + j * W + lane] = two / vv if vv > 0 else zero
            for c in range(m):
                _reflect(buf, oV + j * n * W, obeta + j * W, oWm + c * W, m * W, j, n, oacc, W)
        for i in range(m):
            for c in range(m):
                for lane in range(W):
                    buf[oR + (i * m + c) * W + lane] = buf[oWm + (i * m + c) * W + lane] if c >= i else zero
        for i in range(n):
            for c in range(n):
                for lane in range(W):
                    buf[oE + (i * n + c) * W + lane] = one if i == c else zero
        for j in range(m - 1, -1, -1):
            for c in range(n):
                _reflect(buf, oV + j * n * W, obeta + j * W, oE + c * W, n * W, j, n, oacc, W)
        # x0 = Y R^-T b
        for i in range(m):
            for lane in range(W):
                buf[owv + i * W + lane] = buf[ob + i * W + lane]
            for c in range(i):
                for lane in range(W):
                    buf[owv + i * W + lane] -= buf[oR + (c * m + i) * W + lane] * buf[owv + c * W + lane]
            for lane in range(W):
                buf[owv + i * W + lane] = buf[owv + i * W + lane] / buf[oR + (i * m + i) * W + lane]
        for r in range(n):
            _dot_lanes(buf, oE + r * n * W, W, owv, W, m, ox0 + r * W, W)

        # ---- the reduced problem in u, x = x0 + Z u with Z = E[:, m:]
        for i in range(n):
            for a in range(k):
                _dot_lanes(buf, oQ + i * n * W, W, oE + (m + a) * W, n * W, n, oQZ + (i * k + a) * W, W)
        for a in range(k):
            for c in range(k):
                _dot_lanes(buf, oE + (m + a) * W, n * W, oQZ + c * W, k * W, n, oQr + (a * k + c) * W, W)
        for a in range(k):
            for c in range(a):
                for lane in range(W):
                    sym = half * (buf[oQr + (a * k + c) * W + lane] + buf[oQr + (c * k + a) * W + lane])
                    buf[oQr + (a * k + c) * W + lane] = sym
                    buf[oQr + (c * k + a) * W + lane] = sym
        for r in range(p):
            for a in range(k):
                _dot_lanes(buf, oG + r * n * W, W, oE + (m + a) * W, n * W, n, oGr + (r * k + a) * W, W)
        for i in range(n):
            _dot_lanes(buf, oQ + i * n * W, W, ox0, W, n, oacc, W)
            for lane in range(W):
                buf[otn + i * W + lane] = buf[oacc + lane] + buf[oq + i * W + lane]
        for a in range(k):
            _dot_lanes(buf, oE + (m + a) * W, n * W, otn, W, n, oqr + a * W, W)
        for r in range(p):
            _dot_lanes(buf, oG + r * n * W, W, ox0, W, n, oacc, W)
            for lane in range(W):
                buf[ohr + r * W + lane] = buf[oh + r * W + lane] - buf[oacc + lane]
        for i in range(k):
            for j in range(i + 1):
                t = i * (i + 1) // 2 + j
                for lane in range(W):
                    buf[oQlow + t * W + lane] = buf[oQr + (i * k + j) * W + lane]
                for r in range(p):
                    for lane in range(W):
                        buf[oGG + (r * nt + t) * W + lane] = (
                            buf[oGr + (r * k + i) * W + lane] * buf[oGr + (r * k + j) * W + lane])

        # ---- CVXOPT's start: least squares with s = z = 1, shifted into the orthant
        for t in range(nt):
            for lane in range(W):
                buf[oHl + t * W + lane] = buf[oQlow + t * W + lane]
            for r in range(p):
                for lane in range(W):
                    buf[oHl + t * W + lane] += buf[oGG + (r * nt + t) * W + lane]
        _cholesky_packed(buf, oHl, oL, oLinv, k, one, W)
        for a in range(k):
            _dot_lanes(buf, oGr + a * W, k * W, ohr, W, p, orhs + a * W, W)
            for lane in range(W):
                buf[orhs + a * W + lane] -= buf[oqr + a * W + lane]
        _cho_solve(buf, oL, oLinv, orhs, ou, k, W)
        _matvec(buf, oGr, ou, oGu, p, k, W)
        _matvec(buf, oQr, ou, oQu, k, k, W)
        for lane in range(W):
            first = buf[oGu + lane] - buf[ohr + lane]
            buf[oa1 + lane] = first  # max r
            buf[oa2 + lane] = first  # min r
        for r in range(1, p):
            for lane in range(W):
                rr = buf[oGu + r * W + lane] - buf[ohr + r * W + lane]
                buf[oa1 + lane] = _nanmax(buf[oa1 + lane], rr)
                buf[oa2 + lane] = -_nanmax(-buf[oa2 + lane], -rr)
        for r in range(p):
            for lane in range(W):
                rr = buf[oGu + r * W + lane] - buf[ohr + r * W + lane]
                worst_s = buf[oa1 + lane]
                worst_z = -buf[oa2 + lane]
                buf[os_ + r * W + lane] = -rr if worst_s < 0 else (-rr + one) + worst_s
                buf[oz + r * W + lane] = rr if worst_z < 0 else (rr + one) + worst_z

        # ---- Mehrotra predictor-corrector iterations
        for _ in range(iterations):
            for r in range(p):
                for lane in range(W):
                    sv = buf[os_ + r * W + lane]
                    zv = buf[oz + r * W + lane]
                    sv = floor if sv < floor else sv
                    zv = floor if zv < floor else zv
                    buf[os_ + r * W + lane] = sv
                    buf[oz + r * W + lane] = zv
                    buf[orp + r * W + lane] = (buf[oGu + r * W + lane] + sv) - buf[ohr + r * W + lane]
                    inv_s = one / sv
                    buf[oinvs + r * W + lane] = inv_s
                    buf[oinvz + r * W + lane] = one / zv
                    buf[oD + r * W + lane] = zv * inv_s
            # H = Q + G^T diag(D) G, lower triangle: GG^T D, then + Q
            _matvec(buf, oGG, oD, oHl, nt, p, W, transposed=True)
            for t in range(nt):
                for lane in range(W):
                    buf[oHl + t * W + lane] = buf[oQlow + t * W + lane] + buf[oHl + t * W + lane]
            _cholesky_packed(buf, oHl, oL, oLinv, k, one, W)
            _dot_lanes(buf, os_, W, oz, W, p, oacc2, W)
            for lane in range(W):
                buf[oacc2 + lane] = buf[oacc2 + lane] / pf  # mu
            # predictor (w = 0)
            _direction(buf, oGr, ozp, oD, orp, oQu, oqr, orhs, oL, oLinv, odu, oGdu, oz, odsa, odza, p, k, W)
            _step_length(buf, oinvs, oinvz, odsa, odza, oa1, oa2, p, one, W)
            for lane in range(W):
                buf[oacc + lane] = 0
            for r in range(p):
                for lane in range(W):
                    a = buf[oa1 + lane]
                    buf[oacc + lane] += (buf[os_ + r * W + lane] + a * buf[odsa + r * W + lane]) * (
                        buf[oz + r * W + lane] + a * buf[odza + r * W + lane])
            for lane in range(W):
                mu = buf[oacc2 + lane]
                ratio = (buf[oacc + lane] / pf) / mu
                ratio = zero if ratio < zero else (one if ratio > one else ratio)
                buf[oa2 + lane] = ratio * ratio * ratio * mu  # sigma mu
            for r in range(p):
                for lane in range(W):
                    buf[ow + r * W + lane] = (buf[odsa + r * W + lane] * buf[odza + r * W + lane]
                                              - buf[oa2 + lane]) * buf[oinvs + r * W + lane]
            # corrector
            _direction(buf, oGr, ow, oD, orp, oQu, oqr, orhs, oL, oLinv, odu, oGdu, oz, ods, odz, p, k, W)
            _matvec(buf, oQr, odu, oQdu, k, k, W)
            _step_length(buf, oinvs, oinvz, ods, odz, oa1, oa2, p, one, W)
            for lane in range(W):
                a = p99 * buf[oa1 + lane]
                buf[oa1 + lane] = a if a < one else one
            for a in range(k):
                for lane in range(W):
                    step = buf[oa1 + lane]
                    buf[ou + a * W + lane] += step * buf[odu + a * W + lane]
                    buf[oQu + a * W + lane] += step * buf[oQdu + a * W + lane]
            for r in range(p):
                for lane in range(W):
                    step = buf[oa1 + lane]
                    buf[os_ + r * W + lane] += step * buf[ods + r * W + lane]
                    buf[oz + r * W + lane] += step * buf[odz + r * W + lane]
                    buf[oGu + r * W + lane] += step * buf[oGdu + r * W + lane]

        # ---- x, y
        for i in range(n):
            _dot_lanes(buf, oE + i * n * W + m * W, W, ou, W, k, oacc, W)
            for lane in range(W):
                buf[ox + i * W + lane] = buf[ox0 + i * W + lane] + buf[oacc + lane]
        for i in range(n):  # tn = Q x + q + G^T z
            _dot_lanes(buf, oQ + i * n * W, W, ox, W, n, oacc, W)
            _dot_lanes(buf, oG + i * W, n * W, oz, W, p, oacc2, W)
            for lane in range(W):
                buf[otn + i * W + lane] = (buf[oacc + lane] + buf[oq + i * W + lane]) + buf[oacc2 + lane]
        for j in range(m):
            _dot_lanes(buf, oE + j * W, n * W, otn, W, n, oacc, W)
            for lane in range(W):
                buf[owv + j * W + lane] = -buf[oacc + lane]
        for i in range(m - 1, -1, -1):
            for lane in range(W):
                buf[oy + i * W + lane] = buf[owv + i * W + lane]
            for j in range(i + 1, m):
                for lane in range(W):
                    buf[oy + i * W + lane] -= buf[oR + (i * m + j) * W + lane] * buf[oy + j * W + lane]
            for lane in range(W):
                buf[oy + i * W + lane] = buf[oy + i * W + lane] / buf[oR + (i * m + i) * W + lane]

        # ---- the scaled residuals and ok, per problem; back to the caller's units
        for lane in range(W):
            bi = start + lane
            if bi >= nbatch:
                continue
            primal = zero
            for i in range(m):
                acc = zero
                for j in range(n):
                    acc = acc + buf[oA + (i * n + j) * W + lane] * buf[ox + j * W + lane]
                primal = _nanmax(primal, abs(acc - buf[ob + i * W + lane]))
            comp = zero
            for r in range(p):
                acc = zero
                for j in range(n):
                    acc = acc + buf[oG + (r * n + j) * W + lane] * buf[ox + j * W + lane]
                slack = buf[oh + r * W + lane] - acc
                primal = _nanmax(primal, -slack)
                comp = _nanmax(comp, abs(buf[oz + r * W + lane] * slack))
            dual = zero
            for i in range(n):
                acc = zero
                for j in range(m):
                    acc = acc + buf[oA + (j * n + i) * W + lane] * buf[oy + j * W + lane]
                dual = _nanmax(dual, abs(buf[otn + i * W + lane] + acc))
            good = _nanmax(_nanmax(primal, dual), comp) <= tol
            for r in range(p):
                if not (np.isfinite(buf[os_ + r * W + lane]) and buf[oz + r * W + lane] >= 0):
                    good = False
            for i in range(n):
                xs_out[bi, i] = buf[ox + i * W + lane] if good else zero
            for i in range(m):
                ys_out[bi, i] = buf[oy + i * W + lane] if good else zero
            for r in range(p):
                zs_out[bi, r] = buf[oz + r * W + lane] if good else zero
                s_out[bi, r] = buf[os_ + r * W + lane] if good else one
            fin = buf[ofin + lane] > 0
            good = good and fin
            ok_out[bi] = 1 if good else 0
            res_out[bi, 0] = primal if (fin and np.isfinite(primal)) else big
            res_out[bi, 1] = dual if (fin and np.isfinite(dual)) else big
            res_out[bi, 2] = comp if (fin and np.isfinite(comp)) else big
            c = buf[oc + lane]
            for i in range(n):
                x_out[bi, i] = buf[od + i * W + lane] * buf[ox + i * W + lane] if good else zero
            for i in range(m):
                y_out[bi, i] = c * buf[oy + i * W + lane] / buf[ora + i * W + lane] if good else zero
            for r in range(p):
                z_out[bi, r] = c * buf[oz + r * W + lane] / buf[org + r * W + lane] if good else zero
            obj = zero
            if good:
                for i in range(n):
                    acc = zero
                    for j in range(n):
                        acc = acc + half * (Q[bi, i, j] + Q[bi, j, i]) * x_out[bi, j]
                    obj = obj + half * x_out[bi, i] * acc + q[bi, i] * x_out[bi, i]
            obj_out[bi] = obj


# ------------------------------------------------------------------------- FFI binding
_FFI_API = (0, 3)  # the XLA FFI API version this handler is written against
_EXTENSION_METADATA = 1  # XLA_FFI_Extension_Type: XLA asks the handler for its metadata
_STAGE_EXECUTE = 3  # XLA_FFI_ExecutionStage
_N_ARGS, _N_RETS = 9, 10


@intrinsic
def _ptr(typingctx, addr):
    """The int64 address `addr` as a void pointer (for `numba.carray`)."""
    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(types.voidptr))

    return types.voidptr(types.int64), codegen


@contextlib.contextmanager
def _slp_vectorizer():
    """numba's SLP vectorizer on while the kernel compiles (numba reads the setting when it
    builds a pass pipeline; its default is off)."""
    before = nb.config.SLP_VECTORIZE
    nb.config.SLP_VECTORIZE = True
    try:
        yield
    finally:
        nb.config.SLP_VECTORIZE = before


def _handler(n: int, m: int, p: int, dtype: np.dtype):
    """The FFI handler (a numba cfunc) for problems of sizes n, m, p in `dtype`. XLA passes
    Q, q, A, b, G, h, x_scale (any leading batch axes), iterations (int32) and the kernel's
    consts, and gets x, y, z, objective, residuals, ok (uint8), xs, ys, zs, s."""
    dt = np.dtype(dtype).type
    w = VECTOR_BYTES // np.dtype(dtype).itemsize
    major, minor = _FFI_API

    @nb.cfunc(types.voidptr(types.voidptr), nopython=True)
    def handler(frame_p):
        # XLA_FFI_CallFrame: struct_size, extension_start, api, ctx, stage (int) | args:
        # struct_size, extension_start, size, types, args (word 9) | rets: ..., rets (word 14)
        frame = nb.carray(frame_p, (16,), np.int64)
        if frame[1] != 0:  # an extension: answer the metadata query, run nothing
            ext = nb.carray(_ptr(frame[1]), (4,), np.int64)
            if (ext[1] & 0xFFFFFFFF) == _EXTENSION_METADATA:
                meta = nb.carray(_ptr(ext[3]), (10,), np.int32)  # XLA_FFI_Metadata
                meta[6] = major  # api_version.major_version (byte 24)
                meta[7] = minor  # api_version.minor_version (byte 28)
                meta[8] = 0  # traits (byte 32)
            return _ptr(0)
        if (frame[4] & 0xFFFFFFFF) != _STAGE_EXECUTE:
            return _ptr(0)
        args = nb.carray(_ptr(frame[9]), (_N_ARGS,), np.int64)
        rets = nb.carray(_ptr(frame[14]), (_N_RETS,), np.int64)
        # XLA_FFI_Buffer: struct_size, extension_start, dtype (int), data (word 3), rank, dims
        qbuf = nb.carray(_ptr(args[1]), (6,), np.int64)
        dims = nb.carray(_ptr(qbuf[5]), (qbuf[4],), np.int64)
        size = 1
        for i in range(qbuf[4]):
            size *= dims[i]
        B = size // n
        data = np.empty(_N_ARGS, np.int64)
        for i in range(_N_ARGS):
            data[i] = nb.carray(_ptr(args[i]), (6,), np.int64)[3]
        out = np.empty(_N_RETS, np.int64)
        for i in range(_N_RETS):
            out[i] = nb.carray(_ptr(rets[i]), (6,), np.int64)[3]
        iterations = nb.carray(_ptr(data[7]), (1,), np.int32)[0]
        solve_batch_np(
            nb.carray(_ptr(data[0]), (B, n, n), dt), nb.carray(_ptr(data[1]), (B, n), dt),
            nb.carray(_ptr(data[2]), (B, m, n), dt), nb.carray(_ptr(data[3]), (B, m), dt),
            nb.carray(_ptr(data[4]), (B, p, n), dt), nb.carray(_ptr(data[5]), (B, p), dt),
            nb.carray(_ptr(data[6]), (B, n), dt), iterations, nb.carray(_ptr(data[8]), (8,), dt),
            nb.carray(_ptr(out[0]), (B, n), dt), nb.carray(_ptr(out[1]), (B, m), dt),
            nb.carray(_ptr(out[2]), (B, p), dt), nb.carray(_ptr(out[3]), (B,), dt),
            nb.carray(_ptr(out[4]), (B, 3), dt), nb.carray(_ptr(out[5]), (B,), np.uint8),
            nb.carray(_ptr(out[6]), (B, n), dt), nb.carray(_ptr(out[7]), (B, m), dt),
            nb.carray(_ptr(out[8]), (B, p), dt), nb.carray(_ptr(out[9]), (B, p), dt),
            n, m, p, w)
        return _ptr(0)

    return handler


_HANDLERS: dict[str, object] = {}  # the registered cfuncs, kept alive for XLA


@functools.cache
def ffi_target(n: int, m: int, p: int, dtype: str) -> str:
    """The name of the FFI target for sizes (n, m, p) and `dtype` ("float32" or "float64"),
    compiling and registering its handler on first use."""
    name = f"jaxloco_qp_{n}_{m}_{p}_{dtype}"
    with _slp_vectorizer():
        handler = _handler(n, m, p, np.dtype(dtype))
    _HANDLERS[name] = handler
    capsule = ctypes.pythonapi.PyCapsule_New
    capsule.restype = ctypes.py_object
    capsule.argtypes = (ctypes.c_void_p, ctypes.c_char_p, ctypes.c_void_p)
    jax.ffi.register_ffi_target(name, capsule(handler.address, None, None), platform="cpu")
    return name


def solve_batch(Q, q, A, b, G, h, x_scale, *, iterations: int, tol: float):
    """The kernel on a batch (every argument with the same leading batch axes, one float
    dtype): (x, y, z, objective, residuals (..., 3), ok (bool), xs, ys, zs, s) as
    `solve_batch_np` writes them. jit-compatible; under `vmap` the batch axes grow."""
    dtype = jnp.dtype(q.dtype)
    n, m, p = q.shape[-1], b.shape[-1], h.shape[-1]
    batch = q.shape[:-1]
    fi = np.finfo(dtype)
    consts = jnp.asarray([0.5, 1.0, 0.99, np.sqrt(fi.eps), fi.max, tol, p, 1e-12], dtype)
    shapes = [(n,), (m,), (p,), (), (3,), (), (n,), (m,), (p,), (p,)]
    out_types = [jax.ShapeDtypeStruct(batch + s, jnp.uint8 if i == 5 else dtype) for i, s in enumerate(shapes)]
    call = jax.ffi.ffi_call(ffi_target(int(n), int(m), int(p), dtype.name), out_types, vmap_method="broadcast_all")
    outs = call(Q, q, A, b, G, h, x_scale, jnp.asarray(iterations, jnp.int32), consts)
    return (*outs[:5], outs[5].astype(bool), *outs[6:])
