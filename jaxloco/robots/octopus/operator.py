"""The operator of OCTOPUS's semi-autonomous system, kept apart from the CLM controller.

The paper's CLM cannot measure the yaw ("To real OCTOPUS, the yaw angle of robot cannot
be got ... we assume the yaw angle is not change"), and the system is semi-autonomous:
"the operator just inputs move direction" from the in-vehicle camera image. So the CLM
(`clm`) never reads the heading; a course that drifts is the operator's to correct.

`with_operator` models that operator as a separate, switchable layer over any OCTOPUS
controller: while the controller drives straight (both crawler commands equal and
forward), the operator adds a track speed difference against the heading error that a
person watching would see, the robot's yaw from facing the steps squarely (world +x, the
risers' normal; yaw from the simulated IMU quaternion, which here stands for the person's
eyes). `operator_gain` = 0 (the default) switches it off: the actions are then exactly the
controller's, and every paper row runs that way.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxloco.robots.octopus import params
from jaxloco.sim.scenario import Controller

Array = jax.Array

PARAM_DEFAULTS: dict[str, float] = {
    "operator_gain": params.PARAMETERS.default("operator_gain"),  # [m/s per rad] default (ours): 0 = no operator
}


def heading(quat: Array) -> Array:
    """Yaw [rad] of the body x axis about the world z axis, from a (w, x, y, z) quaternion."""
    w, x, y, z = quat[0], quat[1], quat[2], quat[3]
    return jnp.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def steer(tracks: Array, yaw: Array, gain: Array) -> Array:
    """Crawler commands (left, right) [m/s] with the operator's correction: while both are
    equal and forward, left - right = 2 gain yaw (yaw > 0 is a turn to the left, so the
    left track speeds up and turns it back), the correction capped at the commanded
    speed; otherwise unchanged."""
    v = 0.5 * (tracks[0] + tracks[1])
    straight = (jnp.abs(tracks[0] - tracks[1]) < 1e-9) & (v > 0.0)
    d = jnp.clip(gain * yaw, -v, v)
    return jnp.where(straight, jnp.stack([v + d, v - d]), tracks)


def with_operator(controller: Controller) -> Controller:
    """`controller` with the operator layer (params["operator_gain"]); its state is the
    controller's own (the operator is stateless: the reference heading is the risers'
    normal, which the person sees)."""

    def step(p, s, obs):
        s_new, action = controller.step(p, s, obs)
        tracks = steer(action[:2], heading(obs["quat"].astype(action.dtype)), p["operator_gain"])
        return s_new, action.at[:2].set(tracks.astype(action.dtype))

    return Controller(controller.init, step, name=controller.name)
