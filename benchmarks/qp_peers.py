"""Peer QP solvers for `bench_qp.py`, each solving the same problems
(minimize 0.5 x'Qx + q'x s.t. Ax = b, Gx <= h; arrays of shape (N, ...)) and returning
(x (N, n), solved (N,) bool, seconds). Loops call the solver once per problem from
Python (as a caller would); batched solvers get the whole set in one call. The peers
are optional (`pip install -e ".[bench]"`); a missing one is skipped."""

from __future__ import annotations

import time

import numpy as np

KEYS = ("Q", "q", "A", "b", "G", "h")


def _finite_rows(G, h):
    live = np.isfinite(h)
    return G[live], h[live]


def daqp_loop(data):
    import daqp

    N, n = data["q"].shape
    m = data["b"].shape[1]
    xs, ok = np.zeros((N, n)), np.zeros(N, bool)
    probs = []
    for i in range(N):
        G, h = _finite_rows(data["G"][i], data["h"][i])
        C = np.ascontiguousarray(np.vstack([data["A"][i], G]))
        upper = np.ascontiguousarray(np.r_[data["b"][i], h])
        lower = np.r_[data["b"][i], np.full(len(h), -1e30)]
        sense = np.r_[np.full(m, 5), np.zeros(len(h))].astype(np.int32)  # 5: equality (active + immutable)
        probs.append((np.ascontiguousarray(data["Q"][i]), np.ascontiguousarray(data["q"][i]), C, upper, lower, sense))
    t0 = time.perf_counter()
    for i, (H, f, C, u, lo, s) in enumerate(probs):
        x, _, flag, _ = daqp.solve(H, f, C, u, lo, s)
        xs[i], ok[i] = x, flag in (1, 2)
    return xs, ok, time.perf_counter() - t0


def proxsuite_loop(data):
    """proxsuite's dense solver on the problem in scaled variables x = D x~ (D = x_scale,
    the scaling jaxloco.qp gets too; prepared outside the timed loop, as daqp's arrays):
    unscaled, its infeasibility test stops the contact QPs (forces of 10-500 N) after
    5 iterations as "primal infeasible"."""
    import proxsuite

    N, n = data["q"].shape
    xs, ok = np.zeros((N, n)), np.zeros(N, bool)
    scale = np.broadcast_to(data.get("x_scale", np.ones(n)), (N, n))
    probs = []
    for i in range(N):
        D = scale[i]
        probs.append((np.ascontiguousarray(D[:, None] * data["Q"][i] * D[None, :]), D * data["q"][i],
                      np.ascontiguousarray(data["A"][i] * D[None, :]), data["b"][i],
                      np.ascontiguousarray(data["G"][i] * D[None, :]), np.full(len(data["h"][i]), -1e20),
                      data["h"][i]))
    t0 = time.perf_counter()
    for i, (H, g, A, b, C, lo, up) in enumerate(probs):
        r = proxsuite.proxqp.dense.solve(H, g, A, b, C, lo, up, eps_abs=1e-9, eps_rel=0.0)
        xs[i] = scale[i] * r.x
        ok[i] = str(r.info.status).endswith("SOLVED")
    return xs, ok, time.perf_counter() - t0


def clarabel_loop(data, tight=False):
    import clarabel
    import scipy.sparse as sp

    N, n = data["q"].shape
    xs, ok = np.zeros((N, n)), np.zeros(N, bool)
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    if tight:  # reference accuracy ~1e-7 instead of the default ~1e-5
        settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = 1e-10
    t0 = time.perf_counter()
    for i in range(N):
        Q, q, A, b, G, h = (data[k][i] for k in KEYS)
        cones = [clarabel.ZeroConeT(len(b)), clarabel.NonnegativeConeT(len(h))]
        solver = clarabel.DefaultSolver(sp.csc_matrix(np.triu(Q)), q, sp.csc_matrix(np.vstack([A, G])),
                                        np.r_[b, h], cones, settings)
        r = solver.solve()
        xs[i], ok[i] = np.array(r.x), str(r.status) == "Solved"
    return xs, ok, time.perf_counter() - t0


def moreau_batch(data):
    import moreau

    N, n = data["q"].shape
    m, p = data["b"].shape[1], data["h"].shape[1]
    rows = m + p
    dense_csr = lambda r, c: (np.arange(r + 1) * c, np.tile(np.arange(c), r))
    P_off, P_col = dense_csr(n, n)
    A_off, A_col = dense_csr(rows, n)
    cones = moreau.Cones(num_zero_cones=m, num_nonneg_cones=p)
    settings = moreau.Settings(batch_size=N, device="cpu")
    solver = moreau.CompiledSolver(n=n, m=rows, P_row_offsets=P_off, P_col_indices=P_col, A_row_offsets=A_off,
                                   A_col_indices=A_col, cones=cones, settings=settings)
    P_vals = data["Q"].reshape(N, -1)
    A_vals = np.concatenate([data["A"], data["G"]], axis=1).reshape(N, -1)
    bs = np.concatenate([data["b"], data["h"]], axis=1)
    solver.setup(P_vals, A_vals)
    solver.solve(data["q"], bs)  # first call picks its configuration
    t0 = time.perf_counter()
    solver.setup(P_vals, A_vals)
    sol = solver.solve(data["q"], bs)
    t = time.perf_counter() - t0
    # SolverStatus is an IntEnum: str() of a member is its number, its name says "Solved"
    # (np.atleast_1d would turn the list of members into plain ints)
    raw = solver.info.status
    status = np.asarray([getattr(s, "name", str(s)) for s in (raw if isinstance(raw, (list, tuple)) else [raw])])
    solved = np.array(["solved" in v.lower() or "optimal" in v.lower() for v in status])
    return np.asarray(sol.x), np.broadcast_to(solved, (N,)) if solved.size == 1 else solved, t


def qpax_vmap(data, iterations=25):
    import jax
    import jax.numpy as jnp
    import qpax

    args = tuple(jnp.asarray(data[k]) for k in KEYS)

    def one(Q, q, A, b, G, h):
        x, _, _, _, conv, _ = qpax.solve_qp(Q, q, A, b, G, h, solver_tol=1e-6, max_iter=iterations)
        return x, conv

    fn = jax.jit(jax.vmap(one)).lower(*args).compile()
    jax.block_until_ready(fn(*args))
    t0 = time.perf_counter()
    x, conv = jax.block_until_ready(fn(*args))
    return np.asarray(x), np.asarray(conv) & np.all(np.isfinite(np.asarray(x)), axis=1), time.perf_counter() - t0


PEERS = {
    "daqp (C, Python loop)": daqp_loop,
    "proxsuite dense (Python loop)": proxsuite_loop,
    "clarabel (Python loop)": clarabel_loop,
    "moreau CompiledSolver (one batch, CPU)": moreau_batch,
    "qpax (jit + vmap)": qpax_vmap,
}
