"""Throughput and accuracy of jaxloco.qp (jitted, vmapped) against clarabel.

    python benchmarks/bench_qp.py [--iterations 25] [--float32] [--problems file.npz]

Without --problems it uses random quadruped-force-distribution-sized QPs (n=16 with
12 forces of O(70 N), a zero-curvature margin variable and 3 dummies; m=9; p=24 with
3 disabled rows). A --problems file holds arrays Q, q, A, b, G, h of shape (N, ...)
and optionally x_scale of shape (N, n) or (n,); batches larger than N repeat it.
Prints compile time and QPs/s at each batch size (best of --repeats, after
compilation), the max deviation from clarabel over --sample instances in scaled units
(|x - x_ref| / x_scale), the fraction ok, clarabel's QPs/s in a Python loop, and the
throughput of a reverse-mode gradient through the solve.
"""

from __future__ import annotations

import argparse
import faulthandler
import sys
import time

import numpy as np

KEYS = ("Q", "q", "A", "b", "G", "h")


def random_problems(count: int, seed: int) -> dict[str, np.ndarray]:
    """Feasible, bounded random QPs built around a known optimum (physical units)."""
    rng = np.random.default_rng(seed)
    nf, n, m, p = 12, 16, 9, 24
    scale = np.r_[np.full(nf, 70.0), 10.0, np.ones(3)]
    out = {k: [] for k in (*KEYS, "x_scale")}
    for _ in range(count):
        Q = np.zeros((n, n))
        B = rng.normal(size=(nf, nf)) / np.sqrt(nf)
        Q[:nf, :nf] = B.T @ B + 0.05 * np.eye(nf)
        Q[13:, 13:] = np.eye(3)
        A = np.zeros((m, n))
        A[:, :nf] = rng.normal(size=(m, nf))
        A[6:, 13:] = rng.normal(size=(3, 3))
        G = np.zeros((p, n))
        G[:, :nf] = rng.normal(size=(p, nf))
        G[:, 12] = rng.uniform(0.5, 1.5, p)
        off = rng.choice(p, 3, replace=False)
        G[off] = 0.0
        act = rng.choice(np.setdiff1d(np.arange(p), off), int(rng.integers(1, 6)), replace=False)
        x, y, z = rng.normal(size=n), rng.normal(size=m), np.zeros(p)
        z[act] = rng.uniform(0.2, 2.0, act.size)
        q = -(Q @ x + A.T @ y + G.T @ z)
        h = G @ x + rng.uniform(0.1, 1.0, p)
        h[act], h[off] = G[act] @ x, 1.0
        for k, v in zip(KEYS, (Q / np.outer(scale, scale), q / scale, A / scale, A @ x, G / scale, h)):
            out[k].append(v)
        out["x_scale"].append(scale)
    return {k: np.stack(v) for k, v in out.items()}


def load_problems(path: str) -> dict[str, np.ndarray]:
    with np.load(path) as f:
        data = {k: np.asarray(f[k], np.float64) for k in KEYS}
        n_prob, n = data["q"].shape
        xs = np.asarray(f["x_scale"], np.float64) if "x_scale" in f else np.ones(n)
    data["x_scale"] = np.broadcast_to(xs, (n_prob, n)).copy()
    return data


def clarabel_solve(Q, q, A, b, G, h, tight=False):
    import clarabel
    import scipy.sparse as sp

    settings = clarabel.DefaultSettings()
    settings.verbose = False
    if tight:  # reference accuracy ~1e-7 instead of the default ~1e-5
        settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = 1e-10
    cones = [clarabel.ZeroConeT(len(b)), clarabel.NonnegativeConeT(len(h))]
    solver = clarabel.DefaultSolver(sp.csc_matrix(np.triu(Q)), q, sp.csc_matrix(np.vstack([A, G])),
                                    np.r_[b, h], cones, settings)
    r = solver.solve()
    return np.array(r.x), str(r.status) == "Solved"


def take(data, count):
    idx = np.arange(count) % data["q"].shape[0]
    return {k: v[idx] for k, v in data.items()}


def best_time(fn, args, repeats):
    import jax

    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(fn(*args))
        best = min(best, time.perf_counter() - t0)
    return best


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--iterations", type=int, default=25)
    ap.add_argument("--problems", help="npz with Q, q, A, b, G, h of shape (N, ...) [and x_scale]")
    ap.add_argument("--float32", action="store_true", help="solve in float32 (default float64)")
    ap.add_argument("--tol", type=float, default=None, help="ok tolerance (default 1e-6, float32 1e-4)")
    ap.add_argument("--batches", default="1,1000,10000", help="comma-separated batch sizes")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--sample", type=int, default=300, help="instances compared with clarabel")
    ap.add_argument("--no-grad", action="store_true", help="skip the gradient throughput figure")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--sequential", action="store_true",
                    help="solve_batch(sequential=True): lax.map instead of vmap (no batched LAPACK)")
    ap.add_argument("--watchdog", type=float, default=600.0,
                    help="abort with a stack dump if one measurement takes longer (s)")
    args = ap.parse_args(argv)

    import jax
    import jax.numpy as jnp

    jax.config.update("jax_enable_x64", not args.float32)
    from jaxloco import qp

    dtype = np.float32 if args.float32 else np.float64
    tol = args.tol if args.tol is not None else (1e-4 if args.float32 else 1e-6)
    batches = [int(b) for b in args.batches.split(",")]
    data = load_problems(args.problems) if args.problems else random_problems(max(args.sample, 1000), args.seed)
    n_prob = data["q"].shape[0]
    src = args.problems or f"{n_prob} random problems (seed {args.seed})"
    n, m, p = data["q"].shape[1], data["b"].shape[1], data["h"].shape[1]
    print(f"jaxloco.qp benchmark: {src}; n={n} m={m} p={p}; {np.dtype(dtype).name}; "
          f"iterations={args.iterations} tol={tol:g}; {'lax.map' if args.sequential else 'vmap'}; "
          f"jax {jax.__version__} on {jax.devices()[0].platform}", flush=True)

    def batched(Q, q, A, b, G, h, xs):
        return qp.solve_batch(Q, q, A, b, G, h, x_scale=xs, iterations=args.iterations, tol=tol,
                              sequential=args.sequential)

    def watchdog():  # jaxlib 0.10.x batched LAPACK on CPU can deadlock; fail loudly, not silently
        faulthandler.cancel_dump_traceback_later()
        faulthandler.dump_traceback_later(args.watchdog, exit=True, file=sys.stderr)

    def as_args(d):
        return tuple(jnp.asarray(d[k], dtype) for k in (*KEYS, "x_scale"))

    sol = None
    print(f"{'batch':>7} {'compile s':>10} {'best s':>10} {'QPs/s':>12} {'ok':>7}")
    for bsz in batches:
        bargs = as_args(take(data, bsz))
        watchdog()
        t0 = time.perf_counter()
        compiled = jax.jit(batched).lower(*bargs).compile()
        t_compile = time.perf_counter() - t0
        out = jax.block_until_ready(compiled(*bargs))
        t = best_time(compiled, bargs, args.repeats)
        print(f"{bsz:>7} {t_compile:>10.2f} {t:>10.4f} {bsz / t:>12.0f} {float(jnp.mean(out.ok)):>7.4f}", flush=True)
        if sol is None or bsz >= args.sample:
            sol, sol_bsz = out, bsz

    count = min(args.sample, n_prob, sol_bsz)
    x = np.asarray(sol.x[:count], np.float64)
    ok = np.asarray(sol.ok[:count])
    faulthandler.cancel_dump_traceback_later()
    problems = [[data[k][i] for k in KEYS] for i in range(count)]
    t0 = time.perf_counter()
    for prob in problems:
        clarabel_solve(*prob)
    t_clar = time.perf_counter() - t0
    refs = [clarabel_solve(*prob, tight=True) for prob in problems]
    solved = np.array([r[1] for r in refs])
    dev = np.abs(x - np.stack([r[0] for r in refs])) / data["x_scale"][:count]
    both = ok & solved
    print(f"clarabel (default settings) on {count} instances: {count / t_clar:.0f} QPs/s (Python loop); "
          f"reference (tol 1e-10) solved {solved.mean():.4f}")
    print(f"fraction ok (jaxloco.qp) on those: {ok.mean():.4f}; ok but clarabel not solved: {int(np.sum(ok & ~solved))}")
    if both.any():
        print(f"max |x - x_clarabel| / x_scale over {int(both.sum())} ok instances: {dev[both].max():.2e} "
              f"(median {np.median(dev[both].max(axis=1)):.2e})")

    if not args.no_grad:
        bsz = min(1000, max(batches))
        gargs = as_args(take(data, bsz))

        def loss(Q, q, A, b, G, h, xs):
            s = batched(Q, q, A, b, G, h, xs)
            return jnp.sum(jnp.where(s.ok[:, None], s.x / xs, 0.0))

        watchdog()
        t0 = time.perf_counter()
        gfn = jax.jit(jax.grad(loss, argnums=tuple(range(6)))).lower(*gargs).compile()
        t_compile = time.perf_counter() - t0
        grads = jax.block_until_ready(gfn(*gargs))
        t = best_time(gfn, gargs, args.repeats)
        finite = all(bool(jnp.all(jnp.isfinite(g))) for g in grads)
        print(f"gradient (solve + VJP wrt Q,q,A,b,G,h) at batch {bsz}: compile {t_compile:.2f} s, "
              f"{bsz / t:.0f} QPs/s, all finite: {finite}")
    faulthandler.cancel_dump_traceback_later()


if __name__ == "__main__":
    main()
