"""Small dense linear solves in plain XLA operations (no LAPACK custom calls).

Why: on the CPU, jax 0.10.2 runs `jnp.linalg.solve` / `cholesky` as LAPACK custom calls;
batched over two CPU devices inside a `lax.scan` (as a sweep shards its rows over the
cores) with a per-device batch above about 32, such programs hang: every device's
execution waits on the runtime's thread pool (seen with the T² Snake-3 controller's
weighted pseudo-inverse; the same solve alone, or one device, runs). The systems here
are tiny (up to ~20 unknowns), so an unrolled Cholesky factorization costs little,
differentiates with ordinary autodiff and keeps every program free of custom calls.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

Array = jax.Array


def cholesky(M: Array) -> Array:
    """Lower-triangular L with L L^T = M for a symmetric positive definite M (n, n),
    unrolled over the n columns (n is static)."""
    n = M.shape[-1]
    L = jnp.zeros_like(M)
    rows = jnp.arange(n)
    for j in range(n):
        col = M[:, j] - L[:, :j] @ L[j, :j]
        d = jnp.sqrt(col[j])
        L = L.at[:, j].set(jnp.where(rows > j, col / d, jnp.where(rows == j, d, 0.0)))
    return L


def _forward(L: Array, B: Array) -> Array:
    """Solve L Y = B (L lower triangular, B (n, k))."""
    Y = jnp.zeros_like(B)
    for i in range(L.shape[0]):
        Y = Y.at[i].set((B[i] - L[i, :i] @ Y[:i]) / L[i, i])
    return Y


def _backward(U: Array, B: Array) -> Array:
    """Solve U X = B (U upper triangular, B (n, k))."""
    n = U.shape[0]
    X = jnp.zeros_like(B)
    for i in reversed(range(n)):
        X = X.at[i].set((B[i] - U[i, i + 1 :] @ X[i + 1 :]) / U[i, i])
    return X


def _solve_with_factor(L: Array, B: Array) -> Array:
    """X with L L^T X = B (L lower triangular, B (n, k))."""
    return _backward(L.T, _forward(L, B))


@jax.custom_jvp
def _solve(M: Array, B: Array) -> Array:
    return _solve_with_factor(cholesky(M), B)


@_solve.defjvp
def _solve_jvp(primals, tangents):
    """d(M^-1 B) = M^-1 (dB - dM M^-1 B): two triangular solves with the primal's factor,
    instead of differentiating the unrolled factorization (smaller programs to compile
    and run; linear in the tangents, so reverse mode transposes it; differentiable
    again for higher orders)."""
    M, B = primals
    dM, dB = tangents
    L = cholesky(M)
    X = _solve_with_factor(L, B)
    return X, _solve_with_factor(L, dB - dM @ X)


def spd_solve(M: Array, B: Array) -> Array:
    """X with M X = B for a symmetric positive definite M (n, n); B (n,) or (n, k).
    Derivatives follow M^-1 (dB - dM X), which along symmetric dM (the only ones a
    symmetric M has) is the derivative of the factorization's solve."""
    vector = B.ndim == 1
    X = _solve(M, B[:, None] if vector else B)
    return X[:, 0] if vector else X
