"""Physics steps per second: the leg-grope quadruped (12 joints, 4 toe contacts on a
box), native `mujoco.batch` open loop and closed loop (jitted JAX controller every
control period) and MJX, at several batch sizes; compile times of the MJX rollout; and
each robot's own closed loop (`ROBOTS`) on both backends.

    python benchmarks/bench_sim.py                     # batch 1, 64, 1024
    python benchmarks/bench_sim.py --mjx-batches 1 64  # MJX is slow on CPU
    python benchmarks/bench_sim.py --robots leggrope titan --batches 1 64 --mjx-batches 1 64

Closed loop uses `scenarios.standing_scenario` (a joint-space controller, records and
metrics: the rollout API's full per-period overhead); with --robots, each robot's closed
loop as its simulated analysis runs it (`ROBOTS`: the scenario for a backend and a batch
of its params). Run it twice to see MJX compile time with a cold and a warm JAX cache
(`JAXLOCO_CACHE_DIR=/tmp/empty-cache python ...` for a cold one).
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def native_open_loop(scenario, params, steps: int, nthread: int) -> float:
    """Physics steps/s of the scenario's batch with no controller: the same model, model
    fields and initial state as the closed loop (robots standing, toes loaded), the
    initial joint targets held, all `steps` in one `Batch.step` call."""
    import jax
    import mujoco

    from jaxloco.sim import native

    n = len(next(iter(params.values())))
    b = native.make_batch(scenario, params, n, nthread)
    init = jax.jit(jax.vmap(scenario.initial_state))(params, jax.random.split(jax.random.PRNGKey(0), n))
    b.reset(stage=mujoco.mjtStage.mjSTAGE_NONE)
    for name in ("qpos", "qvel", "ctrl", "mocap_pos", "mocap_quat"):
        b.bind(name)[...] = np.asarray(getattr(init, name))
    b.forward()
    b.step(nstep=10)  # warm up
    t = time.perf_counter()
    b.step(nstep=steps)
    return n * steps / (time.perf_counter() - t)


def closed_loop(scenario, params, backend: str, nthread: int = 0) -> tuple[float, float]:
    """(steps/s of the second call, first-call seconds)."""
    from jaxloco.sim.rollout import rollout

    n = len(next(iter(params.values())))
    t0 = time.perf_counter()
    rollout(scenario, params, backend=backend, nthread=nthread)
    first = time.perf_counter() - t0
    t0 = time.perf_counter()
    out = rollout(scenario, params, backend=backend, nthread=nthread)
    wall = time.perf_counter() - t0
    loop = out.timing.get("loop_s", wall)
    return n * scenario.physics_steps / loop, first


def leggrope_walk(horizon_s: float, backend: str):
    """The leg-grope walk (grope controller, 15 degree slope) as `leggrope.fragile_walk` runs it
    on `backend` (MJX: the scenario's MJX variant, `make_scenario(mjx_contacts=True)`)."""
    from jaxloco.robots.leggrope import scenarios

    return (scenarios.make_scenario(horizon_s=horizon_s, record_every=5, mjx_contacts=backend == "mjx"),
            scenarios.params_batch)


def snake_reach(horizon_s: float, backend: str):
    """T² Snake-3's gripper-tip reach (`snake.reach`: feedback task-space control from the
    settled robot), on the box ground natively and on its MJX variant (the plane) on MJX;
    the rows' gains K spread over 0.5-2 /s."""
    from jaxloco.robots.snake import sim_analysis

    scenario = sim_analysis.REACH.simulate.scenario(
        {"ground": "box", "horizon": horizon_s, "settle": sim_analysis.SETTLE, "backend": backend})
    return scenario, lambda n: sim_analysis.reach_params(n, gain_k=np.linspace(0.5, 2.0, n))


def octopus_climb(horizon_s: float, backend: str):
    """The OCTOPUS CLM getting over the 400 mm step (`octopus.step_climb`'s scenario, the
    same model on both backends), the paper's perturbed starts (`paper_analysis.perturbations`)."""
    from jaxloco.robots.octopus import paper_analysis, scenarios, sim_analysis

    scenario = sim_analysis.scenario({"kind": "step1", "controller": "clm", "horizon": horizon_s})
    return scenario, lambda n: scenarios.params_batch(n, **paper_analysis.perturbations(n))


def titan_walk(horizon_s: float, backend: str):
    """TITAN XI's `titan.walk` closed loop (the footstep executor and its records) on
    `backend`'s model (native, or the MJX variant: `scenarios.mjx_variant`): the
    analysis' default row, one cycle planned on a survey of the Sec. 7 grid (0.2 m frames
    every 2.0 m, 28 beams), cut to `horizon_s`."""
    from jaxloco.analysis import get
    from jaxloco.robots.titan import scenarios, sim_analysis

    values = {**get("titan.walk").defaults(), "n_cycles": 1}
    plan, _, scalars = sim_analysis.plan_row(values, np.zeros(2, np.uint32), 1)
    field, _, width = sim_analysis.row_terrain(values)
    scenario = scenarios.make_scenario(plan.n_steps, horizon_s=horizon_s, beam_width=width, field=field,
                                       record_every=5, backend=backend)
    return scenario, lambda n: scenarios.params_batch(plan, n, **scalars)


# robot -> builder(horizon [s], backend) -> (scenario, params(n) -> a batch of n param sets)
ROBOTS = {"leggrope": leggrope_walk, "snake": snake_reach, "octopus": octopus_climb, "titan": titan_walk}


def memory_maps() -> int:
    """This process' memory mappings (Linux; 0 elsewhere). Every compiled XLA CPU program
    keeps its code mapped, and a process may hold `vm.max_map_count` maps (65,530 by
    default): past it LLVM fails with "Unable to allocate section memory"."""
    try:
        with open("/proc/self/maps") as f:
            return sum(1 for _ in f)
    except OSError:
        return 0


def robot_rows(name: str, horizon_s: float, batches: list[int], mjx_batches: list[int], nthread: int,
               keep_programs: bool = False) -> None:
    """Print the robot's closed-loop steps/s on each backend and the MJX first call; then,
    unless `keep_programs`, drop JAX's compiled programs (`jax.clear_caches`) so that a
    run over every robot stays under the process' limit of memory maps."""
    import gc

    import jax

    for backend, sizes in (("native", batches), ("mjx", mjx_batches)):
        scenario, params = ROBOTS[name](horizon_s, backend)
        for n in sizes:
            rate, first = closed_loop(scenario, params(n), backend, nthread)
            print(f"{name:>9} {backend:>7} {n:>6} {rate:>12,.0f} {first:>15.1f} {memory_maps():>10,}")
        del scenario, params
    if not keep_programs:
        gc.collect()
        jax.clear_caches()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batches", type=int, nargs="+", default=[1, 64, 1024])
    ap.add_argument("--mjx-batches", type=int, nargs="*", default=[1, 64])
    ap.add_argument("--periods", type=int, default=100, help="control periods per closed-loop rollout")
    ap.add_argument("--substeps", type=int, default=10, help="physics steps per control period")
    ap.add_argument("--nthread", type=int, default=0)
    ap.add_argument("--robots", nargs="+", choices=sorted(ROBOTS), default=[],
                    help="time these robots' own closed loops instead of the standing quadruped")
    ap.add_argument("--horizon", type=float, default=2.0, help="simulated seconds per robot rollout (--robots)")
    ap.add_argument("--keep-programs", action="store_true",
                    help="keep every robot's compiled programs (default: drop them after each robot)")
    args = ap.parse_args()

    from jaxloco import runtime

    runtime.configure(x64=True, cache_dir=True)
    import jax

    from jaxloco.robots.leggrope import scenarios
    from jaxloco.sim.rollout import stack_params

    if args.robots:
        print(f"devices: {jax.device_count()} x {jax.devices()[0].platform}; {args.horizon} s per rollout")
        print(f"{'robot':>9} {'backend':>7} {'batch':>6} {'steps/s':>12} {'first call [s]':>15} {'memory maps':>11}")
        for name in args.robots:
            robot_rows(name, args.horizon, args.batches, args.mjx_batches, args.nthread, args.keep_programs)
        return

    sc = scenarios.standing_scenario(horizon=args.periods, substeps=args.substeps, record_every=10)
    print(f"devices: {jax.device_count()} x {jax.devices()[0].platform}; physics dt {sc.model.opt.timestep} s; "
          f"{args.substeps} steps per control period; {args.periods} periods")

    def params(n):
        rng = np.random.default_rng(0)
        return stack_params([{"ground": 0.0, "offset": float(rng.uniform(-0.05, 0.05)), "mu": 1.0, "kick": 0.0}
                             for _ in range(n)])

    print(f"{'batch':>6} {'native open':>14} {'native closed':>14} {'closed/open':>12}")
    for n in args.batches:
        open_ = native_open_loop(sc, params(n), sc.physics_steps, args.nthread)
        closed, _ = closed_loop(sc, params(n), "native", args.nthread)
        print(f"{n:>6} {open_:>14,.0f} {closed:>14,.0f} {closed / open_:>12.2f}")

    short = scenarios.standing_scenario(horizon=max(10, args.periods // 5), substeps=args.substeps, record_every=10)
    print(f"\nMJX on {jax.devices()[0].platform} ({short.physics_steps} physics steps per rollout)")
    print(f"{'batch':>6} {'steps/s':>12} {'first call [s]':>15}")
    for n in args.mjx_batches:
        rate, first = closed_loop(short, params(n), "mjx")
        print(f"{n:>6} {rate:>12,.0f} {first:>15.1f}")


if __name__ == "__main__":
    main()
