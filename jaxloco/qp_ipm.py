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
3. Every member runs exactly `iterations` iterations (a fixed-length loop: under `vmap`
   no member waits on, or depends on, another; a problem that breaks down, such as an
   infeasible one, ends with a non-finite iterate). There is no early
   stop on a residual: s and z are floored at sqrt(eps) in every step, as in qpax, which
   keeps the factorization well-conditioned but also keeps the complementarity of
   inactive rows near 1e-8, so a stopping test would need to know the problem's scale.
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


class _Reduced(NamedTuple):
    """The problem in u, x = x0 + Z u: min 0.5 u^T Q u + q^T u s.t. G u <= h."""

    Q: Array  # (k, k)
    q: Array  # (k,)
    G: Array  # (p, k)
    h: Array  # (p,)


def _reduce(Q, q, G, h, x0, Z) -> _Reduced:
    QZ = Q @ Z
    Qr = Z.T @ QZ
    return _Reduced(0.5 * (Qr + Qr.T), Z.T @ (Q @ x0 + q), G @ Z, h - G @ x0)


def _direction(L, red: _Reduced, D, r_d, r_p, r_c, s):
    """Newton step of Q du + G^T dz = -r_d, G du + ds = -r_p, Z ds + S dz = -r_c."""
    rc_s = r_c / s
    du = linalg.cho_solve_scalars(L, red.G.T @ (rc_s - D * r_p) - r_d)
    Gdu = red.G @ du
    return du, -r_p - Gdu, -rc_s + D * (r_p + Gdu)


def _max_step(v, dv):
    """Largest alpha in [0, 1] with v + alpha dv >= 0 (v > 0)."""
    neg = dv < 0
    return jnp.minimum(1.0, jnp.min(jnp.where(neg, -v / jnp.where(neg, dv, -1.0), 1.0)))


def _residuals(red: _Reduced, u, s, z):
    return red.Q @ u + red.q + red.G.T @ z, red.G @ u + s - red.h


def _start(red: _Reduced):
    """CVXOPT's initial point: the least-squares solution with s = z = 1, then s and z
    shifted into the positive orthant."""
    H = red.Q + red.G.T @ red.G
    u = linalg.cho_solve_scalars(linalg.cholesky_scalars(H), red.G.T @ red.h - red.q)
    r = red.G @ u - red.h  # = -s
    worst_s, worst_z = jnp.max(r), -jnp.min(r)
    s = jnp.where(worst_s < 0, -r, -r + 1.0 + worst_s)
    z = jnp.where(worst_z < 0, r, r + 1.0 + worst_z)
    return u, s, z


def _mehrotra_step(red: _Reduced, state: _Iterate) -> _Iterate:
    # qpax's safeguard: slacks and multipliers never fall below sqrt(machine epsilon),
    # which bounds the condition of H (z / s stays below ~1e8 z).
    floor = jnp.sqrt(jnp.finfo(state.s.dtype).eps)
    u, s, z = state.u, jnp.maximum(state.s, floor), jnp.maximum(state.z, floor)
    p = s.shape[0]
    r_d, r_p = _residuals(red, u, s, z)
    D = z / s
    L = linalg.cholesky_scalars(red.Q + (red.G.T * D) @ red.G)
    sz = s * z
    mu = jnp.sum(sz) / p
    _, ds_a, dz_a = _direction(L, red, D, r_d, r_p, sz, s)
    alpha = jnp.minimum(_max_step(s, ds_a), _max_step(z, dz_a))
    mu_aff = jnp.sum((s + alpha * ds_a) * (z + alpha * dz_a)) / p
    sigma = jnp.clip(mu_aff / mu, 0.0, 1.0) ** 3
    du, ds, dz = _direction(L, red, D, r_d, r_p, sz + ds_a * dz_a - sigma * mu, s)
    alpha = jnp.minimum(1.0, 0.99 * jnp.minimum(_max_step(s, ds), _max_step(z, dz)))
    return _Iterate(u + alpha * du, s + alpha * ds, z + alpha * dz)


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
    u, s, z = _start(red)
    final = jax.lax.fori_loop(0, iterations, lambda _, st: _mehrotra_step(red, st), _Iterate(u, s, z))
    x = x0 + Z @ final.u
    if m:
        y = linalg.solve_upper(ns.R, -(ns.Y.T @ (Q @ x + q + G.T @ final.z)))
    else:
        y = jnp.zeros((0,), q.dtype)
    return IPMResult(x, y, final.z, final.s, jnp.asarray(iterations, jnp.int32))
