"""What the OCTOPUS stands on: one CLM climb of a step (400 mm unless `--set height=H`) on
native MuJoCo, and at chosen times every robot geom touching the terrain, with the
contact's point, its normal's angle from the horizontal and the load.

    python benchmarks/octopus_contacts.py [--time T ...] [--set name=value ...] [--horizon S] [--push F]

Defaults: the paper's climb (`climb_paper` = 1, no CRAWL) at its default gains, times
24 30 40 60 s. `--set` changes any simulation parameter (`scenarios.PARAM_DEFAULTS`),
e.g. `--set climb_common_axis=1 --set delta_e=0.02`.

`--push F` adds a forward push (world +x, towards the step) of F times each body's
weight, as a horizontal component F g of gravity: the help a stalled climb would need
from outside (traction, an operator's tether). The controller does not see it (the IMU
gives attitude from the orientation).

Loads: wheels and rollers carry MuJoCo touch sensors (their normal load, recorded during
the run); the arm links (boom, forearm) and the chassis do not, so a link's contact is
listed with its geometry only ("link"). The geometry comes from the recorded state
(qpos and the terrain's mocap poses) put back into the model and `mj_forward`: contact
points and normals are the simulation's; the contact forces of that call are not (the
servo commands and velocities are not part of the recorded state), hence the touch
sensors. This is how docs/octopus.md found the paper's climb standing on its rear boom
links (6 Dec 2026).
"""

from __future__ import annotations

import argparse

import numpy as np

from jaxloco import runtime

runtime.configure(x64=True, cache_dir=True)

import mujoco  # noqa: E402

from jaxloco.robots.octopus import clm, operator, scenarios  # noqa: E402
from jaxloco.sim.rollout import rollout  # noqa: E402

RECORD_EVERY = 25  # control periods (0.5 s) between records


def parse_set(items: list[str]) -> dict[str, float]:
    out = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or name not in scenarios.PARAM_DEFAULTS:
            raise SystemExit(f"--set {item!r}: expected name=value with a simulation parameter name")
        out[name] = float(value)
    return out


def report(times: list[float], overrides: dict[str, float], horizon: float, push: float = 0.0) -> None:
    over = {"height": 0.4, "climb_paper": 1.0, "crawl_max_h": 0.0, **overrides}
    sc = scenarios.make_scenario("step1", operator.with_operator(clm.make_controller()), horizon_s=horizon,
                                 record_every=RECORD_EVERY)
    sc.model.opt.gravity[0] = push * -sc.model.opt.gravity[2]
    params = scenarios.params_batch(1, **over)
    res = rollout(sc, params, record_state=True)
    rec = {k: np.asarray(v)[0] for k, v in res.records.items()}
    states = {k: np.asarray(v)[0] for k, v in res.states.items()}
    m, d = sc.model, mujoco.MjData(sc.model)
    edge = float(np.asarray(params["distance"])[0])
    touch_of = {mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, b): k for k, b in enumerate(scenarios.SUPPORT_BODIES)}
    robot = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "chassis")
    settings = ", ".join(f"{k} = {v:g}" for k, v in over.items())
    print(f"{1000 * over['height']:.0f} mm step, riser at x = {edge:.2f} m; {settings}; "
          f"forward push {push:g} x weight; "
          f"status {res.status[0]}, success {bool(res.metrics['success'][0])}")
    for t in times:
        i = int(np.argmin(np.abs(states["time"] - t)))
        d.qpos[:] = states["qpos"][i]
        d.mocap_pos[:], d.mocap_quat[:] = states["mocap_pos"][i], states["mocap_quat"][i]
        mujoco.mj_forward(m, d)
        print(f"\nt = {states['time'][i]:.1f} s  {clm.PHASE_NAMES[int(rec['phase'][i])]}: pitch "
              f"{-rec['rpy'][i, 1]:.2f} rad (nose up), roll {rec['rpy'][i, 0]:+.2f} rad, COG "
              f"{rec['cog'][i, 0] - edge:+.3f} m from the riser, {rec['cog'][i, 2]:.3f} m up")
        print(f"  {'robot geom':<16} {'terrain':<16} {'point x, y, z [m]':<24} {'normal':>7} {'load [N]':>9}")
        for c in range(d.ncon):
            con = d.contact[c]
            g1, g2 = int(con.geom1), int(con.geom2)
            if m.body_rootid[m.geom_bodyid[g1]] != robot:  # robot geom first
                g1, g2 = g2, g1
            if m.body_rootid[m.geom_bodyid[g1]] != robot or m.body_rootid[m.geom_bodyid[g2]] == robot:
                continue
            body = int(m.geom_bodyid[g1])
            load = f"{rec['touch'][i, touch_of[body]]:.0f}" if body in touch_of else "link"
            angle = np.degrees(np.arcsin(min(1.0, abs(float(con.frame[2])))))
            point = ", ".join(f"{x:+.2f}" for x in con.pos)
            print(f"  {m.geom(g1).name:<16} {m.geom(g2).name:<16} {point:<24} {angle:5.0f} deg {load:>9}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--time", type=float, nargs="+", default=[24.0, 30.0, 40.0, 60.0], help="times [s]")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE", help="a simulation parameter")
    ap.add_argument("--horizon", type=float, default=None, help="simulated time [s] (default: the last time + 1)")
    ap.add_argument("--push", type=float, default=0.0, help="forward push, a fraction of the weight (default 0)")
    args = ap.parse_args()
    if not 0.0 <= args.push <= 2.0:
        ap.error(f"--push {args.push:g}: expected a fraction of the weight in [0, 2]")
    horizon = args.horizon if args.horizon is not None else max(args.time) + 1.0
    report(sorted(args.time), parse_set(args.set), horizon, args.push)


if __name__ == "__main__":
    main()
