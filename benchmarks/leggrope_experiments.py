"""The paper's three walking experiments in simulation (Ambe & Matsuno 2016, Figs. 11-14):
one cycle on the pi/12 slope, on an irregular pi/12 slope, and with L1's (the paper's
case) or L2's foothold collapsing during its grope. Prints the README's paper-vs-jaxloco table.

    python benchmarks/leggrope_experiments.py
"""

from __future__ import annotations

import numpy as np


def main() -> None:
    from jaxloco import runtime

    runtime.configure(x64=True, cache_dir=True)
    from jaxloco.robots.leggrope import scenarios
    from jaxloco.sim.rollout import rollout

    sc = scenarios.make_scenario(horizon_s=30.0, record_every=5)
    theta = float(np.pi / 12)
    p = scenarios.params_batch(4, theta=theta, facet_spread=np.array([0.0, 0.3, 0.0, 0.0]),
                               weak_leg=np.array([-1, -1, 0, 1]))
    r = rollout(sc, p, seeds=[0, 1, 0, 0])
    names = ("simple slope", "irregular slope (spread 0.3 rad)", "L1 foothold collapses", "L2 foothold collapses")
    print(f"{'experiment':34} {'status':12} {'gropes':>6} {'max N/R_ref outside D':>22} {'min grope N/R_ref':>18} "
          f"{'tilt change [deg]':>18} {'collapses met/survived':>23} {'min margin [mm]':>15} {'fell':>5}")
    for i, name in enumerate(names):
        m = r.row(i)
        print(f"{name:34} {m['status']:12} {m['completed_gropes']:>6} {m['max_normal_ratio']:>22.2f} "
              f"{m['grope_ratio_min']:>18.2f} {np.degrees(m['max_attitude_change']):>18.1f} "
              f"{m['collapses_met']:>11}/{m['collapses_survived']:<11} {1000 * m['min_margin']:>15.1f} "
              f"{bool(m['fell'])!s:>5}")
    # the attitude change right at the collapse (paper Fig. 13: about 2 degrees), before
    # the robot reacts: tilt 0.2 s after the first collapse against just before it
    for i in (2, 3):
        col = np.asarray(r.records["collapsed"][i])
        if col.max() == 0:
            continue
        k = np.argmax(col >= 1)
        quat = np.asarray(r.records["quat"][i])
        after = min(k + int(round(0.2 / (sc.record_every * 0.02))), len(quat) - 1)
        dot = abs(float(np.dot(quat[max(k - 1, 0)], quat[after])))
        print(f"{names[i]}: attitude change over the 0.2 s after the collapse {np.degrees(2 * np.arccos(min(dot, 1.0))):.1f} deg")


if __name__ == "__main__":
    main()
