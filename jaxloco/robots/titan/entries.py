"""What TITAN XI adds to jaxloco's registries (`jaxloco.registry`): its sweep
analyses, tune objectives and replays, as "module:attribute" references that are imported
only when used. Strings only: importing this module imports no robot code."""

from __future__ import annotations

# sweep analyses (jaxloco.analysis.Analysis)
ANALYSES: dict[str, str] = {
    "titan.stride": "jaxloco.robots.titan.analysis:STRIDE",
    "titan.walk": "jaxloco.robots.titan.sim_analysis:WALK",
}

# tune objectives (jaxloco.tune.Objective)
OBJECTIVES: dict[str, str] = {
    "titan.stride": "jaxloco.robots.titan.tuning:STRIDE_TUNE",
    "titan.body_gain": "jaxloco.robots.titan.mjx_tuning:BODY_GAIN_TUNE",
}

# replays of a table row (jaxloco.render.replay): row -> Replay; other simulated analyses get the generic one
REPLAYS: dict[str, str] = {
    "titan.stride": "jaxloco.render.kinematic:titan_stride",
    "titan.walk": "jaxloco.render.replay:titan_walk",
}
