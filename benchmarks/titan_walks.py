"""TITAN XI: the gait planner's footsteps executed in MuJoCo on the paper's terrains
(Sections 7 and 8.4), one table row per walk.

    python benchmarks/titan_walks.py [--cycles 4] [--nthread 2]

Rows: the Section 7 frames (0.2 m on a 2.0 m grid, 0.3 m on 3.0 m) walking straight
(+x), changing direction (Figs. 19-20: +x, then +y from the third cycle), walking in other
directions (30, 45, 90, 180 deg), and the Section 8.4 slope (30 deg, 0.2 m frames every
1.5 m, tethers on) walking up and across it. Each walk is planned from a clear standard
start (`walk.clear_start`) with `walk.plan_walk` and executed by the quasi-static
footstep executor (`scenarios.make_scenario`, native MuJoCo, 3 s per step); walks on the
same frame width run as one batch.

Columns: planner (min NESM [m], distance per cycle [m], failed cycles, modifications)
and simulation (success, min NESM with the whole-robot COG [m], largest touchdown
error [m], smallest swing clearance to the frames [m], largest COG error at the cycle
ends [m], distance walked [m]). Prints the wall time of planning (first call compiles)
and of each simulated batch.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

ROWS = (
    # name, start xy, directions (deg; one, or one per half of the walk), frame, grid, slope
    ("sec7 0.2 m / 2.0 m, +x", (-3.0, 0.3), (0,), 0.2, 2.0, 0.0),
    ("sec7 0.3 m / 3.0 m, +x", (-3.0, 0.3), (0,), 0.3, 3.0, 0.0),
    ("sec7 0.2 m, +x then +y", (-3.0, -1.0), (0, 90), 0.2, 2.0, 0.0),
    ("sec7 0.2 m, 30 deg", (-3.0, -1.5), (30,), 0.2, 2.0, 0.0),
    ("sec7 0.2 m, 45 deg", (-3.0, -1.5), (45,), 0.2, 2.0, 0.0),
    ("sec7 0.2 m, +y (90 deg)", (0.3, -3.0), (90,), 0.2, 2.0, 0.0),
    ("sec7 0.2 m, -x (180 deg)", (3.0, 0.3), (180,), 0.2, 2.0, 0.0),
    ("sec8.4 slope 30 deg, up", (-2.0, 0.0), (0,), 0.2, 1.5, 30.0),
    ("sec8.4 slope 30 deg, across", (0.0, -2.0), (90,), 0.2, 1.5, 30.0),
)


def verdict(m, gait, status) -> str:
    if int(gait.n_failures) > 0:
        return f"held ({int(gait.n_failures)} cycles unplanned)"
    return "yes" if m["success"] else f"no ({status})"


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cycles", type=int, default=4)
    ap.add_argument("--nthread", type=int, default=2)
    ap.add_argument(
        "--body-gain",
        type=float,
        default=None,
        help="executor body_gain [1/s] (default: scenarios.PARAM_DEFAULTS)",
    )
    ap.add_argument(
        "--mass-feedforward",
        type=float,
        default=None,
        help="executor mass_feedforward (1: the body moves against the legs' mass; 0: integral only)",
    )
    ap.add_argument(
        "--nesm-tol",
        type=float,
        default=None,
        help="success allowance below S_NE^c [m] (default: scenarios.PARAM_DEFAULTS)",
    )
    args = ap.parse_args(argv)

    from jaxloco.robots.titan import scenarios, walk
    from jaxloco.sim.rollout import rollout

    n = args.cycles
    planned = []
    t0 = time.perf_counter()
    for name, xy, dirs_deg, frame, grid, slope_deg in ROWS:
        half = n // 2
        dirs = np.array(
            [
                math.radians(dirs_deg[min(c // max(half, 1), len(dirs_deg) - 1)])
                for c in range(n)
            ]
            if len(dirs_deg) > 1
            else [math.radians(dirs_deg[0])] * n
        )
        try:
            plan, gait, scalars = walk.plan_walk(
                xy, n, dirs, frame, grid, math.radians(slope_deg)
            )
        except ValueError as e:
            print(f"{name}: {e}")
            continue
        planned.append((name, frame, plan, gait, scalars))
    t_plan = time.perf_counter() - t0
    print(
        f"planned {len(planned)} walks of {n} cycles in {t_plan:.1f} s (first compiles)"
    )

    results = {}
    results_gait = {row[0]: row[3] for row in planned}
    for width in sorted({row[1] for row in planned}):
        group = [row for row in planned if row[1] == width]
        sc = scenarios.make_scenario(6 * n, beam_width=width)
        keys = group[0][4].keys()
        extra = {
            k: v
            for k, v in (
                ("body_gain", args.body_gain),
                ("mass_feedforward", args.mass_feedforward),
                ("nesm_tol", args.nesm_tol),
            )
            if v is not None
        }
        p = scenarios.params_batch(
            [row[2] for row in group],
            **{k: np.array([row[4][k] for row in group]) for k in keys},
            **extra,
        )
        t0 = time.perf_counter()
        r = rollout(sc, p, nthread=args.nthread)
        dt = time.perf_counter() - t0
        print(
            f"simulated {len(group)} walks on {width} m frames "
            f"({6 * n * 3 + 2:.0f} s each) in {dt:.1f} s"
        )
        for i, row in enumerate(group):
            results[row[0]] = (r.row(i), r.status[i])

    head = (
        "| walk | plan min NESM | plan m/cycle | failed | mods | sim success | "
        "sim min NESM | touchdown err | min swing clearance | cycle-end COG err | "
        "walked | sim min NESM in swings |"
    )
    print()
    print(head)
    print("|" + " --- |" * 12)
    for name, _, plan, gait, _ in planned:
        m, status = results[name]
        print(
            f"| {name} | {float(gait.min_nesm):.4f} | {float(gait.distance_per_cycle):.2f} | "
            f"{int(gait.n_failures)} | {int(gait.n_modifications)} | "
            f"{verdict(m, gait, status)} | {m['min_nesm']:.4f} | "
            f"{m['max_touchdown_error']:.3f} | {m['min_swing_clearance']:.3f} | "
            f"{m['max_cycle_error']:.3f} | {m['final_progress']:.2f} | {m['min_nesm_swing']:.3f} |"
        )
    print()
    for name, *_ in planned:
        m, _ = results[name]
        if not m["success"] and int(results_gait[name].n_failures) == 0:
            why = [
                k
                for k, bad in (
                    ("not completed", not m["completed"]),
                    ("fell", m["fell"]),
                    ("NESM below S_NE^c - tol", not m["nesm_ok"]),
                    ("swing collision", m["swing_collision"]),
                    ("foot on a frame", m["forbidden_landing"]),
                    (
                        f"touchdown error {m['max_touchdown_error']:.3f}",
                        m["max_touchdown_error"] >= 0.1,
                    ),
                    (
                        f"path deviation {m['max_path_deviation']:.3f}",
                        m["max_path_deviation"] >= 0.1,
                    ),
                )
                if bad
            ]
            print(f"{name}: failed: {', '.join(why) or 'see metrics'}")


if __name__ == "__main__":
    main()
