"""Design of the footstep sequence of the leg-grope walk cycle: initial stance and the
sideways shift of each leg's step.

With h_ref = 1/2 the admissible regions are tight (see `gait` module docstring): the
plan's margins depend strongly on where the four feet start and where they land.
`search_footsteps` maximizes the worst `design_score` of the cycle over the 8 stance
coordinates and the 4 sideways shifts by a cross-entropy search (batched planner calls),
subject to a reach margin for every leg. The plan's barycentric geometry is invariant
under the slope's affine foreshortening, but the swinging leg's mass is not (on a slope
the body sits uphill of the footprint, which changes the leg configurations), hence a
worst case over slopes.

* The literal numbering's footsteps (`gait.DEFAULT_STANCE`, `gait.DEFAULT_LATERAL`), for
  the paper's A-D cycle, came from

      python -m jaxloco.robots.leggrope.design --seed 0

  (objective "plan": the worst region margin over `DESIGN_SLOPES`, |theta| <= 0.5 and
  four walking directions): -1.7 mm.
* The mirrored numbering's experimental walk (`gait.DESIGNS["mirrored"]`) is designed for
  surviving a collapse, objective "collapse": the worst-case triangle margin of
  the cycle (the grope's COG inside the other three legs' triangle) subject to every grope
  reaching R_ref (the groped foothold inside its step-D region), both at least the score,
  with the planner's "collapse_safe" COG rule. Step B's COG is then the walk's A'
  position, not the grope's (the paper's steps A', D'-1 move the COG between them). From

      python -m jaxloco.robots.leggrope.design --numbering mirrored --iterations 200 --seed 3

  (`COLLAPSE_SLOPES`: theta 0 and pi/12, psi 0; stride 0.06 m; 1 min on 2 cores) the
  design reaches `gait.MIRRORED_DESIGN_MARGIN` (11.0 mm).

A user redesigns for another body (`LegGropeParams`), R_ref (`--r-ref-factor`) or stride
(`--stride`) by the same call.
"""

from __future__ import annotations

import argparse
from dataclasses import replace

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco.robots.leggrope import gait
from jaxloco.robots.leggrope.params import LegGropeParams, default_params

# The footsteps must serve every slope: on a slope the body sits uphill of the footprint
# (the COG's vertical projection is what the regions constrain), which changes the leg
# configurations and so the COG shift of each swing. The search maximizes the worst case.
DESIGN_SLOPES = np.array(
    [(t, p) for t in (0.0, 0.25, -0.25, 0.5, -0.5) for p in (0.0, 0.25 * np.pi, -0.25 * np.pi, 0.5 * np.pi)]
)


# The experimental walk's collapse-safe design is made for the paper's experiments: the
# pi/12 slope walked straight up (and level ground).
COLLAPSE_SLOPES = np.array([(0.0, 0.0), (np.pi / 12, 0.0)])
OBJECTIVES = ("plan", "collapse", "static")


def design_score(
    params: LegGropeParams,
    walk: gait.WalkParams,
    config: gait.WalkConfig,
    x: jax.Array,
    min_reach: float,
    max_lateral: float,
    slopes: np.ndarray,
    objective: str = "plan",
) -> jax.Array:
    """Worst margin [m] of the footsteps x = (stance (8), lateral (4)) over the (theta, psi)
    pairs `slopes`, penalized when a leg's reach margin falls below `min_reach` or a
    sideways step exceeds `max_lateral` (long sideways steps swing a foot past its hip,
    where the yaw joint whips round and the leg's inertia upsets the force balance).

    objective "plan": the plan margin (`CyclePlan.margin`, "balanced" COG rule: the
    paper's A-D cycle). "collapse": with the "collapse_safe" COG rule, the smaller of (the
    groped foothold inside the step-D region, the grope's COG inside the triangle of the
    other three legs) over the cycle's four gropes: the worst-case triangle margin subject
    to every grope reaching R_ref (both >= the score). "static": with the "static_safe"
    rule, the region margins and the triangle margin together (the A-D cycle, whose COG
    stays still from step B to D). For "collapse" and "static" the sideways shifts are x[8:]
    minus their mean, so that the body does not drift sideways over the cycle."""
    rule = {"plan": "balanced", "collapse": "collapse_safe", "static": "static_safe"}[objective]
    lateral = x[8:] if objective == "plan" else x[8:] - jnp.mean(x[8:])
    w = replace(walk, stance=x[:8].reshape(4, 2), lateral=lateral)
    config = replace(config, cog_rule=rule)
    slopes = jnp.asarray(slopes, x.dtype)
    plans = jax.vmap(lambda tp: gait.plan_cycle(params, w, gait.simple_slope(tp[0], tp[1]), config))(slopes)
    margin = jnp.min(jax.vmap(lambda pl: pl.rule_margin(rule))(plans))
    reach = jnp.min(plans.reach_margin)
    over = jnp.sum(jnp.maximum(jnp.abs(lateral) - max_lateral, 0.0))
    return margin - 2.0 * jnp.maximum(min_reach - reach, 0.0) - 2.0 * over


def search_footsteps(
    params: LegGropeParams | None = None,
    walk: gait.WalkParams | None = None,
    config: gait.WalkConfig | None = None,
    *,
    objective: str = "plan",
    seed: int = 0,
    population: int = 128,
    elite: int = 16,
    iterations: int = 30,
    min_reach: float = 0.02,
    max_lateral: float = 0.08,
    slopes: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, float]:
    """Cross-entropy search from `walk`'s footsteps; returns (stance (4, 2), lateral (4,),
    score [m]). objective "plan" (and "static"): the paper's A-D cycle, over
    `DESIGN_SLOPES` by default; "collapse": the experimental walk surviving a collapse,
    over `COLLAPSE_SLOPES` by default; see `design_score`."""
    if objective not in OBJECTIVES:
        raise ValueError(f"unknown objective {objective!r}; expected one of {OBJECTIVES}")
    params = params or default_params()
    walk = walk or gait.WalkParams()
    config = config or gait.WalkConfig()
    if slopes is None:
        slopes = DESIGN_SLOPES if objective == "plan" else COLLAPSE_SLOPES
    score = jax.jit(jax.vmap(lambda x: design_score(params, walk, config, x, min_reach, max_lateral, slopes,
                                                    objective)))
    rng = np.random.default_rng(seed)
    mean = np.concatenate([np.asarray(walk.stance, float).reshape(-1), np.asarray(walk.lateral, float)])
    std = np.full(12, 0.03)
    best, best_score = mean.copy(), -np.inf
    for _ in range(iterations):
        pop = mean + std * rng.standard_normal((population, 12))
        pop[0] = best
        s = np.asarray(score(jnp.asarray(pop)))
        top = np.argsort(-s)[:elite]
        if s[top[0]] > best_score:
            best, best_score = pop[top[0]].copy(), float(s[top[0]])
        mean = pop[top].mean(axis=0)
        std = np.maximum(pop[top].std(axis=0), 1e-3)
    lateral = best[8:] if objective == "plan" else best[8:] - best[8:].mean()  # as `design_score` scored it
    return best[:8].reshape(4, 2), lateral, best_score


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--numbering", choices=tuple(gait.DESIGNS), default="literal",
                    help="leg numbering; the search starts from its shipped footsteps")
    ap.add_argument("--objective", choices=OBJECTIVES, default=None,
                    help="plan: region margins of the A-D cycle over DESIGN_SLOPES; static: the same and the "
                         "triangle margin (zero-mean sideways shifts); collapse: worst triangle/grope margin over "
                         "COLLAPSE_SLOPES (default: collapse for the mirrored numbering, plan for the literal)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--stride", type=float, default=float(gait.WalkParams().stride))
    ap.add_argument("--iterations", type=int, default=30)
    ap.add_argument("--max-lateral", type=float, default=0.08)
    ap.add_argument("--r-ref-factor", type=float, default=None,
                    help="R_ref / (M g cos theta) (default: the paper's 1/2)")
    args = ap.parse_args(argv)
    jax.config.update("jax_enable_x64", True)
    design = gait.gait_design(args.numbering)
    objective = args.objective or ("collapse" if design.cog_rule == "collapse_safe" else "plan")
    params = default_params()
    if args.r_ref_factor is not None:
        params = params.with_(r_ref_factor=args.r_ref_factor)
    stance, lateral, s = search_footsteps(
        params, design.walk(stride=args.stride), design.config(), objective=objective, seed=args.seed,
        iterations=args.iterations, max_lateral=args.max_lateral,
    )
    print(f"{args.numbering} numbering, objective {objective}: smallest margin {s * 1000:.2f} mm with")
    print("stance (u, v) [m] =", np.array2string(np.round(stance, 4), separator=", "))
    print("lateral [m] =", np.array2string(np.round(lateral, 4), separator=", "))


if __name__ == "__main__":
    main()
