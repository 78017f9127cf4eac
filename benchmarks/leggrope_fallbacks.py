"""Where should a leg grope next when its target foothold collapses? A search over
fallback offsets for the simulated leg-grope walk (`gait.GaitDesign.fallback`).

For each leg and each offset (walking frame, u forward, v left; at least `--distance`
from the primary target, and its pad at least `--clearance` from the edges of that leg's
primary and starting pads, so that a toe landing a little off target does not share its
load between two pads: a weak foothold then passes its grope) the cycle is re-planned with
that leg on its fallback, and the worst margin that the design's COG rule maximizes
(`gait.CyclePlan.rule_margin`: for the literal walk the COG and groped-foothold margins,
for the mirrored walk the groped-foothold and triangle margins of every grope) over
several slopes is printed for the best offsets. Then the worst margin of all 16
primary/fallback combinations with the design's directions.

    python benchmarks/leggrope_fallbacks.py [--numbering mirrored] [--distance 0.04] [--clearance 0.012]
"""

from __future__ import annotations

import argparse

import numpy as np

SLOPES = {  # the slopes each design is for (theta, psi) [rad]
    "literal": ((0.0, 0.0), (np.pi / 12, 0.0), (np.pi / 12, np.pi / 2), (0.35, 0.0), (0.35, np.pi / 2)),
    "mirrored": ((0.0, 0.0), (np.pi / 12, 0.0)),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--numbering", choices=tuple(SLOPES), default="mirrored")
    parser.add_argument("--distance", type=float, default=0.04, help="smallest fallback offset [m]")
    parser.add_argument("--clearance", type=float, default=0.0,
                        help="smallest gap between the fallback pad and the leg's primary and starting pads [m]")
    args = parser.parse_args()

    from jaxloco import runtime

    runtime.configure(x64=True, cache_dir=True)
    import jax
    import jax.numpy as jnp

    from jaxloco.robots.leggrope import control, gait, scenarios
    from jaxloco.robots.leggrope.scenarios import PAD_HALF

    design = gait.gait_design(args.numbering)
    slopes = SLOPES[args.numbering]
    p = {k: jnp.asarray(v) for k, v in scenarios.PARAM_DEFAULTS.items()}
    robot = control.robot_params(p)
    walk = design.walk(stride=p["stride"], swing_height=p["swing_height"])
    config = design.config()
    primary = jnp.stack([jnp.full(4, walk.stride), jnp.asarray(walk.lateral)], axis=1)
    grid = np.arange(-0.08, 0.0801, 0.01)
    offsets = np.array([(u, v) for u in grid for v in grid if np.hypot(u, v) >= args.distance - 1e-9])
    gap = 2 * PAD_HALF + args.clearance  # square pads: Chebyshev distance between centres

    def clear(g):
        """Offsets whose pad keeps `clearance` from leg g's primary and starting pads."""
        start = -np.asarray(primary[g])  # the starting pad, relative to the primary
        return (np.max(np.abs(offsets), 1) >= gap - 1e-9) & (np.max(np.abs(offsets - start), 1) >= gap - 1e-9)

    def worst_margin(steps):
        out = []
        for theta, psi in slopes:
            terrain = gait.simple_slope(jnp.asarray(theta), jnp.asarray(psi))
            plan = gait.plan_cycle(robot, walk, terrain, config, steps=steps)
            ok = plan.reach_margin > 0.005  # the legs reach every planned placement
            out.append(jnp.where(ok, plan.rule_margin(design.cog_rule), -1.0))
        return jnp.min(jnp.stack(out))

    one_leg = jax.jit(jax.vmap(lambda g, o: worst_margin(primary.at[g].add(o)), (None, 0)))
    print(f"{args.numbering} walk: worst {design.cog_rule} margin [mm] over {len(slopes)} slopes with one leg on a "
          f"fallback {args.distance * 1000:.0f}+ mm away (primary plan: {1000 * float(worst_margin(primary)):.1f} mm)")
    chosen = np.zeros((4, 2))
    for label, g in enumerate(design.legs):
        m = np.where(clear(g), np.asarray(one_leg(g, jnp.asarray(offsets))), -np.inf)
        best = np.argsort(-m)[:4]
        chosen[g] = offsets[best[0]]
        cells = ", ".join(f"({offsets[i][0]:+.2f}, {offsets[i][1]:+.2f}): {1000 * m[i]:.1f}" for i in best)
        print(f"  L{label + 1} (physical leg {g}): {cells}")
    _combinations(jax, jnp, worst_margin, primary, chosen, "the best offsets above")
    _combinations(jax, jnp, worst_margin, primary, np.asarray(design.fallback) * args.distance, "the design's offsets")


def _combinations(jax, jnp, worst_margin, primary, offsets, name: str) -> None:
    """Print the worst margin of each of the 16 primary/fallback combinations."""
    dirs = jnp.asarray(offsets)
    combos = np.array([[(c >> g) & 1 for g in range(4)] for c in range(16)], bool)
    steps = jnp.where(jnp.asarray(combos)[:, :, None], primary[None] + dirs[None], primary[None])
    m = np.asarray(jax.jit(jax.vmap(worst_margin))(steps))
    print(f"{name} {np.round(offsets, 3).tolist()} [m] (physical legs): worst margin per "
          "combination (bit g: physical leg g on its fallback) [mm]")
    print("  " + " ".join(f"{c}:{1000 * v:.1f}" for c, v in enumerate(m)))


if __name__ == "__main__":
    main()
