"""TITAN XI: survey -> map -> long walk (Hodoshima et al. 2007, Secs. 8.2-8.3, Figs. 22-28).

    python benchmarks/titan_long_walk.py [--cycles 52] [--noise 0.005] [--seeds 0,1,2] [--nthread 2]

The dummy-frame field of Sec. 8.3 ("30 m x 5 m including frames of 0.2 m x 0.2 m"; ours:
0.2 m beams every 1.5 m, 30.2 x 4.7 m, `walk.LONG_FIELD`) in MuJoCo; per seed a synthetic
total-station survey of its crossings and area centres with Gaussian noise (--noise
[m] per coordinate), the grid maps made from it (`maps.map_from_survey`), the walk
planned on those maps from 5 m before the field along +x, and executed by the footstep
executor on the true beams. Prints per seed: planned cycles, failed cycles,
modifications, planned min NESM, whether the last 2 cycles are the standard gait
(|L| = L_std, |W| = W_std, no modification), and the simulation's success, distance
walked, min NESM, feet landed on a frame, touchdown error and swing clearance; then mean
and worst over the seeds.
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cycles", type=int, default=52)
    ap.add_argument("--noise", type=float, default=0.005)
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--nthread", type=int, default=2)
    args = ap.parse_args(argv)

    from jaxloco import runtime

    runtime.configure(x64=True)
    from jaxloco.robots.titan import params as P
    from jaxloco.robots.titan import scenarios as S
    from jaxloco.robots.titan import walk as W
    from jaxloco.sim.rollout import rollout

    params = P.default_params()
    seeds = [int(s) for s in args.seeds.split(",")]
    t0 = time.perf_counter()
    planned = [W.plan_long_walk(args.cycles, args.noise, seed, params=params) for seed in seeds]
    print(f"planned {len(seeds)} walks of {args.cycles} cycles on surveyed maps (noise {args.noise:g} m) "
          f"in {time.perf_counter() - t0:.1f} s")
    sc = S.make_scenario(6 * args.cycles, beam_width=float(P.FRAME_SMALL), field=W.LONG_FIELD)
    keys = planned[0][2].keys()
    p = S.params_batch([row[0] for row in planned], **{k: np.array([row[2][k] for row in planned]) for k in keys})
    t0 = time.perf_counter()
    r = rollout(sc, p, nthread=args.nthread)
    print(f"simulated {len(seeds)} walks of {6 * args.cycles * 3 + 2:.0f} s in {time.perf_counter() - t0:.1f} s")
    cols = ("seed | failed | mods | plan min NESM | standard at the end | sim | walked [m] | sim min NESM | "
            "feet on frames | touchdown err [m] | min swing clearance [m]")
    print("\n| " + cols + " |\n|" + " --- |" * (cols.count("|") + 1))
    rows = []
    for i, (seed, (_plan, gait, _s, _g)) in enumerate(zip(seeds, planned)):
        m = r.row(i)
        conv = W.converged(gait, params)
        rows.append((m["final_progress"], m["min_nesm"], m["max_touchdown_error"], m["min_swing_clearance"]))
        print(f"| {seed} | {int(gait.n_failures)} | {int(gait.n_modifications)} | {float(gait.min_nesm):.3f} | "
              f"{'yes' if conv else 'no'} | {'ok' if m['success'] else r.status[i]} | "
              f"{m['final_progress']:.1f} | {m['min_nesm']:.3f} | {'yes' if m['forbidden_landing'] else 'no'} | "
              f"{m['max_touchdown_error']:.3f} | {m['min_swing_clearance']:.3f} |")
    a = np.asarray(rows, float)
    print(f"\nmean (worst) over {len(seeds)} seeds: walked {a[:, 0].mean():.1f} ({a[:, 0].min():.1f}) m, sim min NESM "
          f"{a[:, 1].mean():.3f} ({a[:, 1].min():.3f}) m, touchdown error {a[:, 2].mean():.3f} ({a[:, 2].max():.3f}) m, "
          f"swing clearance {a[:, 3].mean():.3f} ({a[:, 3].min():.3f}) m")


if __name__ == "__main__":
    main()
