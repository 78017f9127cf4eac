"""What T² Snake-3 adds to jaxloco's registries (`jaxloco.registry`): its sweep
analyses, tune objectives and replays, as "module:attribute" references that are imported
only when used. Strings only: importing this module imports no robot code."""

from __future__ import annotations

# sweep analyses (jaxloco.analysis.Analysis)
ANALYSES: dict[str, str] = {
    "snake.kv": "jaxloco.robots.snake.analysis:KV",
    "snake.reach": "jaxloco.robots.snake.sim_analysis:REACH",
    "snake.table3": "jaxloco.robots.snake.table3:TABLE3",
    "snake.contact": "jaxloco.robots.snake.contact:CONTACT",
    "snake.operations": "jaxloco.robots.snake.operations_analysis:OPERATIONS",
}

# tune objectives (jaxloco.tune.Objective)
OBJECTIVES: dict[str, str] = {
    "snake.kv": "jaxloco.robots.snake.tuning:KV_TUNE",
    "snake.reach_gain": "jaxloco.robots.snake.mjx_tuning:REACH_GAIN_TUNE",
}

# replays of a table row (jaxloco.render.replay): row -> Replay; other simulated analyses get the generic one
REPLAYS: dict[str, str] = {
    "snake.kv": "jaxloco.render.kinematic:snake_kv",
    "snake.operations": "jaxloco.render.replay:snake_operation",
}
