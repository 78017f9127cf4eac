"""Dump real force-distribution QPs of the leg-grope walk (one per 15 ms step of cycles
on random slopes) to an npz for `bench_qp.py --problems`.

    python benchmarks/dump_leggrope_qps.py --out /tmp/leggrope_qps.npz --cycles 8
    python benchmarks/bench_qp.py --problems /tmp/leggrope_qps.npz --iterations 20
"""

from __future__ import annotations

import argparse

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco import runtime


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="/tmp/leggrope_qps.npz")
    ap.add_argument("--cycles", type=int, default=8)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    runtime.configure(x64=True)
    from jaxloco.robots.leggrope import forces, gait, params

    p, walk, cfg, settings = params.default_params(), gait.WalkParams(), gait.WalkConfig(), forces.QPSettings()
    weight = float(p.total_mass) * 9.81

    def problems(theta, psi):
        terrain = gait.simple_slope(theta, psi)
        plan = gait.plan_cycle(p, walk, terrain, cfg)
        r_ref = p.r_ref_factor * weight * jnp.cos(theta)

        def one(i):
            info = gait.step_info(i, cfg, p.dt)
            dyn = forces.step_dynamics(p, walk, plan, terrain, info, cfg)
            ramp = jnp.where(info.phase == 1, 0.25 * weight * (1 - info.fraction), r_ref * info.fraction)
            modes = forces.leg_modes(info, ramp)
            A, b, G, h = forces.build_constraints(p, dyn, modes, r_ref, -settings.s_tol * weight)
            Q, q = forces.controller_cost(p, dyn, jnp.zeros(12), jnp.asarray(0.0), settings)
            return dict(Q=Q, q=q, A=A, b=b, G=G, h=h, x_scale=forces.x_scale(p, Q.dtype))

        return jax.vmap(one)(jnp.arange(cfg.n_steps))

    rng = np.random.default_rng(args.seed)
    theta = jnp.asarray(rng.uniform(-0.35, 0.35, args.cycles))
    psi = jnp.asarray(rng.uniform(-np.pi / 2, np.pi / 2, args.cycles))
    out = jax.jit(jax.vmap(problems))(theta, psi)
    arrays = {k: np.asarray(v).reshape((-1,) + v.shape[2:]) for k, v in out.items()}
    np.savez(args.out, **arrays)
    print(f"wrote {args.out}: {arrays['Q'].shape[0]} QPs of n={arrays['Q'].shape[1]}, "
          f"m={arrays['A'].shape[1]}, p={arrays['G'].shape[1]}")


if __name__ == "__main__":
    main()
