"""`linalg.spd_solve` (unrolled Cholesky, plain XLA ops): equal to numpy's LAPACK solve
on random symmetric positive definite systems of the sizes the controllers use
(n = 1, 6, 18), for vector and matrix right-hand sides, in float64 and float32; its
derivatives (autodiff through the unrolled factorization) against finite differences;
and no custom calls in the compiled program (why the module exists). The scalar forms
(`cholesky_scalars`, `cho_solve_scalars`) and the closed forms (`solve_2x2`, `det_3x3`)
against NumPy."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads

from jaxloco import linalg

_SOLVE = jax.jit(linalg.spd_solve)
_CHOL = jax.jit(linalg.cholesky)


def _spd(n: int, seed: int, cond: float = 1e3) -> np.ndarray:
    """A random SPD matrix with eigenvalues log-spaced in [1, cond] (a random basis)."""
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.normal(size=(n, n)))
    return (Q * np.logspace(0, np.log10(cond), n)) @ Q.T


# float32: relative error of a solve is about cond * eps32 = 1e3 * 6e-8
TOLS = {np.float64: 1e-10, np.float32: 2e-3}


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("n", [1, 6, 18])
@pytest.mark.parametrize("rhs", ["vector", "matrix"])
def test_spd_solve_matches_numpy(n, rhs, dtype):
    rng = np.random.default_rng(n)
    M = _spd(n, seed=10 + n)
    B = rng.normal(size=(n,) if rhs == "vector" else (n, 3))
    X = _SOLVE(jnp.asarray(M, dtype), jnp.asarray(B, dtype))
    assert X.dtype == dtype and X.shape == B.shape
    expected = np.linalg.solve(M, B)  # float64 LAPACK on the exact (float64) data
    err = np.abs(np.asarray(X, np.float64) - expected).max() / np.abs(expected).max()
    assert err < TOLS[dtype], err
    # the factor itself: lower triangular, L L^T = M
    L = np.asarray(_CHOL(jnp.asarray(M)))
    assert np.allclose(np.triu(L, 1), 0.0)
    assert np.allclose(L @ L.T, M, rtol=0, atol=1e-10 * np.abs(M).max())
    assert np.allclose(L, np.linalg.cholesky(M), atol=1e-9)


def test_spd_solve_batched_under_vmap():
    Ms = np.stack([_spd(6, seed=s) for s in range(4)])
    Bs = np.random.default_rng(0).normal(size=(4, 6))
    X = jax.jit(jax.vmap(linalg.spd_solve))(jnp.asarray(Ms), jnp.asarray(Bs))
    for i in range(4):
        assert np.allclose(X[i], np.linalg.solve(Ms[i], Bs[i]), rtol=0, atol=1e-10)


def test_gradients_through_the_solve():
    """Forward and reverse mode, first and second order, w.r.t. both M and B (M kept
    symmetric, as callers pass it: the derivative of a Cholesky solve is only defined
    along symmetric directions)."""
    n = 6
    M0 = _spd(n, seed=3, cond=20.0)
    B0 = np.random.default_rng(1).normal(size=(n, 2))

    @jax.jit
    def f(S, B):
        return linalg.spd_solve(jnp.asarray(M0) + 0.5 * (S + S.T), B)

    S = jnp.zeros((n, n))
    check_grads(f, (S, jnp.asarray(B0)), order=2, modes=("fwd", "rev"), atol=1e-6, rtol=1e-6)
    # the analytic derivative: d(M^-1 B)/dM [dM] = -M^-1 dM M^-1 B
    dS = np.random.default_rng(2).normal(size=(n, n))
    _, tangent = jax.jvp(f, (S, jnp.asarray(B0)), (jnp.asarray(dS), jnp.zeros_like(B0)))
    dM = 0.5 * (dS + dS.T)
    expected = -np.linalg.solve(M0, dM @ np.linalg.solve(M0, B0))
    assert np.allclose(tangent, expected, rtol=0, atol=1e-10)


def test_no_custom_calls_in_the_compiled_program():
    M = jnp.asarray(_spd(18, seed=0))
    text = _SOLVE.lower(M, jnp.ones(18)).as_text()
    assert "custom_call" not in text and "lapack" not in text.lower()


def test_scalar_cholesky_and_solve_match_numpy():
    rng = np.random.default_rng(1)
    B = rng.normal(size=(7, 7))
    M = B @ B.T + 0.1 * np.eye(7)
    r = rng.normal(size=7)
    L = linalg.cholesky_scalars(jnp.asarray(M))
    dense = np.array([[float(L[i][j]) if j <= i else 0.0 for j in range(7)] for i in range(7)])
    np.testing.assert_allclose(dense, np.linalg.cholesky(M), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(linalg.cho_solve_scalars(L, jnp.asarray(r)), np.linalg.solve(M, r), rtol=1e-10)
    rows, cols = np.tril_indices(7)
    assert len(rows) == 28 and all(i >= j for i, j in zip(rows, cols))
    packed = linalg.cholesky_packed_scalars(jnp.asarray(M[rows, cols]), 7)  # row by row: (0,0), (1,0), (1,1), ...
    assert all(float(packed[i][j]) == float(L[i][j]) for i in range(7) for j in range(i + 1))


def test_closed_form_2x2_solve_and_3x3_determinant_match_numpy():
    rng = np.random.default_rng(3)
    for _ in range(20):
        M2, b, M3 = rng.normal(size=(2, 2)), rng.normal(size=2), rng.normal(size=(3, 3))
        np.testing.assert_allclose(linalg.solve_2x2(jnp.asarray(M2), jnp.asarray(b)), np.linalg.solve(M2, b),
                                   rtol=1e-9, atol=1e-12)
        assert abs(float(linalg.det_3x3(jnp.asarray(M3))) - np.linalg.det(M3)) < 1e-12
    M2, b, M3 = (jnp.asarray(v) for v in (rng.normal(size=(2, 2)) + 2 * np.eye(2), rng.normal(size=2),
                                          rng.normal(size=(3, 3))))
    check_grads(linalg.solve_2x2, (M2, b), order=2, modes=("fwd", "rev"))
    check_grads(linalg.det_3x3, (M3,), order=2, modes=("fwd", "rev"))
    text = jax.jit(linalg.solve_2x2).lower(M2, b).as_text() + jax.jit(linalg.det_3x3).lower(M3).as_text()
    assert "custom_call" not in text
