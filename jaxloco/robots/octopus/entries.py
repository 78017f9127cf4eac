"""What OCTOPUS adds to jaxloco's registries (`jaxloco.registry`): its sweep
analyses, tune objectives and replays, as "module:attribute" references that are imported
only when used. Strings only: importing this module imports no robot code."""

from __future__ import annotations

# sweep analyses (jaxloco.analysis.Analysis)
ANALYSES: dict[str, str] = {
    "octopus.terrain_classification": "jaxloco.robots.octopus.analysis:TERRAIN_CLASSIFICATION",
    "octopus.step_climb": "jaxloco.robots.octopus.sim_analysis:STEP_CLIMB",
    "octopus.paper": "jaxloco.robots.octopus.paper_analysis:PAPER_EXPERIMENTS",
}

# tune objectives (jaxloco.tune.Objective)
OBJECTIVES: dict[str, str] = {
    "octopus.sigma": "jaxloco.robots.octopus.tuning:SIGMA_TUNE",
    "octopus.climb_lift": "jaxloco.robots.octopus.mjx_tuning:CLIMB_LIFT_TUNE",
}

# replays of a table row (jaxloco.render.replay): row -> Replay; other simulated analyses get the generic one
REPLAYS: dict[str, str] = {
    "octopus.step_climb": "jaxloco.render.replay:octopus_step_climb",
    "octopus.paper": "jaxloco.render.replay:octopus_step_climb",
}

# analyses without a replay, and why
NO_REPLAY: dict[str, str] = {
    "octopus.terrain_classification": "a row is a Monte-Carlo set of static postures, not a motion",
}
