"""Throughput of the stability margins of jaxloco.stability (jit + vmap, and jit +
`batching.vmap_in_blocks`), the batch sharded over the CPU cores.

    python benchmarks/bench_margins.py [--batch 100000] [--contacts 4,8,16]
                                       [--dtypes float64,float32] [--repeats 5] [--block 256]

For each margin (static_margin, ne_stability_margin, longitudinal_margin,
friction_margin), each contact count N and each dtype it builds random scenes (contacts
around a ring on a rough slope, a random number of active contacts between 3 and N
under a random mask, garbage in the masked rows, a COG above the support polygon, a
random travel direction, random contact forces), compiles `jit(vmap(margin))` and
prints the compile time (lower + compile, persistent cache off unless --cache), the
best wall time of --repeats evaluations of the whole batch (block_until_ready, after
compilation) and margins evaluated per second; then, in the same run, margins/s with
`vmap_in_blocks(margin, block=--block)` (blocks keep the working set in the cache) and
the largest difference between the two (0: same members, same operations).
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

MARGINS = ("static_margin", "ne_stability_margin", "longitudinal_margin", "friction_margin")


def random_scenes(batch: int, n: int, seed: int) -> dict[str, np.ndarray]:
    """Vectorized random scenes in float64 (see the module docstring)."""
    rng = np.random.default_rng(seed)
    ang = np.sort(rng.uniform(0, 2 * np.pi, (batch, n)), axis=1)
    r = rng.uniform(0.3, 0.6, (batch, n))
    xy = np.stack([r * np.cos(ang), r * np.sin(ang)], axis=-1)
    slope = rng.uniform(-0.3, 0.3, (batch, 1, 2))
    z = np.sum(xy * slope, axis=-1) + rng.uniform(-0.05, 0.05, (batch, n))
    contacts = np.concatenate([xy, z[..., None]], axis=-1)
    n_active = rng.integers(3, n + 1, batch)
    rank = np.argsort(rng.uniform(size=(batch, n)), axis=1).argsort(axis=1)
    mask = rank < n_active[:, None]
    contacts = np.where(mask[..., None], contacts, rng.uniform(-30, 30, contacts.shape))
    w = mask / n_active[:, None]
    centre = np.einsum("bn,bnk->bk", w, contacts)
    cog = centre + np.c_[rng.uniform(-0.1, 0.1, (batch, 2)), rng.uniform(0.3, 0.6, batch)]
    phi = rng.uniform(0, 2 * np.pi, batch)
    direction = np.stack([np.cos(phi), np.sin(phi)], axis=1)
    forces = np.concatenate([rng.normal(0, 5, (batch, n, 2)), rng.uniform(5, 60, (batch, n, 1))], axis=-1)
    return dict(cog=cog, contacts=contacts, mask=mask, direction=direction, forces=forces)


def margin_fn(name: str, mu: float = 0.6):
    from jaxloco import stability as sm

    return {
        "static_margin": lambda s: sm.static_margin(s["cog"], s["contacts"], s["mask"]),
        "ne_stability_margin": lambda s: sm.ne_stability_margin(s["cog"], s["contacts"], s["mask"]),
        "longitudinal_margin": lambda s: sm.longitudinal_margin(s["cog"], s["contacts"], s["mask"], s["direction"]),
        "friction_margin": lambda s: sm.friction_margin(s["forces"], mu, s["mask"]),
    }[name]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--batch", type=int, default=100_000)
    ap.add_argument("--contacts", default="4,8,16", help="comma-separated contact counts N")
    ap.add_argument("--dtypes", default="float64,float32", help="comma-separated: float64, float32")
    ap.add_argument("--margins", default=",".join(MARGINS), help="comma-separated subset of " + ", ".join(MARGINS))
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--block", type=int, default=256, help="block of vmap_in_blocks (0: skip)")
    ap.add_argument("--cache", action="store_true", help="use the persistent compilation cache")
    args = ap.parse_args(argv)

    from jaxloco import runtime

    runtime.configure(x64=True, cache_dir=bool(args.cache))
    import jax
    import jax.numpy as jnp

    contacts = [int(v) for v in args.contacts.split(",")]
    dtypes = [v.strip() for v in args.dtypes.split(",")]
    margins = [v.strip() for v in args.margins.split(",")]
    print(
        f"jaxloco.stability margins: batch {args.batch}, best of {args.repeats}; jax {jax.__version__} on "
        f"{jax.devices()[0].platform} ({os.cpu_count()} CPUs, {platform.machine()}); "
        f"persistent cache {'on' if args.cache else 'off'}"
    )
    from jaxloco.batching import vmap_in_blocks

    mesh = jax.sharding.Mesh(np.array(jax.devices()), ("batch",))
    sharded = jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec("batch"))
    print(f"batch sharded over {len(jax.devices())} devices; blocks of {args.block}")
    print(f"{'margin':<22}{'N':>4}{'dtype':>9}{'compile s':>11}{'batch ms':>11}{'margins/s':>13}"
          f"{'in blocks/s':>13}{'max diff':>10}  check")
    for n in contacts:
        scenes64 = random_scenes(args.batch, n, args.seed)
        for dt in dtypes:
            dtype = {"float64": jnp.float64, "float32": jnp.float32}[dt]
            scenes = {
                k: jnp.asarray(v) if v.dtype == bool else jnp.asarray(v, dtype) for k, v in scenes64.items()
            }
            if args.batch % len(jax.devices()) == 0:
                scenes = jax.device_put(scenes, sharded)
            for name in margins:
                f = jax.jit(jax.vmap(margin_fn(name)))
                t0 = time.perf_counter()
                compiled = f.lower(scenes).compile()
                t_compile = time.perf_counter() - t0
                out = compiled(scenes).block_until_ready()  # warm-up
                best = np.inf
                for _ in range(args.repeats):
                    t0 = time.perf_counter()
                    compiled(scenes).block_until_ready()
                    best = min(best, time.perf_counter() - t0)
                vals = np.asarray(out)
                check = f"finite {np.mean(np.isfinite(vals)):.3f}, >0 {np.mean(vals > 0):.3f}"
                blocks, diff = "-", "-"
                if args.block:
                    fb = jax.jit(vmap_in_blocks(margin_fn(name), block=args.block)).lower(scenes).compile()
                    out_b = np.asarray(fb(scenes).block_until_ready())
                    best_b = np.inf
                    for _ in range(args.repeats):
                        t0 = time.perf_counter()
                        fb(scenes).block_until_ready()
                        best_b = min(best_b, time.perf_counter() - t0)
                    same = np.isfinite(vals) & np.isfinite(out_b)
                    blocks = f"{args.batch / best_b:.3g}"
                    diff = f"{np.max(np.abs(vals[same] - out_b[same]), initial=0.0):.1e}"
                    if not np.array_equal(np.isfinite(vals), np.isfinite(out_b)):
                        diff += "!"
                print(
                    f"{name:<22}{n:>4}{dt:>9}{t_compile:>11.2f}{best * 1e3:>11.1f}{args.batch / best:>13.3g}"
                    f"{blocks:>13}{diff:>10}  {check}",
                    flush=True,
                )


if __name__ == "__main__":
    main()
