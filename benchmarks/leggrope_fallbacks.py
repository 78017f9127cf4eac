"""Where should a leg grope next when its target foothold collapses? A search over
fallback offsets for the simulated leg-grope walk (`control.FALLBACK_DIRECTIONS`).

For each leg and each offset (walking frame, u forward, v left; at least `--distance`
from the primary target so that the pads do not overlap) the cycle is re-planned with
that leg on its fallback, and the worst plan margin (COG and groped-foothold margins of
every grope, `gait.plan_cycle`) over several slopes and walking directions is printed
for the best offsets. Then the worst margin of all 16 primary/fallback combinations with
the chosen directions.

    python benchmarks/leggrope_fallbacks.py [--distance 0.04]
"""

from __future__ import annotations

import argparse

import numpy as np

SLOPES = ((0.0, 0.0), (np.pi / 12, 0.0), (np.pi / 12, np.pi / 2), (0.35, 0.0), (0.35, np.pi / 2))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--distance", type=float, default=0.04, help="smallest fallback offset [m]")
    args = parser.parse_args()

    from jaxloco import runtime

    runtime.configure(x64=True, cache_dir=True)
    import jax
    import jax.numpy as jnp

    from jaxloco.robots.leggrope import control, gait, scenarios

    p = {k: jnp.asarray(v) for k, v in scenarios.PARAM_DEFAULTS.items()}
    robot = control.robot_params(p)
    walk = gait.WalkParams(stride=p["stride"], swing_height=p["swing_height"])
    primary = jnp.stack([jnp.full(4, walk.stride), jnp.asarray(walk.lateral)], axis=1)
    grid = np.arange(-0.06, 0.0601, 0.01)
    offsets = np.array([(u, v) for u in grid for v in grid if np.hypot(u, v) >= args.distance - 1e-9])

    def worst_margin(steps):
        out = []
        for theta, psi in SLOPES:
            plan = gait.plan_cycle(robot, walk, gait.simple_slope(jnp.asarray(theta), jnp.asarray(psi)), steps=steps)
            ok = plan.reach_margin > 0.005  # the legs reach every planned placement
            out.append(jnp.where(ok, plan.margin, -1.0))
        return jnp.min(jnp.stack(out))

    one_leg = jax.jit(jax.vmap(lambda g, o: worst_margin(primary.at[g].add(o)), (None, 0)))
    print(f"worst plan margin [mm] over {len(SLOPES)} slopes with one leg on a fallback {args.distance * 1000:.0f}+ mm "
          f"away (primary plan: {1000 * float(worst_margin(primary)):.1f} mm)")
    for g in range(4):
        m = np.asarray(one_leg(g, jnp.asarray(offsets)))
        best = np.argsort(-m)[:4]
        cells = ", ".join(f"({offsets[i][0]:+.2f}, {offsets[i][1]:+.2f}): {1000 * m[i]:.1f}" for i in best)
        print(f"  L{g + 1}: {cells}")

    dirs = jnp.asarray(control.FALLBACK_DIRECTIONS) * args.distance
    combos = np.array([[(c >> g) & 1 for g in range(4)] for c in range(16)], bool)
    steps = jnp.where(jnp.asarray(combos)[:, :, None], primary[None] + dirs[None], primary[None])
    m = np.asarray(jax.jit(jax.vmap(worst_margin))(steps))
    print(f"chosen directions {control.FALLBACK_DIRECTIONS}: worst plan margin per combination (bit g: leg g+1 on "
          "its fallback) [mm]")
    print("  " + " ".join(f"{c}:{1000 * v:.1f}" for c, v in enumerate(m)))


if __name__ == "__main__":
    main()
