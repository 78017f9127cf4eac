"""A batched, differentiable QP layer: a primal-dual interior-point method in plain XLA
operations, laid out across the batch.

Problem (one instance; batch with `jax.vmap` or `solve_batch`)::

    minimize    0.5 x^T Q x + q^T x
    subject to  A x = b,   G x <= h          Q: (n, n) PSD,  A: (m, n),  G: (p, n)

Units and scaling. Inputs and the returned `x`, `y`, `z`, `objective` are in the
caller's units. Inside, the layer solves an equivalent well-scaled problem:
variables x = D x~ with D = diag(x_scale) (default ones, so pass the typical
magnitude of each variable, e.g. 70 for a force in N); every row of A D and G D is
divided by its 2-norm (an all-zero row keeps norm 1, so a row disabled as
``G_i = 0, h_i > 0`` is harmless); the objective is divided by
c = max(max|D Q D|, |D q|_inf, 1e-12). Multipliers are mapped back
(y = c y~ / |row of A D|, z likewise). `primal_residual`, `dual_residual` and
`complementarity` are measured on that scaled problem, so `tol` is a relative,
unit-free tolerance. A row with h_i = +inf is treated as disabled.

Method (`_ipm`). The equalities are eliminated once per instance: a Householder QR of
A^T = [Y N] [R; 0] gives the minimum-norm point x0 = Y R^-T b and an orthonormal basis
N (n, n - m) of A's null space, so x = x0 + N u and the QP in u has only inequalities
(k = n - m unknowns; 8 for the leg-grope step QP of 17 variables). On it runs
Mehrotra's predictor-corrector for exactly `iterations` iterations: each factorizes
the k x k normal matrix N^T Q N + (G N)^T (Z/S) (G N) once (an unrolled Cholesky) and
solves with it twice. An iterate that has converged to rounding level, or whose step
is not finite, is kept as it is, so running more iterations never harms. y follows from
stationarity, y = -R^-1 Y^T (Q x + q + G^T z). All arrays carry the batch as their
last axis and every operation is elementwise or a short reduction over the small
problem axes, so XLA runs one vectorized loop over the batch per step (no LAPACK
custom calls, no batched tiny matrix products); under `jax.vmap` of `solve` the
kernel receives the whole batch at once (`jax.custom_batching.custom_vmap`). No batch
member's result depends on the others.

The ok flag. `ok` is True iff everything is finite and all three scaled residuals
are <= `tol`. Infeasible problems (whose iterates then diverge), unbounded ones,
non-finite inputs, an A without full row rank (a pivot of its QR below ~sqrt(eps) / 100
of its normalized rows) and ones that simply did not converge in `iterations` get
``ok=False``; their `x`, `y`, `z` and `objective` are zeros and their residual fields
hold the residuals of the last iterate (the largest finite float where those are not
finite), so a near miss can be told from a failure. No output is ever NaN.
Non-finite inputs are swapped for a harmless dummy problem before the solve, with
`jnp.where` on both sides, so no NaN enters the computation.

Precision: tol=1e-6 suits float64 (20-25 iterations reach ~1e-10 on the quadruped QP).
In float32 pass tol ~1e-4.

Requirements (violations give ok=False, not a wrong answer): A must have full row rank,
and N^T Q N + (G N)^T (G N) must be positive definite, i.e. every direction without
curvature (such as a margin variable) must appear in some inequality row.

Gradients (``differentiable=True``): reverse mode only (`jax.grad`, `jax.vjp`; not
`jax.jvp`). `x`, `y`, `z` and `objective` are differentiable with respect to all of
Q, q, A, b, G, h by implicit differentiation of the KKT conditions at the returned
point (OptNet's formulas). The adjoint system [[Q, A^T, G^T], [A, 0, 0], [G, 0, -S/Z]]
is solved in A's null space with the same reduction as the forward pass, followed by
two steps of iterative refinement against the unreduced system (the reduced matrix has
condition ~1e10 at the solution; refinement recovers the lost digits). This is the
exact derivative when the solution is strictly complementary (every active row has
z_i > 0) and the active rows together with A are linearly independent (LICQ). At
degenerate points (duplicated active rows, weakly active rows) the adjoint system
is ill-conditioned but non-singular, since the iterate keeps s, z > 0: the result
is finite but is only the derivative of the interior-point iterate, not a unique
derivative of the solution. The residual fields, `ok` and `iterations` have zero
gradient, and so has `x_scale` (the solution does not depend on it). Instances with
``ok=False`` get zero cotangents and a dummy well-posed adjoint system, so a bad
member of a vmapped batch contributes exactly zero (never NaN) to a gradient.
With ``differentiable=False`` all outputs are wrapped in `stop_gradient`.

Batching: `solve_batch(...)` vmaps `solve` over a leading axis (arrays without it are
shared), or write ``jax.vmap(functools.partial(solve, iterations=25, tol=1e-6))``;
any batch size runs in one call.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
from jax.custom_batching import custom_vmap

__all__ = ["QPSolution", "solve", "solve_batch"]


class QPSolution(NamedTuple):
    x: jax.Array  # (n,) primal solution, caller's units; zeros where not ok
    y: jax.Array  # (m,) equality multipliers, caller's units; zeros where not ok
    z: jax.Array  # (p,) inequality multipliers >= 0, caller's units; zeros where not ok
    primal_residual: jax.Array  # () max(|A x - b|_inf, max(G x - h, 0)), scaled units
    dual_residual: jax.Array  # () |Q x + q + A^T y + G^T z|_inf, scaled units
    complementarity: jax.Array  # () max_i |z_i (h - G x)_i|, scaled units
    objective: jax.Array  # () 0.5 x^T Q x + q^T x, caller's units; zero where not ok
    ok: jax.Array  # () bool: all finite and every residual <= tol
    iterations: jax.Array  # () int32, interior-point iterations run


# --- batch-last dense kernels: every array is (..., B); Python loops run over the
# --- small problem axes only, so each line is one vectorized loop over the batch.

def _fold(op, items):
    """op-reduction of a list of arrays, written as a chain of elementwise ops (XLA fuses
    it into one loop over the batch; a reduce over a leading axis runs much slower)."""
    return functools.reduce(op, items)


def _over0(op, v, empty):
    """op-reduction over the leading axis of v (empty: the value for no rows)."""
    if v.shape[0] == 0:
        return jnp.full(v.shape[1:], empty, v.dtype)
    return _fold(op, [v[i] for i in range(v.shape[0])])


def _sum0(v):
    return _over0(jnp.add, v, 0)


def _max0(v):
    return _over0(jnp.maximum, v, 0)  # used on |.| and residuals: 0 for no rows


def _min0(v):
    return _over0(jnp.minimum, v, jnp.inf)


def _all0(v):
    return _over0(jnp.logical_and, v, True)


def _mv(M, v):
    """M v for M (r, c, B), v (c, B) -> (r, B)."""
    return _fold(jnp.add, [M[:, j] * v[j] for j in range(M.shape[1])])


def _mtv(M, v):
    """M^T v for M (r, c, B), v (r, B) -> (c, B)."""
    return _fold(jnp.add, [M[i] * v[i] for i in range(M.shape[0])])


def _mm(M, N):
    """M N for M (r, c, B), N (c, d, B) -> (r, d, B)."""
    return _fold(jnp.add, [M[:, j][:, None] * N[j][None] for j in range(M.shape[1])])


def _mtm(M, N):
    """M^T N for M (r, c, B), N (r, d, B) -> (c, d, B)."""
    return _fold(jnp.add, [M[i][:, None] * N[i][None] for i in range(M.shape[0])])


_barrier = jax.lax.optimization_barrier


def _normal(P, Gr, w, shift=0.0):
    """Lower triangle of P + shift I + Gr^T diag(w) Gr as nested lists of (B,) entries
    (P (k, k, B), Gr (p, k, B), w (p, B)); materialized once (else XLA recomputes its
    entries inside every column of the factorization)."""
    k = P.shape[0]
    wG = w[:, None] * Gr
    H = [[P[i, j] + _sum0(Gr[:, i] * wG[:, j]) + (shift if i == j else 0.0) for j in range(i + 1)]
         for i in range(k)]
    return _barrier(H)


def _chol(H, tiny):
    """Unrolled Cholesky of a symmetric H given as its lower triangle (nested lists of
    (B,) entries, H[i][j] for j <= i): lower factor as rows of (B,) entries, and the
    inverse diagonal. Pivots are floored at `tiny` (a singular H gives a finite factor)."""
    k = len(H)
    L = [[None] * k for _ in range(k)]
    inv = [None] * k
    for j in range(k):
        d = H[j][j]
        for l in range(j):
            d = d - L[j][l] * L[j][l]
        d = jnp.sqrt(jnp.maximum(d, tiny))
        L[j][j], inv[j] = d, 1.0 / d
        for i in range(j + 1, k):
            e = H[i][j]
            for l in range(j):
                e = e - L[i][l] * L[j][l]
            L[i][j] = e * inv[j]
        # materialize each column: otherwise XLA recomputes it inside every later one
        col = _barrier([L[i][j] for i in range(j, k)] + [inv[j]])
        for i in range(j, k):
            L[i][j] = col[i - j]
        inv[j] = col[-1]
    return L, inv


def _chol_solve(fac, r):
    """x with L L^T x = r, r (k, B)."""
    L, inv = fac
    k = len(inv)
    w = [None] * k
    for i in range(k):
        e = r[i]
        for l in range(i):
            e = e - L[i][l] * w[l]
        w[i] = e * inv[i]
    x = [None] * k
    for i in reversed(range(k)):
        e = w[i]
        for l in range(i + 1, k):
            e = e - L[l][i] * x[l]
        x[i] = e * inv[i]
    return jnp.stack(x)


def _householder(At):
    """Householder QR of At = A^T (n, m, B), m <= n: the reflectors (u_j (n - j, B),
    beta_j (B,)) with Qf = H_0 ... H_{m-1}, H_j = I - beta_j u_j u_j^T on rows j.., and
    R (m, m, B) (upper triangle valid). Qf = [Y | N]: Y spans A's rows, N its null space."""
    m = At.shape[1]
    M = At
    refl = []
    for j in range(m):
        v = M[j:, j]
        norm = jnp.sqrt(_sum0(v * v))
        alpha = jnp.where(v[0] >= 0, -norm, norm)
        u = jnp.concatenate([v[:1] - alpha, v[1:]])
        unorm2 = _sum0(u * u)
        beta = jnp.where(unorm2 > 0, 2.0 / jnp.where(unorm2 > 0, unorm2, 1.0), 0.0)
        proj = _mtv(M[j:], u)  # (m, B)
        M = _barrier(jnp.concatenate([M[:j], M[j:] - beta * u[:, None] * proj[None]]))
        refl.append((u, beta))
    return refl, M[:m]


def _apply_q(refl, X, transpose=False):
    """Qf X (or Qf^T X) for X (n, B) or (n, c, B), applying the reflectors."""
    for j in (range(len(refl)) if transpose else reversed(range(len(refl)))):
        u, beta = refl[j]
        if X.ndim == 3:
            u = u[:, None]
        proj = _sum0(u * X[j:])
        X = _barrier(jnp.concatenate([X[:j], X[j:] - beta * u * proj[None]]))
    return X


def _tri_upper_solve_t(R, b):
    """x with R^T x = b (R upper (m, m, B), b (m, B))."""
    m = R.shape[0]
    x = []
    for i in range(m):
        e = b[i]
        for l in range(i):
            e = e - R[l, i] * x[l]
        x.append(e / R[i, i])
    return jnp.stack(x) if m else b


def _tri_upper_solve(R, b):
    """x with R x = b (R upper (m, m, B), b (m, B))."""
    m = R.shape[0]
    x = [None] * m
    for i in reversed(range(m)):
        e = b[i]
        for l in range(i + 1, m):
            e = e - R[i, l] * x[l]
        x[i] = e / R[i, i]
    return jnp.stack(x) if m else b


class _Elim(NamedTuple):
    refl: list  # Householder reflectors of A^T
    R: jax.Array  # (m, m, B) triangular factor, tiny pivots replaced by 1
    N: jax.Array  # (n, n - m, B) orthonormal null-space basis of A

    def particular(self, b):
        """Minimum-norm solution x of A x = b, b (m, B)."""
        m = self.R.shape[0]
        v = _tri_upper_solve_t(self.R, b)
        pad = jnp.zeros((self.N.shape[0] - m,) + b.shape[1:], b.dtype)
        return _apply_q(self.refl, jnp.concatenate([v, pad]))

    def multipliers(self, g):
        """y with A^T y = g in the least-squares sense (Y^T g = R y), g (n, B)."""
        m = self.R.shape[0]
        return _tri_upper_solve(self.R, _apply_q(self.refl, g, transpose=True)[:m])


def _eliminate(A, rank_tol):
    """Null-space reduction of A x = b (A (m, n, B)): (_Elim, full_rank (B,))."""
    n, m = A.shape[1], A.shape[0]
    refl, R = _householder(jnp.swapaxes(A, 0, 1))
    if m:
        diag = jnp.stack([R[i, i] for i in range(m)])
        full_rank = _all0(jnp.abs(diag) > rank_tol)
        safe = jnp.where(full_rank, diag, 1.0)
        R = jnp.where(jnp.eye(m, dtype=bool)[:, :, None], safe[:, None], R)
    else:
        full_rank = jnp.ones(A.shape[2:], bool)
    basis = jnp.broadcast_to(jnp.eye(n, dtype=A.dtype)[:, m:, None], (n, n - m) + A.shape[2:])
    return _Elim(refl, R, _apply_q(refl, basis)), full_rank


def _polish(P, c, Gr, hr, u, s, z, tiny):
    """Refine an interior-point iterate by solving the KKT system of its active set
    (rows with z > s) as equalities; kept only where it lowers the worst residual
    (reduced, batch-last: P (k, k, B), c (k, B), Gr (p, k, B), hr (p, B))."""
    dtype = c.dtype
    delta = jnp.finfo(dtype).eps ** 0.4
    act = z > s
    w = jnp.where(act, 1.0 / delta, 0.0)
    fac = _chol(_normal(P, Gr, w, delta), tiny)
    up, zp = u, jnp.where(act, z, 0.0)
    for _ in range(POLISH):  # iterative refinement of the regularized KKT solve
        r1 = -c - _mv(P, up) - _mtv(Gr, zp)
        r2 = jnp.where(act, hr - _mv(Gr, up), 0.0)
        du = _chol_solve(fac, r1 + _mtv(Gr, w * r2))
        up = up + du
        zp = zp + jnp.where(act, (_mv(Gr, du) - r2) / delta, 0.0)

    better = (_worst(P, c, Gr, hr, up, zp) <= _worst(P, c, Gr, hr, u, z)) & _all0(zp >= 0)
    better = better & _all0(jnp.isfinite(up)) & _all0(jnp.isfinite(zp))
    return jnp.where(better, up, u), jnp.where(better, zp, z)


def _worst(P, c, Gr, hr, u, z):
    """Largest reduced KKT residual (stationarity, infeasibility, |z_i gap_i|) of (u, z)."""
    rd = _max0(jnp.abs(_mv(P, u) + c + _mtv(Gr, z)))
    gap = hr - _mv(Gr, u)
    rp = _max0(jnp.maximum(-gap, 0.0))
    return jnp.maximum(jnp.maximum(rd, rp), _max0(jnp.abs(z * jnp.maximum(gap, 0.0))))


def _max_step(v, dv):
    """Largest a in [0, 1] with v + a dv >= 0 (v > 0), per batch member."""
    ratio = jnp.where(dv < 0, -v / jnp.where(dv < 0, dv, -1.0), jnp.inf)
    return jnp.minimum(1.0, _min0(ratio))


REFINE = 0
STOP_EXP = 0.7
POLISH = 3
ADJOINT_REFINE = 6


def _ipm(Q, q, A, b, G, h, xw=None, zw=None, *, iterations):
    """Mehrotra predictor-corrector on the null-space-reduced QP (batch-last arrays:
    Q (n, n, B), q (n, B), A (m, n, B), b (m, B), G (p, n, B), h (p, B)).
    Returns x (n, B), y (m, B), z (p, B), s (p, B) and full_rank (B,)."""
    dtype = q.dtype
    eps = jnp.finfo(dtype).eps
    tiny = jnp.finfo(dtype).tiny ** 0.5
    p = h.shape[0]
    el, full_rank = _eliminate(A, jnp.sqrt(eps) * 0.01)
    N, x0 = el.N, el.particular(b)
    P = _mtm(N, _mm(Q, N))  # (k, k, B)
    c = _mtv(N, _mv(Q, x0) + q)  # (k, B)
    Gr = _mm(G, N)  # (p, k, B)
    hr = h - _mv(G, x0)

    def factor(w):
        return _chol(_normal(P, Gr, w), tiny)

    # initial point (as CVXOPT's coneqp): least squares with unit weights, then shifted
    u = _chol_solve(factor(jnp.ones_like(hr)), _mtv(Gr, hr) - c)
    s = hr - _mv(Gr, u)
    s = jnp.where(_min0(s) > 0, s, s + 1.0 - _min0(s))
    z = -(hr - _mv(Gr, u))
    z = jnp.where(_min0(z) > 0, z, z + 1.0 - _min0(z))
    stop = eps ** STOP_EXP  # converged well enough for the polish: keep the iterate
    if xw is not None:
        # warm start: the KKT system of the guessed active set (rows with zw > 0) solved
        # at once; where that point is optimal to rounding level it is taken as converged
        uw = _mtv(N, xw - x0)
        uw, zp = _polish(P, c, Gr, hr, uw, jnp.where(zw > 0, 0.0, 1.0), jnp.maximum(zw, 0.0), tiny)
        good = (_worst(P, c, Gr, hr, uw, zp) <= stop) & _all0(zp >= 0)
        good = good & _all0(jnp.isfinite(uw)) & _all0(jnp.isfinite(zp))
        sp = jnp.maximum(hr - _mv(Gr, uw), 0.0)
        u, s, z = (jnp.where(good, w, v) for w, v in ((uw, u), (sp, s), (zp, z)))

    def body(_, state):
        u, s, z = state
        rd, rp, inv_s = _mv(P, u) + c + _mtv(Gr, z), _mv(Gr, u) + s - hr, 1.0 / s
        sz = s * z
        mu = _sum0(sz) / p
        done = jnp.maximum(_max0(jnp.abs(rd)), _max0(jnp.maximum(jnp.abs(rp), sz))) <= stop
        fac = factor(z * inv_s)

        def newton(r1, r2, r3):
            # P du + Gr^T dz = r1, Gr du + ds = r2, z ds + s dz = r3
            du = _chol_solve(fac, r1 - _mtv(Gr, (r3 - z * r2) * inv_s))
            ds = r2 - _mv(Gr, du)
            return du, ds, (r3 - z * ds) * inv_s

        def direction(rc, refine):
            du, ds, dz = newton(-rd, -rp, -rc)
            for _ in range(refine):  # the reduced matrix loses digits as Z/S grows: refine
                e1 = -rd - _mv(P, du) - _mtv(Gr, dz)
                e2 = -rp - _mv(Gr, du) - ds
                e3 = -rc - z * ds - s * dz
                eu, es, ez = newton(e1, e2, e3)
                du, ds, dz = du + eu, ds + es, dz + ez
            return du, ds, dz

        du, ds, dz = direction(sz, 0)
        a = jnp.minimum(_max_step(s, ds), _max_step(z, dz))
        mu_aff = _sum0((s + a * ds) * (z + a * dz)) / p
        sigma = jnp.clip(mu_aff / mu, 0.0, 1.0) ** 3
        du, ds, dz = direction(sz + ds * dz - sigma * mu, REFINE)
        a = 0.99 * jnp.minimum(_max_step(s, ds), _max_step(z, dz))
        new = (u + a * du, s + a * ds, z + a * dz)
        finite = _all0(jnp.isfinite(new[0])) & _all0(jnp.isfinite(new[1]) & jnp.isfinite(new[2]))
        keep = done | ~finite
        return tuple(jnp.where(keep, o, nw) for o, nw in zip(state, new)), ~jnp.all(done)

    def cond(carry):
        i, _, running = carry
        return (i < iterations) & running

    def step(carry):
        i, state, _ = carry
        state, running = body(i, state)
        return i + 1, state, running

    # A converged member is frozen, so stopping once all are converged (or after
    # `iterations`) gives every member exactly what `iterations` steps would.
    _, (u, s, z), _ = jax.lax.while_loop(cond, step, (0, (u, s, z), jnp.asarray(True)))
    u, z = _polish(P, c, Gr, hr, u, s, z, tiny)
    x = x0 + _mv(N, u)
    g = _mv(Q, x) + q + _mtv(G, z)
    y = -el.multipliers(g)
    return x, y, z, s, full_rank


def _fwd_kernel(Q, q, A, b, G, h, xw=None, zw=None, *, iterations, tol):
    """`_ipm` plus the scaled residuals and the ok flag (batch-last)."""
    x, y, z, s, full_rank = _ipm(Q, q, A, b, G, h, xw, zw, iterations=iterations)
    slack = h - _mv(G, x)
    primal = jnp.maximum(_max0(jnp.abs(_mv(A, x) - b)),
                         _max0(-slack))
    dual = _max0(jnp.abs(_mv(Q, x) + q + _mtv(A, y) + _mtv(G, z)))
    comp = _max0(jnp.abs(z * slack))
    ok = (jnp.maximum(jnp.maximum(primal, dual), comp) <= tol) & full_rank
    ok = ok & _all0(jnp.isfinite(s)) & _all0(z >= 0)
    big = jnp.finfo(x.dtype).max
    primal, dual, comp = (jnp.where(jnp.isfinite(r), r, big) for r in (primal, dual, comp))
    x, y, z = (jnp.where(ok, v, 0.0) for v in (x, y, z))
    s = jnp.where(ok, s, 1.0)  # safe slack for the adjoint solve of a bad instance
    return x, y, z, s, primal, dual, comp, ok


def _adjoint_kernel(Q, A, G, h, x, z, ok, gx, gy, gz):
    """(dx, dy, w) solving [[Q, A^T, G^T], [A, 0, 0], [G, 0, -S/Z]] (dx, dy, w) = -(gx, gy, gz)
    at the returned point (batch-last; S = slack h - G x, and w_i = 0 where z_i = 0).
    The solve uses S/Z floored at delta = eps^0.4 (so the reduced matrix stays well
    conditioned) and iterative refinement against the exact system. A bad instance
    gets a dummy well-posed system and zero right-hand side."""
    n, m = Q.shape[0], A.shape[0]
    dtype = Q.dtype
    eye = jnp.eye(n, dtype=dtype)[:, :, None]
    Q = jnp.where(ok, Q, eye)
    A = jnp.where(ok, A, eye[:m])
    G = jnp.where(ok, G, 0.0)
    z = jnp.where(ok, z, 1.0)
    s = jnp.where(ok, jnp.maximum(h - _mv(G, x), 0.0), 1.0)
    gx, gy, gz = (jnp.where(ok, g, 0.0) for g in (gx, gy, gz))
    delta = jnp.finfo(dtype).eps ** 0.4
    live = z > 0
    zsafe = jnp.where(live, z, 1.0)
    W = jnp.where(live, z / jnp.maximum(s, delta * zsafe), 0.0)  # floored S/Z, inverted
    D = s / zsafe  # exact S/Z on live rows
    el, _ = _eliminate(A, jnp.asarray(0.0, dtype))
    N = el.N
    P = _mtm(N, _mm(Q, N))
    Gr = _mm(G, N)
    fac = _chol(_normal(P, Gr, W), jnp.finfo(dtype).tiny ** 0.5)

    def hess(v):
        return _mv(Q, v) + _mtv(G, W * _mv(G, v))

    def kkt(a, bb, c):
        rhs = a + _mtv(G, W * c)
        xp = el.particular(bb)
        dx = xp + _mv(N, _chol_solve(fac, _mtv(N, rhs - hess(xp))))
        dy = el.multipliers(rhs - hess(dx))
        return dx, dy, W * (_mv(G, dx) - c)

    a, bb, c = -gx, -gy, -gz
    dx, dy, w = kkt(a, bb, c)
    for _ in range(ADJOINT_REFINE):  # iterative refinement against the exact system
        r1 = a - (_mv(Q, dx) + _mtv(A, dy) + _mtv(G, w))
        r2 = bb - _mv(A, dx)
        r3 = jnp.where(live, c - (_mv(G, dx) - D * w), 0.0)
        ex, ey, ew = kkt(r1, r2, r3)
        dx, dy, w = dx + ex, dy + ey, w + ew
    return dx, dy, w


def _per_instance(kernel):
    """One-instance form of a batch-last kernel; under `jax.vmap` it runs the kernel once
    on the whole batch (moved to the last axis) instead of batching its operations."""

    @custom_vmap
    def one(*args):
        out = kernel(*(a[..., None] for a in args))
        return tuple(o[..., 0] for o in out)

    @one.def_vmap
    def rule(axis_size, in_batched, *args):
        moved = [jnp.moveaxis(a, 0, -1) if bat else jnp.broadcast_to(a[..., None], a.shape + (axis_size,))
                 for a, bat in zip(args, in_batched)]
        out = tuple(jnp.moveaxis(o, -1, 0) for o in kernel(*moved))
        return out, (True,) * len(out)

    return one


@functools.cache
def _forward_fn(iterations, tol):
    return _per_instance(functools.partial(_fwd_kernel, iterations=iterations, tol=tol))


_adjoint = _per_instance(_adjoint_kernel)


def _forward(data, iterations, tol, warm=None):
    """Run the interior-point method (at most `iterations` steps): sanitized iterate,
    residuals, ok and the iteration count. `warm`: (x, z) guess in scaled units."""
    out = _forward_fn(iterations, tol)(*data, *(warm or ()))
    return (*out, jnp.asarray(iterations, jnp.int32))


@functools.partial(jax.custom_vjp, nondiff_argnums=(8, 9, 10))
def _solve_diff(Q, q, A, b, G, h, xw, zw, iterations, tol, warm):
    return _forward((Q, q, A, b, G, h), iterations, tol, (xw, zw) if warm else None)


def _solve_diff_fwd(Q, q, A, b, G, h, xw, zw, iterations, tol, warm):
    out = _forward((Q, q, A, b, G, h), iterations, tol, (xw, zw) if warm else None)
    x, y, z, _, *_, ok, _ = out
    return out, (Q, A, G, h, x, y, z, ok, jnp.zeros_like(xw), jnp.zeros_like(zw))


def _solve_diff_bwd(iterations, tol, warm, saved, cts):
    del iterations, tol, warm
    Q, A, G, h, x, y, z, ok, zx, zz = saved
    dx, dy, w = _adjoint(Q, A, G, h, x, z, ok, *cts[:3])
    grads = (
        0.5 * (jnp.outer(dx, x) + jnp.outer(x, dx)),
        dx,
        jnp.outer(dy, x) + jnp.outer(y, dx),
        -dy,
        jnp.outer(w, x) + jnp.outer(z, dx),
        -w,
    )
    return (*(jnp.where(ok, g, 0.0) for g in grads), zx, zz)  # the warm start has no gradient


_solve_diff.defvjp(_solve_diff_fwd, _solve_diff_bwd)


def _row_norms(M):
    norms = jnp.sqrt(jnp.sum(M * M, axis=1))
    return jnp.where(norms > 0, norms, 1.0)


def solve(Q, q, A, b, G, h, *, x_scale=None, iterations: int = 25, tol: float = 1e-6,
          differentiable: bool = True, warm_start=None) -> QPSolution:
    """Solve one QP (see the module docstring); jit/vmap compatible, float32 or float64.

    Shapes: Q (n, n), q (n,), A (m, n), b (m,), G (p, n), h (p,), x_scale (n,) > 0.
    `iterations` (static int >= 1): the interior-point iteration budget (a converged
    member stops changing, so the result is that of all of them).
    `tol` (static float): bound on the scaled residuals for ``ok``.
    `warm_start`: optional (x (n,), z (p,)) in the caller's units, e.g. the previous
    solution of a slowly changing problem: its active set (z_i > 0) is tried first, and
    where that gives the optimum (to rounding level) no iteration is needed; otherwise
    the solve starts cold. The result is the same optimum either way (not
    differentiated with respect to the guess).
    """
    if int(iterations) != iterations or iterations < 1:
        raise ValueError(f"iterations must be a positive int, got {iterations!r}")
    dtype = jnp.result_type(Q, q, A, b, G, h, 0.0)
    Q, q, A, b, G, h = (jnp.asarray(v, dtype) for v in (Q, q, A, b, G, h))
    if not differentiable:
        Q, q, A, b, G, h = (jax.lax.stop_gradient(v) for v in (Q, q, A, b, G, h))
    n, m = q.shape[0], b.shape[0]
    Q = 0.5 * (Q + Q.T)
    off = jnp.isposinf(h)  # h = +inf: disabled row
    G = jnp.where(off[:, None], 0.0, G)
    h = jnp.where(off, 1.0, h)
    d = jnp.ones(n, dtype) if x_scale is None else jnp.asarray(x_scale, dtype)
    finite = jnp.all(jnp.stack([jnp.all(jnp.isfinite(v)) for v in (Q, q, A, b, G, h, d)]))
    finite = finite & jnp.all(d > 0)
    # Double where: a non-finite instance is replaced by a dummy (and its gradient is 0).
    Q = jnp.where(finite, Q, jnp.eye(n, dtype=dtype))
    q = jnp.where(finite, q, 0.0)
    A = jnp.where(finite, A, jnp.eye(m, n, dtype=dtype))
    b = jnp.where(finite, b, 0.0)
    G = jnp.where(finite, G, 0.0)
    h = jnp.where(finite, h, 1.0)
    d = jax.lax.stop_gradient(jnp.where(finite, d, 1.0))
    # Scale factors are constants for autodiff: x, y, z of the caller's problem do not
    # depend on them, so the derivative at fixed factors is the exact derivative.
    Qd, qd, Ad, Gd = d[:, None] * Q * d[None, :], d * q, A * d[None, :], G * d[None, :]
    ra, rg = jax.lax.stop_gradient(_row_norms(Ad)), jax.lax.stop_gradient(_row_norms(Gd))
    c = jnp.maximum(jnp.max(jnp.abs(Qd)), jnp.max(jnp.abs(qd), initial=0.0))
    c = jax.lax.stop_gradient(jnp.maximum(c, 1e-12))
    data = (Qd / c, qd / c, Ad / ra[:, None], b / ra, Gd / rg[:, None], h / rg)
    warm = warm_start is not None
    if warm:
        xw, zw = (jax.lax.stop_gradient(jnp.asarray(v, dtype)) for v in warm_start)
        xw, zw = xw / d, zw * rg / c
        use = finite & jnp.all(jnp.isfinite(xw)) & jnp.all(jnp.isfinite(zw))
        xw, zw = jnp.where(use, xw, 0.0), jnp.where(use & ~off, zw, 0.0)
    else:
        xw, zw = jnp.zeros(n, dtype), jnp.zeros(h.shape[0], dtype)
    if differentiable:
        out = _solve_diff(*data, xw, zw, int(iterations), float(tol), warm)
    else:
        out = _forward(data, int(iterations), float(tol), (xw, zw) if warm else None)
    xs, ys, zs, _, primal, dual, comp, ok, iters = out
    ok = ok & finite
    big = jnp.finfo(dtype).max  # residuals of the dummy stand-in would mislead
    primal, dual, comp = (jnp.where(finite, r, big) for r in (primal, dual, comp))
    x = jnp.where(ok, d * xs, 0.0)
    y = jnp.where(ok, c * ys / ra, 0.0)
    z = jnp.where(ok, c * zs / rg, 0.0)
    objective = jnp.where(ok, jnp.sum(x * (0.5 * jnp.sum(Q * x[None, :], axis=1) + q)), 0.0)
    sol = QPSolution(x, y, z, primal, dual, comp, objective, ok, iters)
    return sol if differentiable else jax.tree_util.tree_map(jax.lax.stop_gradient, sol)


_BASE_NDIM = (2, 1, 2, 1, 2, 1, 1)  # Q, q, A, b, G, h, x_scale


def solve_batch(Q, q, A, b, G, h, *, x_scale=None, iterations: int = 25, tol: float = 1e-6,
                differentiable: bool = True, sequential: bool = False, warm_start=None) -> QPSolution:
    """`solve` over a leading batch axis: `jax.vmap` or, if `sequential`, `jax.lax.map`.

    Each of Q, q, A, b, G, h, x_scale may carry the batch axis (shape (B, ...)) or not
    (shared by all members; at least one must carry it); `warm_start` (x (B, n), z (B, p))
    is per member. Returns a batched QPSolution.
    Any batch size runs in one call (the solver uses no LAPACK custom calls);
    `sequential=True` solves one instance at a time (same results, much slower; kept
    for comparison and for memory-bound uses).
    """
    fn = functools.partial(solve, iterations=iterations, tol=tol, differentiable=differentiable)
    args = [jnp.asarray(v) for v in (Q, q, A, b, G, h, 1.0 if x_scale is None else x_scale)]
    axes = [0 if v.ndim == k + 1 else None for v, k in zip(args, _BASE_NDIM)]
    if x_scale is None:
        axes[6] = None
    if warm_start is not None:
        args += [jnp.asarray(v) for v in warm_start]
        axes += [0, 0]

    def call(*a):
        warm = None if warm_start is None else (a[7], a[8])
        return fn(*a[:6], x_scale=None if x_scale is None else a[6], warm_start=warm)

    if not sequential:
        return jax.vmap(call, in_axes=axes)(*args)
    mapped = [a for a, ax in zip(args, axes) if ax == 0]

    def one(ms):
        it = iter(ms)
        return call(*(next(it) if ax == 0 else a for a, ax in zip(args, axes)))

    return jax.lax.map(one, mapped)
