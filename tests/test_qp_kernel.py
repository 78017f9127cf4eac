"""`qp.solve_batch(..., backend="kernel")` (`jaxloco.qp_kernel`, one numba-compiled CPU
kernel) against the XLA form and clarabel: the same answers, ok flags, residuals, failure
semantics (NaN, infeasible, disabled rows, no equalities), float32 and the same gradients.

The kernel compiles once per problem size and dtype (about 25 s the first time, then from
numba's disk cache), so the tests share the force-distribution shape of tests/test_qp.py
(float64 and float32) and one small shape without equalities.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("numba")
# three numba compiles of ~30 s each with an empty cache: start this module first
pytestmark = pytest.mark.slow

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
from test_qp import KEYS, X_SCALE, args_of, clarabel_solve, make_problem  # noqa: E402

from jaxloco import qp  # noqa: E402

ITERATIONS = 25


def _batch(count, seed, dtype=np.float64):
    rng = np.random.default_rng(seed)
    probs = [make_problem(rng) for _ in range(count)]
    return probs, tuple(np.stack([args_of(p, dtype)[i] for p in probs]) for i in range(len(KEYS)))


def _solve(backend, tol=1e-6, differentiable=False):
    return jax.jit(lambda *a: qp.solve_batch(*a, x_scale=X_SCALE, iterations=ITERATIONS, tol=tol,
                                             differentiable=differentiable, backend=backend))


PROBS, ARGS = _batch(64, 0)
KERNEL, XLA = _solve("kernel"), _solve("xla")


def test_the_kernel_gives_the_xla_forms_answers_and_clarabels():
    k, r = KERNEL(*ARGS), XLA(*ARGS)
    assert np.all(np.asarray(k.ok)) and np.array_equal(np.asarray(k.ok), np.asarray(r.ok))
    for name in ("x", "y", "z", "objective", "primal_residual", "dual_residual", "complementarity"):
        a, b = np.asarray(getattr(k, name)), np.asarray(getattr(r, name))
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9 * max(1.0, np.abs(b).max()), err_msg=name)
    assert np.all(np.asarray(k.iterations) == ITERATIONS)
    for i in range(0, 64, 16):
        x_ref, _, obj_ref = clarabel_solve(*args_of(PROBS[i]))
        assert np.max(np.abs(np.asarray(k.x[i]) - x_ref) / X_SCALE) < 1e-6
        assert abs(float(k.objective[i]) - obj_ref) < 1e-6 * max(1.0, abs(obj_ref))


def test_bad_members_fail_alone_as_in_the_xla_form():
    """A NaN input, an infeasible problem and an infinite b give ok=False, zeros and the
    residual fields of the XLA form; the other members are untouched."""
    bad = [np.array(a) for a in ARGS]
    bad[1][3, 0] = np.nan  # q
    bad[5][5, :] = -1e3  # h: every row violated, infeasible
    bad[3][7, 0] = np.inf  # b
    k, r = KERNEL(*bad), XLA(*bad)
    ok = np.asarray(k.ok)
    assert not ok[[3, 5, 7]].any() and ok.sum() == 61
    np.testing.assert_array_equal(ok, np.asarray(r.ok))
    assert np.all(np.asarray(k.x)[[3, 5, 7]] == 0) and np.all(np.isfinite(np.asarray(k.x)))
    big = np.finfo(np.float64).max
    assert float(k.primal_residual[3]) == big == float(r.primal_residual[3])
    np.testing.assert_allclose(np.asarray(k.x)[ok], np.asarray(r.x)[ok], atol=1e-9)


def test_disabled_rows_shared_arguments_and_no_equalities():
    """h = +inf disables a row; an argument without the batch axis is shared; with m = 0
    the kernel removes no equalities and y is empty."""
    args = [np.array(a) for a in ARGS]
    args[5][:, 2] = np.inf
    args[0] = args[0][0]  # one Q for the whole batch
    k, r = KERNEL(*args), XLA(*args)
    np.testing.assert_array_equal(np.asarray(k.ok), np.asarray(r.ok))
    np.testing.assert_allclose(np.asarray(k.x), np.asarray(r.x), atol=1e-8)

    rng = np.random.default_rng(3)
    n, p = 4, 6
    Q = np.eye(n) + 0.1 * np.ones((n, n))
    q = rng.normal(size=(32, n))
    G = np.vstack([np.eye(n), -np.eye(n)])[:p]
    h = np.ones(p)
    A, b = np.zeros((0, n)), np.zeros(0)
    no_eq = [jax.jit(lambda q, backend=be: qp.solve_batch(Q, q, A, b, G, h, differentiable=False, backend=backend))
             for be in ("kernel", "xla")]
    k, r = no_eq[0](q), no_eq[1](q)
    assert k.y.shape == (32, 0) and np.all(np.asarray(k.ok))
    np.testing.assert_allclose(np.asarray(k.x), np.asarray(r.x), atol=1e-9)


def test_float32():
    _, args32 = _batch(64, 1, np.float32)
    k = _solve("kernel", tol=1e-4)(*args32)
    r = _solve("xla", tol=1e-4)(*args32)
    assert k.x.dtype == jnp.float32
    np.testing.assert_array_equal(np.asarray(k.ok), np.asarray(r.ok))
    assert np.mean(np.asarray(k.ok)) > 0.9
    good = np.asarray(k.ok)
    assert np.max(np.abs(np.asarray(k.x) - np.asarray(r.x))[good] / X_SCALE) < 1e-4


def test_the_gradient_is_the_xla_forms():
    """Reverse mode through the kernel: `solve`'s implicit derivative at the kernel's answer."""
    def loss(backend):
        def f(Q, q, A, b, G, h):
            s = qp.solve_batch(Q, q, A, b, G, h, x_scale=X_SCALE, iterations=ITERATIONS, backend=backend)
            return jnp.sum(s.x / X_SCALE) + 1e-3 * jnp.sum(s.objective) + 1e-2 * jnp.sum(s.y) + jnp.sum(s.z)
        return jax.jit(jax.grad(f, argnums=tuple(range(6))))

    args = tuple(a[:16] for a in ARGS)
    for name, gk, gr in zip(KEYS, loss("kernel")(*args), loss("xla")(*args)):
        gk, gr = np.asarray(gk), np.asarray(gr)
        assert np.all(np.isfinite(gk)), name
        np.testing.assert_allclose(gk, gr, rtol=1e-6, atol=1e-7 * np.abs(gr).max(), err_msg=name)


def test_a_batch_of_4096_in_one_call_and_bad_arguments():
    probs = [np.concatenate([a] * 64) for a in ARGS]  # 4,096 members
    k = KERNEL(*probs)
    assert k.x.shape == (4096, 16) and np.all(np.asarray(k.ok))
    np.testing.assert_allclose(np.asarray(k.x[-64:]), np.asarray(k.x[:64]), atol=1e-12)
    with pytest.raises(ValueError, match="backend"):
        qp.solve_batch(*ARGS, backend="fortran")
    with pytest.raises(ValueError, match="iterations"):
        qp.solve_batch(*ARGS, iterations=0, backend="kernel")
