"""The leg-grope A-D cycle along x_R (the mirrored leg numbering) beside the one along y_R
(the literal numbering): the force-distribution QP over one cycle on several slopes, for
the shipped footsteps of each (`gait.CYCLE_DESIGNS`).

    python benchmarks/leggrope_forward_crawl.py

Readings (see `docs/leggrope.md`). Physical legs 0..3 are left front, right front, right
rear, left rear (`params.hips`).
  * literal: L1..L4 clockwise from the left front seen from above. The groping order
    L2, L1, L3, L4 is legs (1, 0, 2, 3), and the walk goes along +y_R (heading pi/2).
  * mirrored: L1 left front, L2 left rear, L3 right rear, L4 right front. The same order
    is legs (3, 0, 2, 1), the classical crawl along +x_R.
The table shows, per slope, the plan margin, how many 15 ms steps have no slip-free
force distribution (and in which grope and phase the first one is), and the smallest
static margin of the cycle. (`python -m jaxloco.robots.leggrope.design --numbering
mirrored --objective static` searches the mirrored footsteps again.)
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from jaxloco import runtime

runtime.configure(x64=True, cache_dir=True)

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

from jaxloco.robots.leggrope import forces, gait  # noqa: E402
from jaxloco.robots.leggrope.params import default_params  # noqa: E402

SLOPES = [(t, s) for t in (0.0, np.pi / 12, 0.3, -0.3) for s in (0.0, 0.5 * np.pi)]
PHASES = "ABCD"
PHYSICAL = ("left front", "right front", "right rear", "left rear")  # legs 0..3


def qp_table(walk: gait.WalkParams, config: gait.WalkConfig) -> list[str]:
    params = default_params()

    def one(theta, psi):
        terrain = gait.simple_slope(theta, psi)
        plan, summary, trace = forces.simulate_cycle(params, walk, terrain, config, forces.QPSettings(), record=True)
        return plan.margin, summary.min_static_margin, trace["ok"], trace["grope"], trace["phase"]

    theta, psi = (jnp.asarray([c[i] for c in SLOPES]) for i in (0, 1))
    margin, static, ok, grope, phase = (np.asarray(x) for x in jax.jit(jax.vmap(one))(theta, psi))
    lines = []
    for i, (t, s) in enumerate(SLOPES):
        bad = np.flatnonzero(~ok[i])
        k = int(grope[i, bad[0]]) if bad.size else 0
        where = "-"
        if bad.size:
            where = f"grope {k + 1} ({PHYSICAL[config.order[k]]}), phase {PHASES[int(phase[i, bad[0]])]}"
        lines.append(f"| {t:+.3f} | {np.degrees(s):3.0f} | {margin[i] * 1e3:+.1f} | {bad.size} | {where} | "
                     f"{static[i] * 1e3:.1f} |")
    return lines


def main() -> None:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args()
    for name, what in (("literal", "along +y_R"), ("mirrored", "along +x_R")):
        d = gait.gait_design(name, cycle=True)
        t0 = time.perf_counter()
        lines = qp_table(d.walk(), d.config())
        print(f"\n{name}, {what}: one cycle, QP at every 15 ms step ({time.perf_counter() - t0:.0f} s)")
        print("| theta [rad] | psi [deg] | plan margin [mm] | steps without a slip-free QP | where | "
              "min static margin [mm] |")
        print("| --- | --- | --- | --- | --- | --- |")
        print("\n".join(lines))


if __name__ == "__main__":
    main()
