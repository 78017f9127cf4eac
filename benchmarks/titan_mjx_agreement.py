"""TITAN XI on both simulators: `titan.walk` rows run on native MuJoCo and on MJX (the
model's MJX variant, `scenarios.mjx_variant`), metric by metric, and the
`titan.body_gain` loss on both.

    python benchmarks/titan_mjx_agreement.py [--cycles 1] [--seeds 0 1 2]
    python benchmarks/titan_mjx_agreement.py --physics   # MJX step cost: the model vs its variant

Rows: the `titan.walk` defaults (the Sec. 7 grid, 0.2 m frames every 2.0 m, surveyed map)
for each seed, the exact map, the 3.0 m grid with 0.3 m frames, and the Sec. 8.4 slope
(30 deg, 0.2 m frames every 1.5 m) up and across; `--cycles` gait cycles each (18 s of
plan per cycle). Prints per row the status on each backend and, per metric, the largest
|native - MJX| over the rows with the row where it occurs; then the body_gain loss
(the objective's default settings) at a few gains on both backends. `--physics`: MJX
physics steps alone (no controller, batch 1, the home pose on the grid field of
`titan.walk`'s default row) on the full model and on the MJX variant: contacts,
constraint rows, compile time and milliseconds per step.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

METRICS = ("sim_min_nesm", "distance", "max_touchdown_error", "min_swing_clearance", "max_cycle_error",
           "max_path_deviation", "foot_slip", "max_tilt")


def rows(seeds: list[int]) -> tuple[dict[str, np.ndarray], np.ndarray, list[str]]:
    """(swept columns, keys, labels) of the compared rows."""
    slope = math.radians(30.0)
    cases = [("grid 0.2/2.0 survey", "survey", 0.2, 2.0, 0.0, 0.0, s) for s in seeds]
    cases += [("grid 0.2/2.0 exact", "exact", 0.2, 2.0, 0.0, 0.0, 0),
              ("grid 0.3/3.0 survey", "survey", 0.3, 3.0, 0.0, 0.0, 0),
              ("slope 30 deg up", "survey", 0.2, 1.5, slope, 0.0, 0),
              ("slope 30 deg across", "survey", 0.2, 1.5, slope, 0.5 * math.pi, 0)]
    cols = {k: np.array([c[i] for c in cases]) for i, k in
            enumerate(("label", "map", "frame_size", "frame_interval", "slope", "direction"), start=0)}
    labels = [f"{c[0]} seed {c[6]}" for c in cases]
    keys = np.stack([np.array([0, c[6]], np.uint32) for c in cases])
    cols.pop("label")
    return cols, keys, labels


def physics_cost() -> None:
    """Print the MJX cost of a physics step: the full model against the MJX variant."""
    import contextlib
    import io

    import jax
    import jax.numpy as jnp
    import mujoco

    with contextlib.redirect_stdout(io.StringIO()):  # "Failed to import warp"
        from mujoco import mjx

    from jaxloco.robots.titan import scenarios, sim_analysis

    print(f"{'model':<26} {'contacts':>8} {'rows':>6} {'compile [s]':>12} {'ms/step':>8}")
    for backend, label in (("native", "full model (native's)"), ("mjx", "MJX variant")):
        m, _ = scenarios.build_model(0.2, sim_analysis.grid_field(2.0), backend)
        home = mujoco.MjData(m)
        mujoco.mj_resetDataKeyframe(m, home, 0)
        mx = mjx.put_model(m)
        d = mjx.make_data(mx).replace(qpos=jnp.asarray(home.qpos), ctrl=jnp.asarray(home.ctrl),
                                      mocap_pos=jnp.asarray(home.mocap_pos), mocap_quat=jnp.asarray(home.mocap_quat))
        d = jax.jit(mjx.forward)(mx, d)
        steps = jax.jit(lambda d, mx=mx: jax.lax.fori_loop(0, 20, lambda _, x: mjx.step(mx, x), d))
        t0 = time.perf_counter()
        d1 = jax.block_until_ready(steps(d))
        compile_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        for _ in range(10):
            d1 = steps(d1)
        jax.block_until_ready(d1)
        ms = 1e3 * (time.perf_counter() - t0) / 200
        print(f"{label:<26} {d._impl.ncon:>8} {d._impl.nefc:>6} {compile_s:>12.1f} {ms:>8.3f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cycles", type=int, default=1)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--gains", type=float, nargs="*", default=[1.0, 3.0, 10.0])
    ap.add_argument("--physics", action="store_true", help="only the MJX step cost of the model and its variant")
    args = ap.parse_args()

    from jaxloco import runtime

    runtime.configure(x64=True, cache_dir=True)
    if args.physics:
        physics_cost()
        return
    import jax.numpy as jnp

    from jaxloco.analysis import get
    from jaxloco.robots.titan import mjx_tuning
    from jaxloco.sim.rollout import rollout

    walk = get("titan.walk")
    swept, keys, labels = rows(args.seeds)
    out = {}
    for backend in ("native", "mjx"):
        fixed = {**walk.defaults(), "n_cycles": args.cycles, "nthread": 1, "backend": backend}
        t0 = time.perf_counter()
        out[backend] = walk.batch_fn(fixed)(swept, keys)
        print(f"{backend}: {len(labels)} rows of {args.cycles} cycle(s) in {time.perf_counter() - t0:.0f} s "
              "(planning and compiling included)")
    print(f"\n{'row':<34} {'native':>8} {'mjx':>8}")
    for i, label in enumerate(labels):
        print(f"{label:<34} {walk.statuses[out['native']['status'][i]][:8]:>8} "
              f"{walk.statuses[out['mjx']['status'][i]][:8]:>8}")
    print(f"\n{'metric':<22} {'max |native - mjx|':>19} {'native':>10} {'mjx':>10}  row")
    for name in ("success", *METRICS):
        a, b = np.asarray(out["native"][name], float), np.asarray(out["mjx"][name], float)
        d = np.where(np.isfinite(a) & np.isfinite(b), np.abs(a - b), np.where(np.isnan(a) & np.isnan(b), 0.0, np.inf))
        i = int(np.argmax(d))
        print(f"{name:<22} {d[i]:>19.2e} {a[i]:>10.5f} {b[i]:>10.5f}  {labels[i]}")

    settings = {p.name: p.default for p in mjx_tuning.SETTINGS}
    horizon = float(settings["horizon"])
    gains = np.asarray(args.gains, float)
    params = mjx_tuning.loss_params(settings, len(gains), body_gain=gains)
    print(f"\ntitan.body_gain loss [mm^2] (defaults, {horizon:g} s)")
    print(f"{'body_gain':>10} {'native':>10} {'mjx':>10} {'rms native [mm]':>16} {'rms mjx [mm]':>13}")
    res = {}
    for backend in ("native", "mjx"):
        res[backend] = rollout(mjx_tuning.loss_scenario(horizon, backend), params, backend=backend, nthread=1)
    for i, g in enumerate(gains):
        m = {b: mjx_tuning.cog_error({k: jnp.asarray(v[i]) for k, v in params.items()},
                                     {k: jnp.asarray(v[i]) for k, v in r.records.items()}) for b, r in res.items()}
        print(f"{g:>10.2f} {float(m['native']['loss']):>10.4f} {float(m['mjx']['loss']):>10.4f} "
              f"{1e3 * float(m['native']['rms_cog_error']):>16.3f} {1e3 * float(m['mjx']['rms_cog_error']):>13.3f}")


if __name__ == "__main__":
    main()
