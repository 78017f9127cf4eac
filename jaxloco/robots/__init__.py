"""Robot models, each from its paper: params, kinematics, control, scenarios."""
