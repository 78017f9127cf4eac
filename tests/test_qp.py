"""jaxloco.qp against clarabel: accuracy, degenerate/infeasible inputs, batching,
gradients (implicit differentiation, NaN isolation in batches) and float32.

Problems mimic the quadruped force-distribution QP: n = 16 (12 forces of O(70 N),
a margin variable with zero curvature and negative linear cost, 3 identity-curvature
dummies), m = 9 equalities, p = 24 inequalities of which a few are disabled (zero row,
h = 1). Each is built around a known optimum x* with chosen active rows and positive
multipliers, so it is feasible, bounded and strictly complementary.
"""

from __future__ import annotations

import functools

import clarabel
import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.sparse as sp
from jax.test_util import check_grads

from jaxloco import qp

KEYS = ("Q", "q", "A", "b", "G", "h")
NF, N, M, P = 12, 16, 9, 24
X_SCALE = np.r_[np.full(NF, 70.0), 10.0, np.ones(3)]


def make_problem(rng, n_active=None, n_disabled=3):
    """Random force-distribution-like QP with known solution (in physical units)."""
    Qt = np.zeros((N, N))
    B = rng.normal(size=(NF, NF)) / np.sqrt(NF)
    Qt[:NF, :NF] = B.T @ B + 0.05 * np.eye(NF)
    Qt[13:, 13:] = np.eye(3)  # dummies; column 12 (the margin) has no curvature
    At = np.zeros((M, N))
    At[:, :NF] = rng.normal(size=(M, NF))
    At[6:, 13:] = rng.normal(size=(3, 3))
    Gt = np.zeros((P, N))
    Gt[:, :NF] = rng.normal(size=(P, NF))
    Gt[:, 12] = rng.uniform(0.5, 1.5, P)  # every live row bounds the margin from above
    At *= 10 ** rng.uniform(-1, 1, (M, 1))  # badly scaled rows: the layer normalizes them
    Gt *= 10 ** rng.uniform(-1, 1, (P, 1))
    off = rng.choice(P, n_disabled, replace=False)
    Gt[off] = 0.0
    live = np.setdiff1d(np.arange(P), off)
    k = int(rng.integers(1, 6)) if n_active is None else n_active
    act = rng.choice(live, k, replace=False)
    xs, y, z = rng.normal(size=N), rng.normal(size=M), np.zeros(P)
    z[act] = rng.uniform(0.2, 2.0, k)
    qt = -(Qt @ xs + At.T @ y + Gt.T @ z)  # stationarity at x*: margin cost is negative
    ht = Gt @ xs + rng.uniform(0.1, 1.0, P)
    ht[act] = Gt[act] @ xs
    ht[off] = 1.0
    d = X_SCALE
    return {
        "Q": Qt / np.outer(d, d), "q": qt / d, "A": At / d, "b": At @ xs,
        "G": Gt / d, "h": ht, "x": xs * d,
    }


def clarabel_solve(Q, q, A, b, G, h):
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = 1e-10
    cones = [clarabel.ZeroConeT(len(b)), clarabel.NonnegativeConeT(len(h))]
    solver = clarabel.DefaultSolver(sp.csc_matrix(np.triu(Q)), np.asarray(q), sp.csc_matrix(np.vstack([A, G])),
                                    np.r_[b, h], cones, settings)
    r = solver.solve()
    assert str(r.status) == "Solved"
    return np.array(r.x), np.array(r.z), r.obj_val


def args_of(prob, dtype=np.float64):
    return tuple(np.asarray(prob[k], dtype) for k in KEYS)


# One compiled program per shape/dtype, shared by the tests (compile time dominates).
solve_batch64 = jax.jit(lambda *a: qp.solve_batch(*a, x_scale=X_SCALE))
solve_one = jax.jit(functools.partial(qp.solve, x_scale=X_SCALE))
solve_one32 = jax.jit(functools.partial(qp.solve, x_scale=X_SCALE.astype(np.float32), tol=1e-4))


def _loss_one(Q, q, A, b, G, h, w):
    s = qp.solve(Q, q, A, b, G, h, x_scale=X_SCALE)
    return s.x @ w + s.objective


grad_one = jax.jit(jax.grad(_loss_one, argnums=tuple(range(6))))


@pytest.fixture(scope="module")
def random_set():
    rng = np.random.default_rng(20240611)
    probs = [make_problem(rng) for _ in range(240)]
    stacked = tuple(np.stack([p[k] for p in probs]) for k in KEYS)
    return probs, stacked, solve_batch64(*stacked)


def test_matches_clarabel_on_random_problems(random_set):
    probs, _, sol = random_set
    assert bool(jnp.all(sol.ok))
    assert int(sol.iterations[0]) == 25 and bool(jnp.all(sol.iterations == 25))
    for i, prob in enumerate(probs):
        x_ref, yz_ref, obj_ref = clarabel_solve(*args_of(prob))
        # scaled units: |x - x_ref| / x_scale; clarabel itself is accurate to ~1e-6 here
        assert np.max(np.abs(sol.x[i] - x_ref) / X_SCALE) < 1e-5
        assert np.max(np.abs(sol.x[i] - prob["x"]) / X_SCALE) < 1e-8  # known optimum
        assert abs(float(sol.objective[i]) - obj_ref) < 1e-6 * max(1.0, abs(obj_ref))
        yz = np.r_[sol.y[i], sol.z[i]]
        assert np.max(np.abs(yz - yz_ref)) < 1e-5 * max(1.0, np.max(np.abs(yz_ref)))
    assert float(jnp.max(sol.primal_residual)) < 1e-8
    assert float(jnp.max(sol.dual_residual)) < 1e-6 and float(jnp.max(sol.complementarity)) < 1e-6
    assert bool(jnp.all(sol.z >= 0))


def test_vmap_equals_loop(random_set):
    probs, _, sol = random_set
    for i in range(0, 240, 40):
        one = solve_one(*args_of(probs[i]))
        for field in ("x", "y", "z", "objective"):
            np.testing.assert_allclose(getattr(one, field), getattr(sol, field)[i], rtol=1e-9, atol=1e-10)
        assert bool(one.ok) == bool(sol.ok[i])


def test_sequential_and_shared_arrays_match_vmap(random_set):
    _, stacked, _ = random_set
    Q, q, A, b, G, h = (v[:4] for v in stacked)
    Q = Q[0]  # shared by all members (no batch axis)
    run = jax.jit(qp.solve_batch, static_argnames=("sequential",))
    a = run(Q, q, A, b, G, h, x_scale=X_SCALE)
    c = run(Q, q, A, b, G, h, x_scale=X_SCALE, sequential=True)
    assert bool(jnp.all(a.ok)) and bool(jnp.all(c.ok))
    for field in ("x", "y", "z", "objective"):
        np.testing.assert_allclose(getattr(a, field), getattr(c, field), rtol=1e-9, atol=1e-10)


def degenerate_problem():
    """Duplicated/scaled copies of active rows, an equality written as two opposite
    inequalities (no interior, non-unique multipliers) and the LP margin direction."""
    prob = make_problem(np.random.default_rng(5), n_active=4, n_disabled=0)
    Q, q, A, b, G, h = (np.array(prob[k]) for k in KEYS)
    act = np.flatnonzero(np.abs(G @ prob["x"] - h) < 1e-9)
    free = np.setdiff1d(np.arange(P), act)
    G[free[0]], h[free[0]] = G[act[0]], h[act[0]]
    G[free[1]], h[free[1]] = 3 * G[act[1]], 3 * h[act[1]]
    G[free[2]], h[free[2]] = A[0], b[0]
    G[free[3]], h[free[3]] = -A[0], -b[0]
    return (Q, q, A, b, G, h), prob["x"]


def test_degenerate_problem_matches_clarabel():
    args, x_star = degenerate_problem()
    sol = solve_one(*args)
    x_ref, _, obj_ref = clarabel_solve(*args)
    assert bool(sol.ok)
    assert np.max(np.abs(sol.x - x_ref) / X_SCALE) < 1e-5
    assert np.max(np.abs(sol.x - x_star) / X_SCALE) < 1e-8
    assert abs(float(sol.objective) - obj_ref) < 1e-6 * max(1.0, abs(obj_ref))
    # multipliers are not unique but must still certify optimality (small dual residual)
    assert float(sol.dual_residual) < 1e-6 and bool(jnp.all(sol.z >= 0))
    grads = grad_one(*args, np.ones(N))
    assert all(bool(jnp.all(jnp.isfinite(g))) for g in grads)


def bad_problems():
    """Name -> problem that must come back ok=False with finite (zeroed) outputs."""
    base = args_of(make_problem(np.random.default_rng(3)))
    out = {}
    Q, q, A, b, G, h = (v.copy() for v in base)
    G[:2] = 0.0  # f0 <= -10 and -f0 <= -10: infeasible inequalities
    G[0, 0], G[1, 0], h[:2] = 1.0, -1.0, -10.0
    out["infeasible inequalities"] = (Q, q, A, b, G, h)
    Q, q, A, b, G, h = (v.copy() for v in base)
    A[1], b[1] = A[0], b[0] + 1.0
    out["infeasible equalities"] = (Q, q, A, b, G, h)
    Q, q, A, b, G, h = (v.copy() for v in base)
    G[:, 12] = 0.0  # nothing bounds the margin: unbounded LP direction
    out["unbounded"] = (Q, q, A, b, G, h)
    Q, q, A, b, G, h = (v.copy() for v in base)
    Q[0, 0] = np.nan
    out["nan input"] = (Q, q, A, b, G, h)
    Q, q, A, b, G, h = (v.copy() for v in base)
    b[2] = np.inf
    out["inf input"] = (Q, q, A, b, G, h)
    return base, out


def test_infeasible_unbounded_and_nan_are_flagged():
    base, bad = bad_problems()
    assert bool(solve_one(*base).ok)
    for name, args in bad.items():
        sol = solve_one(*args)
        assert not bool(sol.ok), name
        for field, value in sol._asdict().items():
            assert bool(jnp.all(jnp.isfinite(value))), (name, field)
        for field in ("x", "y", "z", "objective"):
            assert bool(jnp.all(getattr(sol, field) == 0)), (name, field)


def test_disabled_rows_zero_or_inf_are_equivalent():
    prob = make_problem(np.random.default_rng(11))
    Q, q, A, b, G, h = args_of(prob)
    off = np.flatnonzero(np.all(G == 0, axis=1))
    h_inf = h.copy()
    h_inf[off] = np.inf
    G_junk = G.copy()
    G_junk[off] = 123.0  # ignored: h = +inf disables the row
    a, c = solve_one(Q, q, A, b, G, h), solve_one(Q, q, A, b, G_junk, h_inf)
    assert bool(a.ok) and bool(c.ok)
    np.testing.assert_allclose(a.x, c.x, rtol=1e-9, atol=1e-9)
    assert bool(jnp.all(c.z[off] < 1e-6))


def small_qp():
    """n=4, m=1, p=6 with two active rows (z = 0.7, 1.3): strictly complementary."""
    rng = np.random.default_rng(1)
    n, m, p = 4, 1, 6
    R = rng.normal(size=(n, n))
    Q = R @ R.T + np.eye(n)
    A, G = rng.normal(size=(m, n)), rng.normal(size=(p, n))
    xs, y, z = rng.normal(size=n), rng.normal(size=m), np.r_[0.7, 1.3, np.zeros(p - 2)]
    q = -(Q @ xs + A.T @ y + G.T @ z)
    h = G @ xs + np.r_[0.0, 0.0, rng.uniform(0.3, 1.0, p - 2)]
    return tuple(map(jnp.asarray, (Q, q, A, A @ xs, G, h))), xs


def test_gradients_match_finite_differences():
    args, xs = small_qp()

    def f(*a):
        s = qp.solve(*a)
        return jnp.concatenate([s.x, s.y, s.z, s.objective[None]])

    f = jax.jit(f)  # (eager execution of the solver is much slower than compiling it)
    np.testing.assert_allclose(f(*args)[:4], xs, atol=1e-9)
    check_grads(f, args, order=1, modes=["rev"])


def test_non_differentiable_mode():
    args, xs = small_qp()

    @jax.jit
    def value_and_grad(q):
        return jax.value_and_grad(lambda q: qp.solve(*args[:1], q, *args[2:], differentiable=False).x.sum())(q)

    value, g = value_and_grad(args[1])
    np.testing.assert_allclose(value, xs.sum(), atol=1e-9)
    assert bool(jnp.all(g == 0))


def test_bad_batch_member_does_not_poison_gradients():
    rng = np.random.default_rng(7)
    good = [args_of(make_problem(rng)) for _ in range(3)]
    _, bad = bad_problems()
    members = [good[0], bad["infeasible inequalities"], good[1], bad["nan input"], good[2]]
    batch = tuple(np.stack(v) for v in zip(*members))
    w = jnp.asarray(rng.normal(size=N))

    def loss(*a):
        s = qp.solve_batch(*a, x_scale=X_SCALE)
        return jnp.sum(jnp.where(s.ok[:, None], s.x, 0.0) @ w) + jnp.sum(jnp.where(s.ok, s.objective, 0.0))

    grads = jax.jit(jax.grad(loss, argnums=tuple(range(6))))(*batch)
    for g in grads:
        assert bool(jnp.all(jnp.isfinite(g)))
    for i, k in ((0, 0), (2, 1), (4, 2)):
        for g_batch, g_ref in zip(grads, grad_one(*good[k], w)):
            np.testing.assert_allclose(g_batch[i], g_ref, rtol=1e-8, atol=1e-12)
    for i in (1, 3):
        for g in grads:
            assert bool(jnp.all(g[i] == 0))


def test_float32_agrees_with_float64():
    prob = make_problem(np.random.default_rng(2))
    s64 = solve_one(*args_of(prob))
    s32 = solve_one32(*args_of(prob, np.float32))
    assert s32.x.dtype == jnp.float32 and s32.objective.dtype == jnp.float32
    assert bool(s64.ok) and bool(s32.ok)
    dev = np.abs(np.asarray(s32.x, np.float64) - s64.x) / X_SCALE
    assert np.max(dev) < 1e-3 * max(1.0, np.max(np.abs(s64.x) / X_SCALE))
    assert abs(float(s32.objective) - float(s64.objective)) < 1e-3 * max(1.0, abs(float(s64.objective)))
