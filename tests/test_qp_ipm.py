"""jaxloco.qp_ipm: the null space against its defining properties, the interior-point
method against clarabel, and the batched program against the properties the
QP layer relies on (one call for a batch of 4,096, no custom calls)."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from test_qp import KEYS, X_SCALE, clarabel_solve, make_problem

from jaxloco import linalg, qp, qp_ipm


def test_null_space_is_an_orthonormal_complement():
    rng = np.random.default_rng(2)
    A = rng.normal(size=(5, 9)) * 10 ** rng.uniform(-1, 1, (5, 1))
    Y, Z, R = (np.asarray(v) for v in qp_ipm.null_space(jnp.asarray(A)))
    basis = np.hstack([Y, Z])
    np.testing.assert_allclose(basis.T @ basis, np.eye(9), atol=1e-12)
    np.testing.assert_allclose(A @ Z, 0.0, atol=1e-12)
    np.testing.assert_allclose(Y @ R, A.T, atol=1e-12)
    np.testing.assert_allclose(np.tril(R, -1), 0.0)
    b = rng.normal(size=5)
    w = np.asarray(linalg.solve_upper_transposed(jnp.asarray(R), jnp.asarray(b)))
    np.testing.assert_allclose(A @ (Y @ w), b, atol=1e-10)


@pytest.fixture(scope="module")
def problems():
    rng = np.random.default_rng(7)
    probs = [make_problem(rng) for _ in range(64)]
    return probs, tuple(np.stack([p[k] for p in probs]) for k in KEYS)


def _scaled(prob):
    """The problem in units where the forces are O(1) (the layer does the same)."""
    d = X_SCALE
    return (prob["Q"] * np.outer(d, d), prob["q"] * d, prob["A"] * d, prob["b"], prob["G"] * d, prob["h"])


def test_matches_clarabel(problems):
    probs, _ = problems
    data = [np.stack(a) for a in zip(*(_scaled(p) for p in probs))]
    solve = jax.jit(jax.vmap(functools.partial(qp_ipm.solve_ipm, iterations=30)))
    out = solve(*data)
    for i, prob in enumerate(probs):
        x_ref, _, _ = clarabel_solve(*(a[i] for a in data))
        np.testing.assert_allclose(out.x[i], x_ref, atol=1e-5)  # raw rows: scaled by 10^+-1
        np.testing.assert_array_less(-1e-12, out.s[i])
    np.testing.assert_array_equal(out.iterations, 30)


def test_batch_of_4096_in_one_call_without_custom_calls(problems):
    _, stacked = problems
    big = tuple(np.concatenate([a] * 64) for a in stacked)  # 4,096 members
    fn = jax.jit(lambda *a: qp.solve_batch(*a, x_scale=X_SCALE, block=None))  # one vmap over 4,096
    assert "custom_call" not in fn.lower(*big).as_text()
    sol = fn(*big)
    assert bool(np.all(sol.ok))
    np.testing.assert_array_equal(np.asarray(sol.x[:64]), np.asarray(sol.x[-64:]))


def test_gradient_program_has_no_custom_calls(problems):
    _, stacked = problems

    def loss(*a):
        return jnp.sum(qp.solve_batch(*a, x_scale=X_SCALE).x)

    assert "custom_call" not in jax.jit(jax.grad(loss, argnums=(1, 5))).lower(*stacked).as_text()


def test_blocked_batch_equals_one_vmap_in_values_and_gradient(problems):
    """solve_batch's blocks (a lax.map over vmapped blocks, members strided over the
    blocks, the last block padded) give one vmap's results and gradient."""
    _, stacked = problems
    Q, q, A, b, G, h = (np.concatenate([a] * 5)[:300] for a in stacked)  # 300 = 2 x 128 + 44
    Q = Q[0]  # shared by every member: no batch axis

    def solve(q, h, block):
        return qp.solve_batch(Q, q, A, b, G, h, x_scale=X_SCALE, iterations=20, block=block)

    blocked = jax.jit(functools.partial(solve, block=128))(q, h)
    whole = jax.jit(functools.partial(solve, block=None))(q, h)
    assert blocked.x.shape == whole.x.shape == q.shape and bool(np.all(blocked.ok))
    for got, want in zip(blocked, whole):
        np.testing.assert_allclose(np.asarray(got), np.asarray(want), rtol=1e-12, atol=1e-13)

    def loss(q, h, block):
        return jnp.sum(solve(q, h, block).x ** 2)

    g_blocked = jax.jit(jax.grad(functools.partial(loss, block=128), argnums=(0, 1)))(q, h)
    g_whole = jax.jit(jax.grad(functools.partial(loss, block=None), argnums=(0, 1)))(q, h)
    for got, want in zip(g_blocked, g_whole):
        np.testing.assert_allclose(np.asarray(got), np.asarray(want), rtol=1e-10, atol=1e-12)
    with pytest.raises(ValueError, match="block"):
        qp.solve_batch(Q, q, A, b, G, h, block=0)
