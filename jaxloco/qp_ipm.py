"""A primal-dual interior-point method for one tiny dense QP, in plain XLA operations.

    minimize 0.5 x^T Q x + q^T x   subject to   A x = b,  G x <= h

Written for thousands of tiny problems (n <= ~20) solved at once under `jax.vmap` on
a CPU: every matrix product is one batched `dot_general`, and the sequential parts
(the Cholesky factorization and the triangular solves of the k x k reduced system) are
unrolled scalar by scalar, so `vmap` turns each of their scalar operations into one
elementwise operation over the batch, which XLA fuses into a few loops (the scalar forms
of `jaxloco.linalg`). No LAPACK
custom call is emitted (batched LAPACK calls can deadlock XLA's CPU thread pool).

Method (in the caller's units; the caller, `jaxloco.qp`, scales the problem first):
1. The equalities are removed once: a Householder QR of A^T (n x m) gives A^T = Y R
   and an orthonormal null-space basis Z (n x k, k = n - m), so x = x0 + Z u with
   x0 = Y R^-T b.
2. Mehrotra's predictor-corrector method on the reduced problem in u (k unknowns, p
   inequalities, slacks s and multipliers z), each iteration factorizing
   H = Z^T Q Z + G_r^T diag(z / s) G_r once, started from CVXOPT's least-squares point.
   The products of G_r's columns are computed once, so forming H's lower triangle in an
   iteration is one (p,) x (p, k(k+1)/2) product; G_r u and Q_r u are carried along
   with u (updated by the step's own G_r du and Q_r du), and the G_r^T z of the dual
   residual cancels from the Newton right-hand side in closed form, so an iteration
   holds five small matrix products instead of eight.
3. Every member runs exactly `iterations` iterations (a fixed-length loop: under `vmap`
   no member waits on, or depends on, another; a problem that breaks down, such as an
   infeasible one, ends with a non-finite iterate). There is no early
   stop on a residual: s and z are floored at sqrt(eps) in every step, as in qpax, which
   keeps the factorization well-conditioned but also keeps the complementarity of
   inactive rows near 1e-8, so a stopping test would need to know the problem's scale.
   (Tried on 6 Dec 2026, with the residuals of the scaled problem: a per-member stop as
   a vmapped `while_loop` ran 57,000-63,000 contact QPs/s against 85,000 for the fixed
   20 iterations, and a stop at 1e-6 left answers 5e-4 from clarabel's, since the
   margin variable has no curvature.)
4. The equality multipliers come from stationarity by least squares,
   y = -R^-1 Y^T (Q x + q + G^T z).

Requirements: A has full row rank and Z^T (Q + G^T G) Z is positive definite (every
direction without curvature appears in some inequality). Violations give non-finite or
non-converged iterates, which `jaxloco.qp` reports as ``ok=False``.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco import linalg

Array = jax.Array

__all__ = ["IPMResult", "NullSpace", "null_space", "solve_ipm"]


# ------------------------------------------------------------------ equality removal
class NullSpace(NamedTuple):
    """A^T = Y R with [Y Z] orthogonal (n, n) and R upper triangular (m, m)."""

    Y: Array  # (n, m)
    Z: Array  # (n, k)
    R: Array  # (m, m)


def null_space(A: Array) -> NullSpace:
    """Householder QR of A^T for A (m, n), m <= n, unrolled over the m reflectors.

    Rank deficiency shows as a (near) zero diagonal entry of R."""
    m, n = A.shape
    W = A.T
    rows = jnp.arange(n)
    reflectors = []
    for j in range(m):
        x = jnp.where(rows >= j, W[:, j], 0.0)
        norm = jnp.sqrt(x @ x)
        alpha = jnp.where(W[j, j] >= 0, -norm, norm)
        v = x - jnp.where(rows == j, alpha, 0.0)
        vv = v @ v
        beta = jnp.where(vv > 0, 2.0 / jnp.where(vv > 0, vv, 1.0), 0.0)
        W = W - jnp.outer(beta * v, v @ W)
        reflectors.append((v, beta))
    R = jnp.triu(W[:m, :])
    E = jnp.eye(n, dtype=A.dtype)
    for v, beta in reversed(reflectors):
        E = E - jnp.outer(beta * v, v @ E)
    return NullSpace(E[:, :m], E[:, m:], R)


# ------------------------------------------------------------------- interior point
class IPMResult(NamedTuple):
    x: Array  # (n,)
    y: Array  # (m,)
    z: Array  # (p,) >= 0
    s: Array  # (p,) slacks h - G x, >= 0
    iterations: Array  # () int32


class _Iterate(NamedTuple):
    u: Array  # (k,) reduced primal variables
    s: Array  # (p,) slacks
    z: Array  # (p,) multipliers
    Gu: Array  # (p,) G u, updated with the steps (no product with G per iteration)
    Qu: Array  # (k,) Q u, likewise


class _Reduced(NamedTuple):
    """The problem in u, x = x0 + Z u: min 0.5 u^T Q u + q^T u s.t. G u <= h, with the
    loop-invariant pieces of the Newton matrix H = Q + G^T diag(D) G precomputed."""

    Q: Array  # (k, k)
    q: Array  # (k,)
    G: Array  # (p, k)
    h: Array  # (p,)
    Q_lower: Array  # (k(k+1)/2,) lower triangle of Q, packed row by row
    GG: Array  # (p, k(k+1)/2) G[r, i] G[r, j] for i >= j, packed alike: H_lower = Q_lower + D @ GG
    GQ: Array  # (p + k, k) G stacked on Q: G du and Q du in one product


def _reduce(Q, q, G, h, x0, Z) -> _Reduced:
    QZ = Q @ Z
    Qr = Z.T @ QZ
    Qr = 0.5 * (Qr + Qr.T)
    Gr = G @ Z
    rows, cols = np.tril_indices(Z.shape[1])
    return _Reduced(Qr, Z.T @ (Q @ x0 + q), Gr, h - G @ x0, Qr[rows, cols], Gr[:, rows] * Gr[:, cols],
                    jnp.concatenate([Gr, Qr]))


def _direction(L, red: _Reduced, D, Qu, r_p, w, z, *, with_Qdu=False):
    """Newton step of Q du + G^T dz = -r_d, G du + ds = -r_p, Z ds + S dz = -r_c, with
    the dual residual r_d = Q u + q + G^T z and r_c = S (z + w): the G^T z terms cancel
    in closed form, so the right-hand side is G^T (w - D r_p) - (Q u + q).
    Returns du, ds, dz and the products G du, Q du (None unless `with_Qdu`)."""
    p = z.shape[0]
    du = linalg.cho_solve_scalars(L, red.G.T @ (w - D * r_p) - (Qu + red.q))
    if with_Qdu:
        GQdu = red.GQ @ du
        Gdu, Qdu = GQdu[:p], GQdu[p:]
    else:
        Gdu, Qdu = red.G @ du, None
    return du, -r_p - Gdu, -(z + w) + D * (r_p + Gdu), Gdu, Qdu


def _max_step(v, dv):
    """Largest alpha in [0, 1] with v + alpha dv >= 0 (v > 0)."""
    neg = dv < 0
    return jnp.minimum(1.0, jnp.min(jnp.where(neg, -v / jnp.where(neg, dv, -1.0), 1.0)))


def _start(red: _Reduced):
    """CVXOPT's initial point: the least-squares solution with s = z = 1, then s and z
    shifted into the positive orthant."""
    H = red.Q + red.G.T @ red.G
    u = linalg.cho_solve_scalars(linalg.cholesky_scalars(H), red.G.T @ red.h - red.q)
    r = red.G @ u - red.h  # = -s
    worst_s, worst_z = jnp.max(r), -jnp.min(r)
    s = jnp.where(worst_s < 0, -r, -r + 1.0 + worst_s)
    z = jnp.where(worst_z < 0, r, r + 1.0 + worst_z)
    return _Iterate(u, s, z, red.G @ u, red.Q @ u)


def _mehrotra_step(red: _Reduced, state: _Iterate) -> _Iterate:
    # qpax's safeguard: slacks and multipliers never fall below sqrt(machine epsilon),
    # which bounds the condition of H (z / s stays below ~1e8 z).
    floor = jnp.sqrt(jnp.finfo(state.s.dtype).eps)
    s, z = jnp.maximum(state.s, floor), jnp.maximum(state.z, floor)
    p = s.shape[0]
    r_p = state.Gu + s - red.h
    D = z / s
    # H = Q + G^T diag(D) G as one (p,) x (p, k(k+1)/2) product with the precomputed
    # column products (one core, batch 128: 1,150 -> 790 ns per iteration and member,
    # against forming (G^T D) G; 6 Dec 2026).
    L = linalg.cholesky_packed_scalars(red.Q_lower + D @ red.GG, red.Q.shape[0])
    sz = s * z
    mu = jnp.sum(sz) / p
    # predictor: r_c = S z (w = 0); corrector: r_c = S z + ds_a dz_a - sigma mu
    _, ds_a, dz_a, _, _ = _direction(L, red, D, state.Qu, r_p, jnp.zeros_like(z), z)
    alpha = jnp.minimum(_max_step(s, ds_a), _max_step(z, dz_a))
    mu_aff = jnp.sum((s + alpha * ds_a) * (z + alpha * dz_a)) / p
    sigma = jnp.clip(mu_aff / mu, 0.0, 1.0) ** 3
    du, ds, dz, Gdu, Qdu = _direction(L, red, D, state.Qu, r_p, (ds_a * dz_a - sigma * mu) / s, z,
                                      with_Qdu=True)
    alpha = jnp.minimum(1.0, 0.99 * jnp.minimum(_max_step(s, ds), _max_step(z, dz)))
    return _Iterate(state.u + alpha * du, s + alpha * ds, z + alpha * dz,
                    state.Gu + alpha * Gdu, state.Qu + alpha * Qdu)


def solve_ipm(Q: Array, q: Array, A: Array, b: Array, G: Array, h: Array, *,
              iterations: int) -> IPMResult:
    """Solve one QP: Q (n, n) symmetric, q (n,), A (m, n), b (m,), G (p, n), h (p,).

    `iterations`: the number of Mehrotra iterations (static)."""
    n, m = q.shape[0], b.shape[0]
    if m:
        ns = null_space(A)
        x0 = ns.Y @ linalg.solve_upper_transposed(ns.R, b)
        Z = ns.Z
    else:
        x0, Z = jnp.zeros_like(q), jnp.eye(n, dtype=q.dtype)
    red = _reduce(Q, q, G, h, x0, Z)
    final = jax.lax.fori_loop(0, iterations, lambda _, st: _mehrotra_step(red, st), _start(red))
    x = x0 + Z @ final.u
    if m:
        y = linalg.solve_upper(ns.R, -(ns.Y.T @ (Q @ x + q + G.T @ final.z)))
    else:
        y = jnp.zeros((0,), q.dtype)
    return IPMResult(x, y, final.z, final.s, jnp.asarray(iterations, jnp.int32))
