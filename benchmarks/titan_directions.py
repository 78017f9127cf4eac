"""TITAN XI: the gait planner in every direction (Sec. 7: "we confirmed that the robot
walks in all directions without a problem"), robustness over frame layouts.

    python benchmarks/titan_directions.py [--cycles 10] [--offsets 4] [--ablate]

Per field (flat, 0.2 m frames on 2.0 m, 0.3 m on 3.0 m, the two mixed in 6 m blocks) the
24 headings 0, 15, ..., 345 deg are planned for --cycles cycles from the standard start at
the centre of a 30 x 30 m map: first with the frame grid of `titan_directions` (centre
lines at (k + 1/2) interval), then with --offsets - 1 random grid offsets (seeded). Prints
per field and layout: walks with a failed cycle, failed cycles, the smallest min NESM and
the distance per cycle (mean, smallest), and the total. --ablate repeats everything
without the directional stride (stride_exponent = 0, the same L_std in every direction).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

FIELDS = (  # label, size, interval, block (field B: 0.3 m / 3.0 m)
    ("flat", 0.0, 2.0, 0.0),
    ("0.2 m / 2.0 m", 0.2, 2.0, 0.0),
    ("0.3 m / 3.0 m", 0.3, 3.0, 0.0),
    ("mixed, 6 m blocks", 0.2, 2.0, 6.0),
)
SHAPE = (300, 300)
START = 15.0


def planner(n_cycles: int, exponent: float):
    import jax
    import jax.numpy as jnp

    from jaxloco.robots.titan import gait, maps, params

    par = params.default_params().with_(stride_exponent=exponent)

    def one(size, interval, block, offset, direction):
        gmap = maps.mixed_frame_map(SHAPE, jnp.zeros(2), jnp.asarray(params.CELL), (size, interval, offset),
                                 (params.FRAME_LARGE, params.GRID_LARGE, offset * params.GRID_LARGE / interval), block)
        start = gait.standard_start(par, gmap, jnp.array([START, START]), direction)
        p = gait.plan_cycles(par, gmap, start, n_cycles, direction)
        return p.n_failures, p.min_nesm, p.distance_per_cycle

    return jax.jit(jax.vmap(one))


def run(label: str, n_cycles: int, n_offsets: int, exponent: float, fields) -> int:
    import jax.numpy as jnp

    f = planner(n_cycles, exponent)
    heads = np.radians(np.arange(0.0, 360.0, 15.0))
    rng = np.random.default_rng(0)
    total_walks = total_bad = total_cycles = 0
    t0 = time.perf_counter()
    print(f"\n{label}: {n_cycles} cycles per walk, 24 headings")
    print("| field | layout | walks failing | failed cycles | min NESM [m] | dist/cycle mean (min) [m] "
          "| bad headings |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for name, size, interval, block in fields:
        for k in range(1 if size == 0 else n_offsets):
            off = np.full((24, 2), 0.5 * interval) if k == 0 else rng.uniform(0.0, interval, (24, 2))
            out = f(*(jnp.full(24, x) for x in (size, interval, block)), jnp.asarray(off), jnp.asarray(heads))
            fails, nesm, dist = (np.asarray(x) for x in out)
            bad = fails > 0
            total_walks += 24
            total_bad += int(bad.sum())
            total_cycles += int(fails.sum())
            print(f"| {name} | {'spec' if k == 0 else f'random {k}'} | {int(bad.sum())} | {int(fails.sum())} | "
                  f"{nesm.min():.3f} | {dist.mean():.2f} ({dist.min():.2f}) | "
                  f"{', '.join(f'{d:.0f}' for d in np.degrees(heads[bad])) or '-'} |")
    print(f"total: {total_bad} of {total_walks} walks with a failed cycle, {total_cycles} failed cycles "
          f"({time.perf_counter() - t0:.0f} s)")
    return total_bad


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cycles", type=int, default=10)
    ap.add_argument("--offsets", type=int, default=4)
    ap.add_argument("--ablate", action="store_true")
    args = ap.parse_args(argv)

    from jaxloco import runtime

    runtime.configure(x64=True)
    from jaxloco.robots.titan import params

    run("default planner", args.cycles, args.offsets, params.STRIDE_EXPONENT, FIELDS)
    if args.ablate:
        run("without the directional stride (stride_exponent = 0)", args.cycles, args.offsets, 0.0, FIELDS)


if __name__ == "__main__":
    main()
