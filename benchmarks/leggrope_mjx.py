"""The leg-grope walk on MJX beside native MuJoCo (docs/simulation.md, "Leg-grope walk"):
the same six walks on native MuJoCo (the robot's own contacts), on MuJoCo C with the MJX
variant's contacts (`make_scenario(mjx_contacts=True)`) and on MJX, each metric per row;
then, with --gradient, the `leggrope.shear_relief` objective's forward-mode derivative
beside central differences of the same MJX loss at a few gains.

    python benchmarks/leggrope_mjx.py --horizon 2           # 2 s: A' and B'
    python benchmarks/leggrope_mjx.py --horizon 6           # the first grope, 2 collapses
    python benchmarks/leggrope_mjx.py --horizon 30 --no-mjx # the cycle (MuJoCo C only)
    python benchmarks/leggrope_mjx.py --gradient --gradient-horizon 0.6 --gains 0.05 0.1 0.4

Rows: the pi/12 slope at mu = 0.45 with sound footholds (R_ref factor 0.5 and 0.4),
L2's first target weak with a regrope and without (the paper's stop), mu = 0.8 on a
0.1 rad slope, an irregular slope (facet spread 0.2 rad) with p_weak = 0.5. A cold
compile of each MJX program takes minutes on 2 busy cores.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

METRICS = ("success", "completed_gropes", "collapses_met", "fell", "off_foothold", "max_attitude_change",
           "max_abs_roll", "max_abs_pitch", "max_normal_ratio", "min_margin", "max_foothold_offset",
           "collapse_tilt", "max_load_over_probe", "cycle_time")


def rows():
    """The six walks' params (`scenarios.params_batch`)."""
    from jaxloco.robots.leggrope import scenarios

    th = float(np.pi / 12)
    return scenarios.params_batch(
        6, theta=np.array([th, th, th, th, 0.1, th]), weak_leg=np.array([-1, 1, 1, -1, -1, -1]),
        regrope=np.array([1, 1, 0, 1, 1, 1]), r_break_lo=np.array([0.35, 0.35, 0.482, 0.35, 0.35, 0.35]),
        r_break_hi=np.array([0.45, 0.45, 0.483, 0.45, 0.45, 0.45]),
        r_ref_factor=np.array([0.5, 0.5, 0.5, 0.4, 0.5, 0.5]),
        mu=np.array([0.45] * 4 + [0.8, 0.45]), facet_spread=np.array([0.0] * 5 + [0.2]),
        p_weak=np.array([0.0] * 5 + [0.5]))


def agreement(horizon: float, with_mjx: bool) -> None:
    from jaxloco.robots.leggrope import scenarios
    from jaxloco.sim.rollout import rollout

    runs = [("native", False, "native"), ("C, variant", True, "native")] + ([("MJX", True, "mjx")] if with_mjx else [])
    results = {}
    for label, variant, backend in runs:
        sc = scenarios.make_scenario(horizon_s=horizon, record_every=5, mjx_contacts=variant)
        t0 = time.perf_counter()
        results[label] = rollout(sc, rows(), backend=backend, nthread=1)
        status = ", ".join(map(str, results[label].status))
        print(f"{label}: {time.perf_counter() - t0:.1f} s (first call), status {status}")
    for name in METRICS:
        for label, r in results.items():
            print(f"{name:>20} {label:>10} " + " ".join(f"{float(v):8.4f}" for v in r.metrics[name]))
    if with_mjx:
        worst = max(np.nanmax(np.abs(np.asarray(results["MJX"].metrics[n], float)
                                     - np.asarray(results["C, variant"].metrics[n], float)), initial=0.0)
                    for n in METRICS)
        print(f"largest |MJX - MuJoCo C| on the variant, over these metrics: {worst:.1e}")


def gradient(horizon: float, gains: list[float], h: float) -> None:
    import jax
    import jax.numpy as jnp

    from jaxloco.robots.leggrope import mjx_tuning
    from jaxloco.tune import runner

    settings = {p.name: p.default for p in mjx_tuning.SETTINGS} | {"horizon": horizon}
    f = jax.jit(runner.value_and_grad(mjx_tuning.make_loss(settings), "forward", ["shear_relief"]))

    def evaluate(g):
        (loss, aux), grad = f({"shear_relief": jnp.float64(g), "twist_relief": jnp.float64(0.02)})
        return float(loss), float(grad["shear_relief"]), {k: float(v) for k, v in aux.items()}

    t0 = time.perf_counter()
    evaluate(gains[0])
    print(f"\nshear_relief gradient, {horizon} s MJX rollout: first call {time.perf_counter() - t0:.1f} s")
    print(f"{'gain':>6} {'loss':>10} {'forward':>12} {'central':>12} {'rel. diff':>10} {'eval s':>7} {'max use':>8}")
    for g in gains:
        t0 = time.perf_counter()
        loss, grad, aux = evaluate(g)
        seconds = time.perf_counter() - t0
        central = (evaluate(g + h)[0] - evaluate(g - h)[0]) / (2 * h)
        print(f"{g:>6.3f} {loss:>10.6f} {grad:>12.5e} {central:>12.5e} {abs(central - grad) / abs(grad):>10.1e} "
              f"{seconds:>7.2f} {aux['max_use']:>8.3f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--horizon", type=float, default=2.0, help="simulated seconds per walk")
    ap.add_argument("--no-mjx", action="store_true", help="MuJoCo C only (native and the variant)")
    ap.add_argument("--gradient", action="store_true", help="only the gradient check")
    ap.add_argument("--gradient-horizon", type=float, default=1.5)
    ap.add_argument("--gains", type=float, nargs="+", default=[0.05, 0.1, 0.2, 0.4, 0.8])
    ap.add_argument("--h", type=float, default=1e-5, help="finite-difference step in the gain [m/s per M g]")
    args = ap.parse_args()

    from jaxloco import runtime

    runtime.configure(x64=True, cache_dir=True)
    if args.gradient:
        gradient(args.gradient_horizon, args.gains, args.h)
    else:
        agreement(args.horizon, not args.no_mjx)


if __name__ == "__main__":
    main()
