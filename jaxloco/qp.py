"""A batched, differentiable QP layer over the unrolled interior-point method of
`jaxloco.qp_ipm`.

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

Fixed iterations. Every instance runs exactly `iterations` Mehrotra predictor-corrector
iterations, so no batch member's result depends on the others. The iteration is qpax's
(CVXOPT's start, s and z floored at sqrt(eps) in every step, steps of 0.99 of the way to
the boundary) and gives qpax's iterates to about 1e-12, but removes the equalities by a
null-space basis and is unrolled over the tiny fixed sizes, so under `vmap` an iteration
is a few fused loops over the batch instead of dozens of small kernels, and no LAPACK
custom call is emitted. An infeasible problem ends with a diverging or non-finite iterate.

The ok flag. `ok` is True iff everything is finite and all three scaled residuals
are <= `tol`. Infeasible problems (the iterate then diverges or breaks down),
unbounded ones, non-finite inputs and ones that simply did not converge in
`iterations` get ``ok=False``; their `x`, `y`, `z` and `objective` are zeros and
their residual fields hold the residuals of the last iterate (the largest finite
float where those are not finite), so a near miss can be told from a failure.
No output is ever NaN. Non-finite inputs are swapped for a harmless dummy problem
before the solve, with `jnp.where` on both sides, so no NaN enters the computation.

Precision: tol=1e-6 suits float64 (25 iterations reach ~1e-9 on the quadruped QP).
In float32 pass tol ~1e-4: s and z are floored at sqrt(eps) ~ 3e-4 in every
iteration, so float32 residuals stall near 2e-5.

Requirements (violations give ok=False, not a wrong answer): A must have full row
rank, and Q + G^T G must be positive definite on the null space of A, i.e. every
direction without curvature (such as a margin variable) must appear in some
inequality row; the method factorizes that matrix with Cholesky.

Gradients (``differentiable=True``): reverse mode only (`jax.grad`, `jax.vjp`; not
`jax.jvp`). `x`, `y`, `z` and `objective` are differentiable with respect to all of
Q, q, A, b, G, h by implicit differentiation of the KKT conditions at the returned
point (OptNet's formulas; the adjoint system is reduced to the null space of A like
the forward solve and refined three times on the unreduced residual, ~1e-7 accurate
against finite differences). This is the
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
shared), or write ``jax.vmap(functools.partial(solve, iterations=25, tol=1e-6))``.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco import batching, linalg, qp_ipm

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


def _residuals(Q, q, A, b, G, h, x, y, z):
    slack = h - G @ x
    primal = jnp.maximum(jnp.max(jnp.abs(A @ x - b), initial=0.0), jnp.max(-slack, initial=0.0))
    dual = jnp.max(jnp.abs(Q @ x + q + A.T @ y + G.T @ z), initial=0.0)
    comp = jnp.max(jnp.abs(z * slack), initial=0.0)
    return primal, dual, comp


def _forward(data, iterations, tol):
    """Run the interior-point method for exactly `iterations` steps; return the
    sanitized iterate, residuals and ok."""
    Q, q, A, b, G, h = data
    x, y, z, s, iters = qp_ipm.solve_ipm(Q, q, A, b, G, h, iterations=iterations)
    res = _residuals(Q, q, A, b, G, h, x, y, z)
    ok = (jnp.max(jnp.stack(res)) <= tol) & jnp.all(jnp.isfinite(s)) & jnp.all(z >= 0)
    big = jnp.finfo(x.dtype).max
    res = tuple(jnp.where(jnp.isfinite(r), r, big) for r in res)
    x, y, z = (jnp.where(ok, v, 0.0) for v in (x, y, z))
    s = jnp.where(ok, s, 1.0)  # safe slack for the adjoint solve of a bad instance
    return (x, y, z, s, *res, ok, iters)


@functools.partial(jax.custom_vjp, nondiff_argnums=(6, 7))
def _solve_diff(Q, q, A, b, G, h, iterations, tol):
    return _forward((Q, q, A, b, G, h), iterations, tol)


def _solve_diff_fwd(Q, q, A, b, G, h, iterations, tol):
    out = _forward((Q, q, A, b, G, h), iterations, tol)
    x, y, z, s, *_, ok, _ = out
    return out, (Q, A, G, x, y, z, s, ok)


def _adjoint_solve(Q, A, G, D, a, b, gz, refinements):
    """Solve the adjoint KKT system at the returned point for (dx, dy, w = Z dz):

        Q dx + A^T dy + G^T w = a,   A dx = b,   G dx - S dz = gz   (D = Z / S),

    i.e. w = D (G dx - gz). The equalities are removed with the null space of A (as in
    the forward solve); the reduced matrix Z^T (Q + G^T D G) Z is ill-conditioned at
    the solution (D spans ~1e-8..1e8), so the solve is refined `refinements` times on
    the residual of the unreduced system, in plain XLA operations (no LU call)."""
    m = b.shape[0]
    null = qp_ipm.null_space(A) if m else None
    H = Q + (G.T * D) @ G
    L = linalg.cholesky_scalars(H if not m else null.Z.T @ H @ null.Z)

    def solve(a, b, c):  # Q dx + A^T dy + G^T w = a, A dx = b, D G dx - w = c
        rhs = a + G.T @ c
        if not m:
            dx = linalg.cho_solve_scalars(L, rhs)
            return dx, jnp.zeros((0,), a.dtype), D * (G @ dx) - c
        dx0 = null.Y @ linalg.solve_upper_transposed(null.R, b)
        dx = dx0 + null.Z @ linalg.cho_solve_scalars(L, null.Z.T @ (rhs - H @ dx0))
        dy = linalg.solve_upper(null.R, null.Y.T @ (rhs - H @ dx))
        return dx, dy, D * (G @ dx) - c

    c = D * gz
    dx, dy, w = solve(a, b, c)
    for _ in range(refinements):
        r1 = a - (Q @ dx + A.T @ dy + G.T @ w)
        r2 = b - A @ dx
        r3 = c - (D * (G @ dx) - w)
        ex, ey, ew = solve(r1, r2, r3)
        dx, dy, w = dx + ex, dy + ey, w + ew
    return dx, dy, w


def _solve_diff_bwd(iterations, tol, saved, cts):
    del iterations, tol
    Q, A, G, x, y, z, s, ok = saved
    n, m = x.shape[0], y.shape[0]
    gx, gy, gz = (jnp.where(ok, g, 0.0) for g in cts[:3])
    # A bad instance gets a well-posed dummy system (and zero right-hand side).
    Qb = jnp.where(ok, Q, jnp.eye(n, dtype=Q.dtype))
    Ab = jnp.where(ok, A, jnp.eye(m, n, dtype=A.dtype))
    Gb = jnp.where(ok, G, 0.0)
    zb = jnp.where(ok, z, 1.0)
    dx, dy, w = _adjoint_solve(Qb, Ab, Gb, zb / s, -gx, -gy, -gz, refinements=3)
    grads = (
        0.5 * (jnp.outer(dx, x) + jnp.outer(x, dx)),
        dx,
        jnp.outer(dy, x) + jnp.outer(y, dx),
        -dy,
        jnp.outer(w, x) + jnp.outer(z, dx),
        -w,
    )
    return tuple(jnp.where(ok, g, 0.0) for g in grads)


_solve_diff.defvjp(_solve_diff_fwd, _solve_diff_bwd)


def _row_norms(M):
    norms = jnp.linalg.norm(M, axis=1)
    return jnp.where(norms > 0, norms, 1.0)


class _Scaling(NamedTuple):
    """What `_prepare` keeps to map the scaled problem's answer back (`_finish`)."""

    Q: jax.Array  # (n, n) the symmetrized Q (the dummy's where not finite)
    q: jax.Array  # (n,)
    d: jax.Array  # (n,) x_scale
    c: jax.Array  # () objective scale
    ra: jax.Array  # (m,) row norms of A D
    rg: jax.Array  # (p,) row norms of G D
    finite: jax.Array  # () bool: every input finite and x_scale > 0


def _prepare(Q, q, A, b, G, h, x_scale, dtype, differentiable):
    """The scaled problem (module docstring) and its `_Scaling`, one instance."""
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
    return data, _Scaling(Q, q, d, c, ra, rg, finite)


def _finish(out, sc: _Scaling, differentiable) -> QPSolution:
    """The caller's QPSolution from `_forward`'s output on the scaled problem."""
    xs, ys, zs, _, primal, dual, comp, ok, iters = out
    ok = ok & sc.finite
    big = jnp.finfo(xs.dtype).max  # residuals of the dummy stand-in would mislead
    primal, dual, comp = (jnp.where(sc.finite, r, big) for r in (primal, dual, comp))
    x = jnp.where(ok, sc.d * xs, 0.0)
    y = jnp.where(ok, sc.c * ys / sc.ra, 0.0)
    z = jnp.where(ok, sc.c * zs / sc.rg, 0.0)
    objective = jnp.where(ok, 0.5 * x @ sc.Q @ x + sc.q @ x, 0.0)
    sol = QPSolution(x, y, z, primal, dual, comp, objective, ok, iters)
    return sol if differentiable else jax.tree_util.tree_map(jax.lax.stop_gradient, sol)


def _check_iterations(iterations) -> None:
    if int(iterations) != iterations or iterations < 1:
        raise ValueError(f"iterations must be a positive int, got {iterations!r}")


def solve(Q, q, A, b, G, h, *, x_scale=None, iterations: int = 25, tol: float = 1e-6,
          differentiable: bool = True) -> QPSolution:
    """Solve one QP (see the module docstring); jit/vmap compatible, float32 or float64.

    Shapes: Q (n, n), q (n,), A (m, n), b (m,), G (p, n), h (p,), x_scale (n,) > 0.
    `iterations` (static int >= 1): interior-point iterations, always all of them.
    `tol` (static float): bound on the scaled residuals for ``ok``.
    """
    _check_iterations(iterations)
    dtype = jnp.result_type(Q, q, A, b, G, h, 0.0)
    data, sc = _prepare(Q, q, A, b, G, h, x_scale, dtype, differentiable)
    if differentiable:
        out = _solve_diff(*data, int(iterations), float(tol))
    else:
        out = _forward(data, int(iterations), float(tol))
    return _finish(out, sc, differentiable)


_BASE_NDIM = (2, 1, 2, 1, 2, 1, 1)  # Q, q, A, b, G, h, x_scale
BLOCK = 128  # members per vmapped block in solve_batch (measured best of 32-256, 2 cores)


BACKENDS = ("xla", "kernel")


def solve_batch(Q, q, A, b, G, h, *, x_scale=None, iterations: int = 25, tol: float = 1e-6,
                differentiable: bool = True, sequential: bool = False,
                block: int | None = BLOCK, backend: str = "xla") -> QPSolution:
    """`solve` over a leading batch axis: `jax.vmap` (in blocks) or, if `sequential`,
    `jax.lax.map`; or, with backend="kernel", one compiled CPU kernel.

    Each of Q, q, A, b, G, h, x_scale may carry the batch axis (shape (B, ...)) or not
    (shared by all members; at least one must carry it). Returns a batched QPSolution.
    `block`: a batch larger than this runs as a `lax.map` over vmapped blocks of `block`
    members (`jaxloco.batching.vmap_in_blocks`), which keeps an iteration's working set
    in the CPU's cache: ~1.4x the QPs/s of one vmap over thousands (see the README).
    None: one vmap. Results do not depend on it. `sequential=True` solves one instance
    at a time (blocks of one: less memory, same results). The solver emits no LAPACK call, so neither
    form can hit jaxlib 0.10's batched-LAPACK deadlock on the CPU.
    `backend`: "xla" (the above; any device) or "kernel" (`jaxloco.qp_kernel`: the same
    method and results up to rounding as one numba-compiled CPU kernel over the batch,
    split over the CPU devices when they divide it; CPU only, needs `jaxloco[kernel]`;
    `block` and `sequential` do not apply). Gradients (reverse mode) are the same
    implicit derivative for both: the kernel's answer, differentiated as `solve` does.
    """
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
    args = [jnp.asarray(v) for v in (Q, q, A, b, G, h, 1.0 if x_scale is None else x_scale)]
    axes = [0 if v.ndim == k + 1 else None for v, k in zip(args, _BASE_NDIM)]
    if x_scale is None:
        axes[6] = None
    if backend == "kernel":
        return _solve_batch_kernel(args, axes, int(iterations), float(tol), differentiable)
    fn = functools.partial(solve, iterations=iterations, tol=tol, differentiable=differentiable)

    def call(*a):
        return fn(*a[:6], x_scale=None if x_scale is None else a[6])

    return batching.vmap_in_blocks(call, block=1 if sequential else block, in_axes=axes)(*args)


# ----------------------------------------------------------------- the kernel backend
def _solve_batch_kernel(args, axes, iterations, tol, differentiable) -> QPSolution:
    """`solve_batch(..., backend="kernel")`: the batch broadcast to one dtype and shape."""
    _check_iterations(iterations)
    if jax.default_backend() != "cpu":
        raise ValueError(f"backend='kernel' runs on the CPU only (JAX's default backend is "
                         f"{jax.default_backend()!r}); use backend='xla'")
    batched = [v for v, ax in zip(args, axes) if ax == 0]
    if not batched:
        raise ValueError("solve_batch: no argument has a batch axis")
    size = batched[0].shape[0]
    dtype = jnp.result_type(*args[:6], 0.0)
    n = args[1].shape[-1]
    raw = []
    for i, (v, ax) in enumerate(zip(args, axes)):
        v = jnp.asarray(v, dtype)
        if i == 6 and v.ndim == 0:  # the default x_scale
            v = jnp.ones((n,), dtype)
        raw.append(v if ax == 0 else jnp.broadcast_to(v, (size, *v.shape)))
    raw = tuple(raw)
    if differentiable:
        return _kernel_diff(*raw, iterations, tol)
    sol = _kernel_solution(_kernel_outputs(raw, iterations, tol), iterations)
    return jax.tree_util.tree_map(jax.lax.stop_gradient, sol)


def _kernel_outputs(raw, iterations, tol):
    """The kernel's outputs for the batch `raw` (stopped gradients), split over the CPU
    devices when their number divides the batch (each runs the kernel on its part)."""
    try:
        from jaxloco import qp_kernel
    except ImportError as e:  # numba: the optional dependency jaxloco[kernel]
        raise ImportError(f"backend='kernel' needs numba: pip install 'jaxloco[kernel]' ({e})") from e

    raw = tuple(jax.lax.stop_gradient(v) for v in raw)
    fn = functools.partial(qp_kernel.solve_batch, iterations=iterations, tol=tol)
    devices = jax.devices()
    if len(devices) > 1 and raw[1].shape[0] % len(devices) == 0:
        return _split_over_devices(fn, raw, devices, n_out=10)
    return fn(*raw)


def _split_over_devices(fn, raw, devices, n_out: int):
    """fn(*raw) with the batch (the leading axis of every array of `raw`) split over
    `devices` (`jax.shard_map`, one part each). A zero-size argument (A and b when there
    are no equalities) is made inside each part instead of passed in: XLA in jaxlib 0.11
    crashes (a segmentation fault while compiling) on a shard_map that takes a zero-size
    sharded input; zero-size outputs are fine."""
    empty = [v.size == 0 for v in raw]
    passed = [v for v, e in zip(raw, empty) if not e]

    def part(*local):
        rows = local[0].shape[0]
        given = iter(local)
        return fn(*(jnp.zeros((rows, *v.shape[1:]), v.dtype) if e else next(given) for v, e in zip(raw, empty)))

    spec = jax.sharding.PartitionSpec("batch")
    mesh = jax.sharding.Mesh(np.array(devices), ("batch",))
    return jax.shard_map(part, mesh=mesh, in_specs=(spec,) * len(passed), out_specs=(spec,) * n_out,
                         check_vma=False)(*passed)


def _kernel_solution(outs, iterations) -> QPSolution:
    x, y, z, objective, res, ok = outs[:6]
    iters = jnp.full(ok.shape, iterations, jnp.int32)
    return QPSolution(x, y, z, res[..., 0], res[..., 1], res[..., 2], objective, ok, iters)


@functools.partial(jax.custom_vjp, nondiff_argnums=(7, 8))
def _kernel_diff(Q, q, A, b, G, h, d, iterations, tol):
    return _kernel_solution(_kernel_outputs((Q, q, A, b, G, h, d), iterations, tol), iterations)


def _kernel_diff_fwd(Q, q, A, b, G, h, d, iterations, tol):
    outs = _kernel_outputs((Q, q, A, b, G, h, d), iterations, tol)
    return _kernel_solution(outs, iterations), ((Q, q, A, b, G, h, d), outs[4:])


def _kernel_diff_bwd(iterations, tol, saved, ct):
    """The cotangents of `solve`'s derivative at the kernel's answer: per instance, the
    scaled problem is rebuilt (`_prepare`), the kernel's scaled iterate differentiated as
    `_solve_diff` does (`_given`), and the result mapped back (`_finish`)."""
    del tol
    (Q, q, A, b, G, h, d), (res, ok, xs, ys, zs, s) = saved

    def one(Qi, qi, Ai, bi, Gi, hi, di, resi, oki, xsi, ysi, zsi, si):
        data, sc = _prepare(Qi, qi, Ai, bi, Gi, hi, di, Qi.dtype, True)
        return _finish(_given(data, (xsi, ysi, zsi, si, resi[0], resi[1], resi[2], oki), iterations), sc, True)

    def solution(Q, q, A, b, G, h):
        return batching.vmap_in_blocks(one, block=BLOCK)(Q, q, A, b, G, h, d, res, ok, xs, ys, zs, s)

    _, vjp = jax.vjp(solution, Q, q, A, b, G, h)
    return (*vjp(ct), jnp.zeros_like(d))


_kernel_diff.defvjp(_kernel_diff_fwd, _kernel_diff_bwd)


@functools.partial(jax.custom_vjp, nondiff_argnums=(2,))
def _given(data, sol, iterations):
    """`_forward`'s output for the scaled problem `data`, already computed (`sol`: xs, ys,
    zs, s, the three residuals, ok); its derivative is `_solve_diff`'s."""
    return (*sol, jnp.asarray(iterations, jnp.int32))


def _given_fwd(data, sol, iterations):
    Qd, _, Ad, _, Gd, _ = data
    xs, ys, zs, s, *_, ok = sol
    return _given(data, sol, iterations), (Qd, Ad, Gd, xs, ys, zs, s, ok, sol)


def _given_bwd(iterations, saved, cts):
    *diff, sol = saved
    grads = _solve_diff_bwd(iterations, None, tuple(diff), cts)
    zeros = jax.tree_util.tree_map(
        lambda v: np.zeros(v.shape, jax.dtypes.float0) if v.dtype == bool else jnp.zeros_like(v), sol)
    return grads, zeros


_given.defvjp(_given_fwd, _given_bwd)
