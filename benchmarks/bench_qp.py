"""Throughput and accuracy of jaxloco.qp (jitted, vmapped) against clarabel and, with
--peers, beside qpax, daqp, moreau, proxsuite and clarabel on the same problems.

    python benchmarks/bench_qp.py [--iterations 25] [--float32] [--problems file.npz]
    python benchmarks/bench_qp.py --set contact --peers --batches 2000   # the peers table of the README
    python benchmarks/bench_qp.py --devices 2 ...   # each batch sharded over 2 CPU devices (cores)

Without --problems it uses random QPs: `--set random` (default) quadruped-force-
distribution-sized ones (n=16 with 12 forces of O(70 N), a zero-curvature margin
variable and 3 dummies; m=9; p=24 with 3 disabled rows), or `--set contact` contact-
force distributions of a 4-footed robot (n=13: 12 contact-frame forces and a friction
margin; m=6 Newton-Euler rows; p=25: per foot 4 pyramid rows, 0 <= F_z <= F_max, and a
floor on the margin). A --problems file holds arrays Q, q, A, b, G, h of shape (N, ...)
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


def contact_problems(count: int, seed: int) -> dict[str, np.ndarray]:
    """Random contact-force QPs (see the module docstring), physical units (N, N m)."""
    rng = np.random.default_rng(seed)
    n, m, p = 13, 6, 25
    weight = 500.0
    scale = np.r_[np.full(12, weight / 4), weight / 10]
    out = {k: [] for k in (*KEYS, "x_scale")}
    corners = np.array([[0.3, 0.2], [0.3, -0.2], [-0.3, -0.2], [-0.3, 0.2]])
    for _ in range(count):
        feet = np.c_[corners + rng.uniform(-0.05, 0.05, (4, 2)), rng.uniform(-0.05, 0.05, 4)]
        cog = np.r_[rng.uniform(-0.08, 0.08, 2), 0.4]
        mu = rng.uniform(0.5, 0.9)
        A = np.zeros((m, n))
        G = np.zeros((p, n))
        h = np.zeros(p)
        for f in range(4):
            tilt = rng.normal(0, 0.15, 2)
            nrm = np.r_[tilt, 1.0] / np.linalg.norm(np.r_[tilt, 1.0])
            tx = np.cross([0.0, 1.0, 0.0], nrm)
            tx /= np.linalg.norm(tx)
            R = np.c_[tx, np.cross(nrm, tx), nrm]  # contact frame: columns x, y, normal
            A[:3, 3 * f:3 * f + 3] = R
            r = feet[f] - cog
            A[3:, 3 * f:3 * f + 3] = np.array([[0, -r[2], r[1]], [r[2], 0, -r[0]], [-r[1], r[0], 0]]) @ R
            for k, (sx, sy) in enumerate(((1, 1), (1, -1), (-1, 1), (-1, -1))):
                G[6 * f + k, 3 * f:3 * f + 3] = np.r_[sx, sy, -mu] / np.sqrt(2)
                G[6 * f + k, 12] = 1.0  # margin s: every pyramid row holds s below its slack
            G[6 * f + 4, 3 * f + 2], G[6 * f + 5, 3 * f + 2], h[6 * f + 5] = -1.0, 1.0, weight
        G[24, 12], h[24] = -1.0, 0.05 * weight  # s >= -5 % of the weight
        wrench = np.r_[rng.normal(0, 0.05 * weight, 2), weight, rng.normal(0, 5.0, 3)]
        wq = 1.0 / weight
        Q = np.diag(np.r_[np.full(12, wq), 0.0])
        q = np.r_[np.zeros(12), -1.0]
        for k, v in zip(KEYS, (Q, q, A, wrench, G, h)):
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


def clarabel_solve(Q, q, A, b, G, h, tight=False):  # kept for callers of this module
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
    ap.add_argument("--set", choices=("random", "contact"), default="random", help="random problem set")
    ap.add_argument("--float32", action="store_true", help="solve in float32 (default float64)")
    ap.add_argument("--tol", type=float, default=None, help="ok tolerance (default 1e-6, float32 1e-4)")
    ap.add_argument("--batches", default="1,1000,10000", help="comma-separated batch sizes")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--sample", type=int, default=300, help="instances compared with clarabel")
    ap.add_argument("--no-grad", action="store_true", help="skip the gradient throughput figure")
    ap.add_argument("--peers", action="store_true",
                    help="also time qpax, daqp, moreau, proxsuite and clarabel on the largest batch's problems "
                         "(and jaxloco in float32 and with its gradient) and print one table")
    ap.add_argument("--skip", default="",
                    help="comma-separated words: peers whose name contains one are left out (e.g. qpax, "
                         "whose batched LAPACK calls can hang with --devices > 1)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--sequential", action="store_true",
                    help="solve_batch(sequential=True): lax.map instead of vmap")
    ap.add_argument("--backend", choices=("xla", "kernel"), default="xla",
                    help="jaxloco.qp's backend (kernel: one compiled CPU kernel, needs jaxloco[kernel])")
    ap.add_argument("--block", type=int, default=None,
                    help="solve_batch's block (members per vmapped block; default qp.BLOCK, 0: one vmap)")
    ap.add_argument("--devices", type=int, default=1,
                    help="JAX CPU devices to shard each batch over (as a sweep does: one per core); "
                         "batches not divisible by it run on one device")
    ap.add_argument("--watchdog", type=float, default=600.0,
                    help="abort with a stack dump if one measurement takes longer (s)")
    args = ap.parse_args(argv)

    import jax
    import jax.numpy as jnp

    from jaxloco import runtime

    # float64 or float32, the devices, and XLA's CPU flags as users' runs get them
    runtime.configure(x64=not args.float32, cache_dir=False, cpu_devices=args.devices)
    from jaxloco import qp

    block = qp.BLOCK if args.block is None else (args.block or None)
    mesh = jax.sharding.Mesh(np.array(jax.devices()), ("batch",))

    dtype = np.float32 if args.float32 else np.float64
    tol = args.tol if args.tol is not None else (1e-4 if args.float32 else 1e-6)
    batches = [int(b) for b in args.batches.split(",")]
    gen = contact_problems if args.set == "contact" else random_problems
    data = load_problems(args.problems) if args.problems else gen(max(args.sample, 1000, *batches), args.seed)
    n_prob = data["q"].shape[0]
    src = args.problems or f"{n_prob} {args.set} problems (seed {args.seed})"
    n, m, p = data["q"].shape[1], data["b"].shape[1], data["h"].shape[1]
    form = ("one compiled kernel (numba) per device" if args.backend == "kernel" else
            "lax.map" if args.sequential else f"vmap in blocks of {block}")
    print(f"jaxloco.qp benchmark: {src}; n={n} m={m} p={p}; {np.dtype(dtype).name}; "
          f"iterations={args.iterations} tol={tol:g}; "
          f"{form}; "
          f"jax {jax.__version__} on {len(jax.devices())} {jax.devices()[0].platform} device(s)", flush=True)

    def batched(Q, q, A, b, G, h, xs, tol=tol):
        return qp.solve_batch(Q, q, A, b, G, h, x_scale=xs, iterations=args.iterations, tol=tol,
                              sequential=args.sequential, block=block, backend=args.backend)

    def watchdog():  # fail loudly, not silently, should a measurement hang
        faulthandler.cancel_dump_traceback_later()
        faulthandler.dump_traceback_later(args.watchdog, exit=True, file=sys.stderr)

    def as_args(d, dt=dtype):
        arrays = tuple(jnp.asarray(d[k], dt) for k in (*KEYS, "x_scale"))
        if arrays[1].shape[0] % len(mesh.devices):
            return arrays
        return jax.device_put(arrays, jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec("batch")))

    sol = None
    rows = []  # (solver, batch, QPs/s, ok fraction, x)
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
        if bsz == max(batches):
            rows.append((f"jaxloco.qp {np.dtype(dtype).name} ({form}, one call)", bsz, bsz / t,
                         float(jnp.mean(out.ok)), np.asarray(out.x, np.float64), np.asarray(out.ok)))

    count = min(args.sample, n_prob, sol_bsz)
    x = np.asarray(sol.x[:count], np.float64)
    ok = np.asarray(sol.ok[:count])
    faulthandler.cancel_dump_traceback_later()
    sub = {k: v[:count] for k, v in data.items()}
    from qp_peers import clarabel_loop

    _, _, t_clar = clarabel_loop(sub)
    x_ref, solved, _ = clarabel_loop(sub, tight=True)
    dev = np.abs(x - x_ref) / data["x_scale"][:count]
    both = ok & solved
    print(f"clarabel (default settings) on {count} instances: {count / t_clar:.0f} QPs/s (Python loop); "
          f"reference (tol 1e-10) solved {solved.mean():.4f}")
    print(
        f"fraction ok (jaxloco.qp) on those: {ok.mean():.4f}; ok but clarabel not solved: {int(np.sum(ok & ~solved))}"
    )
    if both.any():
        print(f"max |x - x_clarabel| / x_scale over {int(both.sum())} ok instances: {dev[both].max():.2e} "
              f"(median {np.median(dev[both].max(axis=1)):.2e})")

    grad_rate = None
    if not args.no_grad:
        bsz = min(1000, max(batches)) if not args.peers else max(batches)
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
        grad_rate = (bsz, bsz / t)
        print(f"gradient (solve + VJP wrt Q,q,A,b,G,h) at batch {bsz}: compile {t_compile:.2f} s, "
              f"{bsz / t:.0f} QPs/s, all finite: {finite}")
    faulthandler.cancel_dump_traceback_later()

    if args.peers:
        bsz = max(batches)
        pdata = take(data, bsz)
        if not args.float32:  # jaxloco in float32 on the same problems, ok at tol 1e-4
            fargs = as_args(pdata, np.float32)
            f32 = jax.jit(lambda *a: batched(*a, tol=1e-4)).lower(*fargs).compile()
            out = jax.block_until_ready(f32(*fargs))
            t = best_time(f32, fargs, args.repeats)
            rows.append((f"jaxloco.qp float32, tol 1e-4 ({form}, one call)", bsz, bsz / t,
                         float(jnp.mean(out.ok)), np.asarray(out.x, np.float64), np.asarray(out.ok)))
        if grad_rate is not None:
            rows.append((f"jaxloco.qp {np.dtype(dtype).name} solve + reverse gradient", grad_rate[0], grad_rate[1],
                         float("nan"), None, None))
        from qp_peers import PEERS

        skip = [w.strip().lower() for w in args.skip.split(",") if w.strip()]
        for name, fn in PEERS.items():
            if any(w in name.lower() for w in skip):
                print(f"{name}: skipped (--skip)")
                continue
            watchdog()  # qpax's batched LAPACK calls can hang with --devices > 1 (jaxlib 0.10.2)
            try:
                xp, okp, t = fn(pdata)
            except ImportError as e:
                print(f"{name}: skipped ({e})")
                continue
            rows.append((name, bsz, bsz / t, float(np.mean(okp)), xp, okp))
        faulthandler.cancel_dump_traceback_later()
        print(f"\nside by side: {bsz} problems ({src}), accuracy against clarabel (tol 1e-10) on the first {count}")
        print("| solver | batch | QPs/s | own solved / ok flag | max abs(x - x_ref) / x_scale |")
        print("| --- | ---: | ---: | ---: | ---: |")
        for name, b, rate, frac, xs_, oks in rows:
            if xs_ is None:
                err = "-"
            else:  # on every instance the reference solved (also where the solver's own flag says no)
                good = np.all(np.isfinite(xs_[:count]), axis=1) & solved
                d = np.abs(xs_[:count] - x_ref) / data["x_scale"][:count]
                err = f"{d[good].max():.1e}" if good.any() else "-"
            print(f"| {name} | {b} | {rate:,.0f} | {'-' if np.isnan(frac) else f'{frac:.4f}'} | {err} |")


if __name__ == "__main__":
    sys.path.insert(0, __import__("os").path.dirname(__file__))
    main()
