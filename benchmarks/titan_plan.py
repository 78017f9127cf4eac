"""Throughput of the TITAN XI gait planner (jaxloco.robots.titan.gait.plan_cycles):
gait cycles planned per second, batched over maps (jit + vmap).

    python benchmarks/titan_plan.py [--batch 1,16,128] [--cycles 4] [--shape 160,100]
                                    [--dtype float64] [--repeats 2]

Each map of a batch is a Section 7 / 8.4 frame grid (0.2 or 0.3 m frames every 1.5,
2.0 or 3.0 m, random grid offset; every eighth map flat ground) on a fixed-shape grid of
0.1 m cells; the robot starts in the standard intermittent crawl pose near the map's
left edge and plans --cycles cycles along +x. The script compiles `jit(vmap(plan))`
for each batch size, then prints the compile time, the best wall time of --repeats
planning calls (block_until_ready) and gait cycles planned per second
(batch * cycles / time). Failed cycles (deadlocks) count: the planner runs all its
trials on them, the slowest case.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np


def make_maps(batch: int, shape: tuple[int, int], seed: int, dtype):
    import jax
    import jax.numpy as jnp

    from jaxloco.robots.titan import maps as titan_maps
    from jaxloco.robots.titan import params

    rng = np.random.default_rng(seed)
    sizes = rng.choice([params.FRAME_SMALL, params.FRAME_LARGE], batch)
    grids = rng.choice([params.SLOPE_GRID, params.GRID_SMALL, params.GRID_LARGE], batch)
    sizes[::8] = 0.0  # flat ground
    offs = rng.uniform(0.0, 1.0, (batch, 2)) * grids[:, None]
    slopes = np.where(grids == params.SLOPE_GRID, params.SLOPE_ANGLE, 0.0)
    gen = jax.vmap(
        lambda s, i, o, a: titan_maps.frame_grid_map(
            shape, jnp.zeros(2, dtype), jnp.asarray(params.CELL, dtype), s, i, o, a
        )
    )
    return gen(*(jnp.asarray(x, dtype) for x in (sizes, grids, offs, slopes)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batch", default="1,16,128")
    ap.add_argument("--cycles", type=int, default=4)
    ap.add_argument("--shape", default="160,100")
    ap.add_argument("--dtype", default="float64")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()

    from jaxloco import runtime

    runtime.configure(x64=args.dtype == "float64", cache_dir=False)
    import jax
    import jax.numpy as jnp

    from jaxloco.robots.titan import gait, params

    dtype = jnp.dtype(args.dtype)
    shape = tuple(int(s) for s in args.shape.split(","))
    par = params.default_params().astype(dtype)
    start_xy = jnp.array([3.0, 0.5 * shape[1] * params.CELL], dtype)

    def plan(gmap):
        start = gait.standard_start(par, gmap, start_xy, jnp.zeros((), dtype))
        p = gait.plan_cycles(par, gmap, start, args.cycles, jnp.zeros((), dtype))
        return p.min_nesm, p.n_failures, p.distance_per_cycle

    f = jax.jit(jax.vmap(plan))
    print(
        f"TITAN XI planner: {args.cycles} cycles per map, map {shape[0]}x{shape[1]} cells, {args.dtype}, "
        f"{jax.default_backend()} ({platform.processor() or platform.machine()}, {os.cpu_count()} CPUs)"
    )
    print(
        f"{'batch':>6} {'compile [s]':>12} {'plan [s]':>10} {'cycles/s':>10} {'failed':>7} {'m/cycle':>8}"
    )
    for b in (int(x) for x in args.batch.split(",")):
        maps = make_maps(b, shape, args.seed, dtype)
        t0 = time.perf_counter()
        compiled = f.lower(maps).compile()
        t_comp = time.perf_counter() - t0
        best = np.inf
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            out = jax.block_until_ready(compiled(maps))
            best = min(best, time.perf_counter() - t0)
        failed = int(np.sum(out[1]))
        dist = float(np.mean(out[2]))
        print(
            f"{b:>6} {t_comp:>12.2f} {best:>10.4f} {b * args.cycles / best:>10.1f} {failed:>7d} {dist:>8.3f}"
        )


if __name__ == "__main__":
    main()
