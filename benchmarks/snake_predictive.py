"""T² Snake-3: predictive mode selection against the paper's fixed order on the
joint-limit experiment (Sec. V-B, Figs. 8-10), in the kinematic simulation.

    python benchmarks/snake_predictive.py [--horizon 30] [--mujoco] [--door]

From the zigzag posture (base yaw joints at +-1.1 rad), gripper tip held, fixing state
for 2 s then switching every Delta T = 1 s: the paper's order (2, 3, ..., 6), the
reverse order and `predictive.chooser` at look-ahead horizons 0.5 and 1 s. Prints the
recovery time (every base joint below 70 % of its limit), V, the largest tip errors, the
modes chosen and the compute per switch (one `mode_scores` call, jit-compiled, the
median of 20). `--mujoco`: the joint-limit runs in MuJoCo; `--door`: opening the door
(`operations`, Sec. V-D 3) with the teleoperator model switching at the stalls, fixed
order against predicted, without and with the operator's correction (about 8 minutes).
"""

from __future__ import annotations

import argparse
import time

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco import runtime

runtime.configure(x64=True, cache_dir=True)

from jaxloco.robots.snake import control, experiments, kinsim, operations, predictive, sim_control

DT = 0.02  # [s]


def run(horizon: float, order: int, prediction: predictive.Prediction | None):
    x0, target = experiments.limit_setup()
    cp = experiments.limit_params(mode_order=jnp.asarray(control.MODE_ORDERS[order]))
    config = kinsim.RolloutConfig(steps=round(horizon / DT), dt=DT, point="tip", feedback=False)
    choose = None if prediction is None else predictive.chooser(target, cp, DT, "tip", prediction)
    f = jax.jit(lambda: kinsim.rollout(x0, target, cp, config, choose=choose))
    t = time.perf_counter()
    recs = jax.block_until_ready(f())
    wall = time.perf_counter() - t
    return recs, wall


def switch_cost(prediction: predictive.Prediction) -> float:
    x0, target = experiments.limit_setup()
    cp = experiments.limit_params()
    f = jax.jit(lambda s, t: predictive.mode_scores(s, t, target, cp, DT, "tip", prediction))
    jax.block_until_ready(f(x0, jnp.asarray(2.0)))
    times = []
    for _ in range(20):
        t = time.perf_counter()
        jax.block_until_ready(f(x0, jnp.asarray(2.0)))
        times.append(time.perf_counter() - t)
    return float(np.median(times))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--horizon", type=float, default=experiments.LIMIT_HORIZON)
    ap.add_argument("--mujoco", action="store_true", help="also the MuJoCo runs (about 3 minutes)")
    ap.add_argument("--door", action="store_true", help="also the door in MuJoCo (about 8 minutes)")
    args = ap.parse_args()
    rows = [
        ("paper order 2..6", 0, None),
        ("reverse order 6..2", 1, None),
        ("predictive, 0.5 s", 0, predictive.Prediction(horizon_s=0.5)),
        ("predictive, 1 s", 0, predictive.Prediction()),
    ]
    print(
        f"Joint-limit avoidance, kinematic, {args.horizon:g} s from the zigzag posture (tip held; switching from 2 s)"
    )
    print("| selection | recovery [s] | V0 -> final V | max tip error [mm] | max att. error [rad] | compute per switch "
          "[ms] | run wall [s] | modes of the first 8 slots |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for label, order, pred in rows:
        recs, wall = run(args.horizon, order, pred)
        m = {k: float(v) for k, v in experiments.limit_metrics(recs).items()}
        sigma = np.asarray(recs["sigma"])
        t = np.asarray(recs["t"])
        slots = [int(sigma[np.argmin(np.abs(t - (experiments.SWITCH_AT + k + 0.5)))]) for k in range(8)]
        cost = "-" if pred is None else f"{1e3 * switch_cost(pred):.1f}"
        print(f"| {label} | {m['recovery_time']:.1f} | {m['V0']:.1f} -> {m['final_V']:.2f} | "
              f"{1e3 * m['max_pos_error']:.1f} | {m['max_att_error']:.3f} | {cost} | {wall:.1f} | "
              f"{' '.join(map(str, slots))} |")
    print("(wall: the whole run with compilation; compute per switch: five look-ahead rollouts, compiled)")
    if args.mujoco:
        mujoco_rows(args.horizon)
    if args.door:
        door_rows()


def mujoco_rows(horizon: float) -> None:
    """The same comparison in MuJoCo (`sim_control.run_joint_limit`, the head held as in
    Fig. 9). The batched controller computes the look-ahead every control period (under
    vmap, lax.cond evaluates both branches), so the predictive run takes about 12 times
    longer than the fixed order; on the robot it would run once per switch."""
    print(f"\nThe same in MuJoCo, {horizon:g} s (head held, the paper's Fig. 9)")
    print("| selection | recovery [s] | V0 -> final V | max head error [mm] | max att. error [rad] | wall [s] | "
          "theta_4..9 below 70 % at [s] |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for label, pred in (("paper order 2..6", None), ("predictive, 1 s", predictive.Prediction())):
        t = time.perf_counter()
        res, recs = sim_control.run_joint_limit(n=1, horizon=horizon, prediction=pred)
        wall = time.perf_counter() - t
        m = {k: float(v) for k, v in experiments.limit_metrics({k: jnp.asarray(v[0]) for k, v in recs.items()
                                                        if k != "slip"}).items()}
        order = np.asarray(experiments.release_times(recs["t"][0], recs["phi"][0]))
        print(f"| {label} ({res.status[0]}) | {m['recovery_time']:.1f} | {m['V0']:.1f} -> {m['final_V']:.2f} | "
              f"{1e3 * m['max_pos_error']:.1f} | {m['max_att_error']:.3f} | {wall:.0f} | "
              f"{' '.join(f'{x:.1f}' for x in order)} |")


def door_rows() -> None:
    """Opening the door (`operations.run_operation("door")`, 40 s) with the teleoperator
    switching modes at a base joint's limit (enter 0.97, exit 0.8, at least 1 s) and the
    operations' gains (`operations.OPERATION_GAINS`), the paper's fixed order against the
    predicted modes, operator gain 0 and 1 /s."""
    print("\nOpening the door in MuJoCo, 40 s, the operator switching at the stalls")
    print("| selection | operator gain [1/s] | door max [rad] | door at the end [rad] | max tip error [mm] | "
          "final tip error [mm] | time switching [s] | wall [s] |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    gains = np.array([0.0, 1.0])
    for label, pred in (("paper order 2..6", None), ("predictive, 1 s", predictive.Prediction())):
        t = time.perf_counter()
        res, m = operations.run_operation("door", 2, prediction=pred, operator_gain=gains, operator_enter=0.97)
        wall = time.perf_counter() - t
        switching = operations.switching_record(res).sum(-1) * (res.times[1] - res.times[0])
        for i, g in enumerate(gains):
            print(f"| {label} | {g:g} | {m['door_max'][i]:.2f} | {m['door_angle'][i]:.2f} | "
                  f"{1e3 * m['max_tip_error'][i]:.0f} | {1e3 * m['final_tip_error'][i]:.0f} | {switching[i]:.1f} | "
                  f"{wall:.0f} |")
    print("(wall: both runs of a row together, with compilation)")


if __name__ == "__main__":
    main()
