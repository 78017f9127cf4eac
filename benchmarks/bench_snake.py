"""T² Snake-3 throughput: the control law (Eq. 12, with its constraint matrices) batched,
the kinematic closed loop, gradient tuning steps and the MuJoCo closed loop.

    python benchmarks/bench_snake.py [--batch 1,64,1024]

Prints, per batch size: controller evaluations per second (jit(vmap(control_input)) at
random postures and modes), kinematic closed-loop control periods per second (the
joint-limit experiment, 200 periods), and once: tuning steps per second
(value_and_grad of the `snake.kv` loss, 20 s at dt 0.05 s = 401 periods, as
jaxloco/specs/snake_kv_tune.toml) and the MuJoCo closed loop (physics steps per second at
batch 1 and 6, 10 physics steps per control period). Compile times are printed apart.
"""

from __future__ import annotations

import argparse
import time

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco import runtime


def timed(fn, *args, repeat: int = 3):
    """(first call incl. compile [s], best of `repeat` later calls [s])."""
    t = time.perf_counter()
    jax.block_until_ready(fn(*args))
    first = time.perf_counter() - t
    best = float("inf")
    for _ in range(repeat):
        t = time.perf_counter()
        jax.block_until_ready(fn(*args))
        best = min(best, time.perf_counter() - t)
    return first, best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batch", default="1,64,1024")
    ap.add_argument("--no-mujoco", action="store_true")
    args = ap.parse_args()
    runtime.configure(x64=True)
    from jaxloco.robots.snake import control, experiments, kinsim, tuning
    from jaxloco.robots.snake import params as snake_params

    print(f"jax {jax.__version__}, devices {jax.devices()}, float64")
    rng = np.random.default_rng(0)
    cp = experiments.limit_params()
    law = jax.jit(jax.vmap(lambda b, phi, g: control.control_input(
        kinsim.point_pose(kinsim.initial_state(phi, b)), phi, jnp.zeros(7), jnp.zeros(7), g, cp)))
    x0, target = experiments.limit_setup()
    config = kinsim.RolloutConfig(steps=200, dt=0.02)
    loop = jax.jit(jax.vmap(lambda k: kinsim.rollout(x0, target, cp.with_(k_eta=k), config)["V"][-1]))
    print("| batch | control law [evals/s] | compile [s] | kinematic closed loop [periods/s] | compile [s] |")
    print("| --- | --- | --- | --- | --- |")
    for n in [int(b) for b in args.batch.split(",")]:
        phi = np.tile(snake_params.INITIAL_PHI, (n, 1)) + rng.uniform(-0.3, 0.3, (n, snake_params.N_PHI))
        base = rng.uniform(-1, 1, (n, 3))
        modes = np.asarray(snake_params.MODES)[rng.integers(0, snake_params.N_MODES, n)]
        c1, b1 = timed(law, jnp.asarray(base), jnp.asarray(phi), jnp.asarray(modes))
        c2, b2 = timed(loop, jnp.linspace(0.05, 0.5, n), repeat=1)
        print(f"| {n} | {n / b1:,.0f} | {c1:.1f} | {n * config.steps / b2:,.0f} | {c2:.1f} |")

    settings = {p.name: p.default for p in tuning.SETTINGS}
    settings.update(horizon=20.0, dt=0.05)
    loss = tuning.make_loss(settings)
    grad = jax.jit(jax.value_and_grad(lambda v: loss(v)[0]))
    values = {k: jnp.asarray(v) for k, v in tuning.PAPER.items()}
    c, b = timed(grad, values)
    print(f"\ntuning (value_and_grad, 401 periods): {1 / b:.2f} steps/s ({b:.2f} s per step), compile {c:.1f} s")

    if not args.no_mujoco:
        from jaxloco.robots.snake import scenarios, sim_control
        from jaxloco.sim.rollout import rollout

        sc = scenarios.snake_scenario(
            5.0, 0.02, sim_control.task_space_controller(0.02, "tip"), phi0=experiments.zigzag_phi()
        )
        for n in (1, 6):
            params = sim_control.params_batch(n, switch_at=1.0)
            rollout(sc, params)  # compile
            t = time.perf_counter()
            res = rollout(sc, params)
            dt = time.perf_counter() - t
            steps = n * sc.horizon * sc.substeps
            print(f"MuJoCo closed loop, batch {n}: {steps / dt:,.0f} physics steps/s "
                  f"({n * sc.horizon * sc.substeps * 0.002 / dt:.1f} x real time), status {set(res.status)}")


if __name__ == "__main__":
    main()
