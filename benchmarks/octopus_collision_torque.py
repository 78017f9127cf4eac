"""How large the arm joint torques get in free motion, per arm transfer phase of the CLM
(`clm.ARM_PHASE_NAMES`): the evidence for the collision thresholds `collision_torque`
(LIFT, SWING, OVER; in LOWER a contact) and `collision_threshold` (LOWER) in
`jaxloco.robots.octopus.clm.PARAM_DEFAULTS`. The collision stop is switched off for the
run (collision_torque = 1e6), so that an arm meeting the block shows its torque.

    python benchmarks/octopus_collision_torque.py [flat|block] [seconds]

Prints, per phase, the number of arm-periods, the largest |boom or elbow torque| [N m],
the max, 99th and 99.9th percentile of the per-period rise max over the arm's three
joints of |tau| - |tau'| [N m] (the `clm_rules.collision` signal of LOWER), and in how
many arm-periods the CLM's collision rule of LIFT/SWING/OVER would fire (torque above
collision_torque, in LIFT with the joint still, collision_periods in a row): on flat ground every
one would be a false stop. On flat ground every rise in LIFT/SWING/OVER is free motion; on "block" (a
500 mm block beside the right side) the arms meet the block.
"""

from __future__ import annotations

import sys

import numpy as np

from jaxloco import runtime

runtime.configure(x64=True, cache_dir=True)

from jaxloco.robots.octopus import clm, clm_rules, scenarios
from jaxloco.sim.rollout import rollout

TOUCH_FREE = 20.0  # [N] a roller below this touches nothing


def main(argv: list[str]) -> None:
    kind = argv[1] if len(argv) > 1 else "flat"
    seconds = float(argv[2]) if len(argv) > 2 else 40.0
    sc = scenarios.make_scenario(kind, clm.make_controller(), horizon_s=seconds, record_every=1)
    base = sc.record

    def record(p, data, obs, c, e):
        r = base(p, data, obs, c, e)
        r.update(arm_phase=c.arms.arm_phase, tau=obs["arm_tau"], q=obs["arm_q"])
        return r

    params = scenarios.params_batch(1, collision_torque=1e6, **({"height": 0.5} if kind == "block" else {}))
    r = rollout(sc.with_(record=record), params, nthread=0)
    tau = np.abs(np.asarray(r.records["tau"])[0].reshape(-1, 4, 3))
    phase = np.asarray(r.records["arm_phase"])[0][1:]
    rise = np.max(tau[1:] - tau[:-1], axis=-1)
    q = np.asarray(r.records["q"])[0].reshape(-1, 4, 3)
    d = clm.PARAM_DEFAULTS
    # the CLM's collision rule: |boom or elbow torque| > collision_torque (in LIFT while that
    # joint moved less than collision_still), collision_periods periods in a row
    still = (np.abs(q[1:, :, 1:] - q[:-1, :, 1:]) < d["collision_still"]) | (phase != clm_rules.LIFT)[..., None]
    held = np.any((tau[1:, :, 1:] > d["collision_torque"]) & still, axis=-1)
    run = np.zeros_like(held, dtype=int)
    for k in range(held.shape[0]):
        run[k] = np.where(held[k], (run[k - 1] if k else 0) + 1, 0)
    fires = run >= d["collision_periods"]
    print(f"OCTOPUS CLM on {kind}, {seconds:g} s, collision stop off: |boom, elbow torque| and its per-period "
          "rise [N m]")
    for k, name in enumerate(clm.ARM_PHASE_NAMES):
        sel = phase == k
        if sel.any():
            v = rise[sel]
            peak = tau[1:, :, 1:].max(axis=-1)[sel].max()
            print(f"  {name:7s} {int(sel.sum()):6d} arm-periods  max |tau| {peak:6.1f}  rise: max {v.max():6.1f}"
                  f"  p99 {np.percentile(v, 99):6.1f}  p99.9 {np.percentile(v, 99.9):6.1f}"
                  f"  collision rule fires: {int(fires[sel].sum())}")
    # LOWER ends on contact (the torque rule among its signals): how large the torque gets
    # before the arm's roller touches anything (its touch sensor below TOUCH_FREE)
    roller = np.asarray(r.records["touch"])[0][1:, scenarios.ROLLERS]  # [N]
    free = (phase == clm_rules.LOWER) & (roller < TOUCH_FREE)
    if free.any():
        print(f"  lower before the roller touches ({int(free.sum())} arm-periods): max |tau| "
              f"{tau[1:, :, 1:].max(axis=-1)[free].max():6.1f}")


if __name__ == "__main__":
    main(sys.argv)
