"""Robot models, each from its paper: params, kinematics, control, scenarios.

Packages: `leggrope`, `octopus`, `titan`, `snake`; each lists its modules in its own
docstring and its analyses, objectives and replays in its `entries` module.
"""
