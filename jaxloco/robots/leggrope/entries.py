"""What the leg-grope walk adds to jaxloco's registries (`jaxloco.registry`): its sweep
analyses, tune objectives and replays, as "module:attribute" references that are imported
only when used. Strings only: importing this module imports no robot code."""

from __future__ import annotations

# sweep analyses (jaxloco.analysis.Analysis)
ANALYSES: dict[str, str] = {
    "leggrope.slope_cycle": "jaxloco.robots.leggrope.analysis:SLOPE_CYCLE",
    "leggrope.fragile_walk": "jaxloco.robots.leggrope.sim_analysis:FRAGILE_WALK",
}

# tune objectives (jaxloco.tune.Objective)
OBJECTIVES: dict[str, str] = {
    "leggrope.shear_relief": "jaxloco.robots.leggrope.mjx_tuning:SHEAR_RELIEF_TUNE",
}

# replays of a table row (jaxloco.render.replay): row -> Replay; other simulated analyses get the generic one
REPLAYS: dict[str, str] = {
    "leggrope.slope_cycle": "jaxloco.render.kinematic:leggrope_slope_cycle",
    "leggrope.fragile_walk": "jaxloco.render.replay:leggrope_fragile_walk",
}
