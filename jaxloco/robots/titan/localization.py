"""Self-localisation of TITAN XI by surveying (Hodoshima et al. 2007, Sec. 8.2.2): the
robot's pose from three total-station (TS) measurements of a corner cube that a
mechanism on the robot turns on a circle, plus a single-axis attitude sensor. Pure JAX
(jit, vmap, grad).

The paper: "The corner cube ... rotates ... with a certain radius, and is tracked
automatically by TS on the ground to measure coordinates of three arbitrary points on
the circumference ... With these coordinates of the three points, both the coordinates
of the rotating center and the vector indicating the axis direction of rotation are
derived. Using this information with additional information from the single-axis
attitude sensor, the pose of the robot can be identified." Fig. 25 (the mechanism) is
not in our copy, so how the axis is mounted is a reading:

  * "x" (default, ours): the rotation axis along the body's x_b (forward). The circle then
    gives the heading and pitch of x_b, which nothing else on the robot measures, and the
    single-axis attitude sensor is an inclinometer giving the roll about x_b (gravity
    gives roll and pitch, never heading). Physically consistent: every sensor measures
    what it can.
  * "z": the axis along z_b (normal to the body). The circle gives roll and pitch, and
    the single-axis sensor must give the heading (a gyro or compass: an inclinometer
    cannot). Kept as an option.

Frames: world (TS) frame, z up; body frame Sigma_b (x forward, y left, z up). The body
attitude is R = Rz(yaw) Ry(pitch) Rx(roll) (`geometry.rpy_to_matrix`; `Pose.euler` lists
(yaw, pitch, roll), rad); positions in m.
The measured points are in time order and the mechanism turns positively (right hand)
about its axis, which fixes the axis' sign; the three points must span less than a
full turn.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from jaxloco import geometry as geo

Array = jax.Array

MOUNTS = ("x", "z")


class Circle(NamedTuple):
    """A circle in space: centre (3,), unit axis (3,) and radius () [m]."""

    centre: Array
    axis: Array
    radius: Array


class Pose(NamedTuple):
    """Body pose in the world frame: origin (3,) [m], attitude R (3, 3) and its ZYX Euler
    angles (yaw, pitch, roll) (3,) [rad]."""

    position: Array
    rotation: Array
    euler: Array


def circle_through(p1: Array, p2: Array, p3: Array) -> Circle:
    """The circle through three points (3,) measured in this order on a mechanism turning
    positively about its axis: the circumcentre in their plane, the unit axis
    (p2 - p1) x (p3 - p2) normalised, the radius."""
    a, b = p1 - p3, p2 - p3
    axb = jnp.cross(a, b)
    n2 = jnp.dot(axb, axb)
    centre = p3 + jnp.cross(jnp.dot(a, a) * b - jnp.dot(b, b) * a, axb) / (2.0 * n2)
    turn = jnp.cross(p2 - p1, p3 - p2)
    axis = turn / jnp.linalg.norm(turn)
    return Circle(centre, axis, jnp.linalg.norm(p1 - centre))


def attitude_from_axis(axis: Array, angle: Array, mount: str = "x") -> Array:
    """ZYX Euler angles (yaw, pitch, roll) (3,) from the world direction `axis` of the
    mechanism's body-fixed rotation axis and the single-axis sensor's `angle` [rad]:
    mount "x": axis = x_b, angle = roll (inclinometer); mount "z": axis = z_b,
    angle = yaw (heading sensor)."""
    if mount == "x":
        yaw = jnp.arctan2(axis[1], axis[0])
        pitch = jnp.arctan2(-axis[2], jnp.hypot(axis[0], axis[1]))
        return jnp.stack([yaw, pitch, angle])
    if mount == "z":
        c, s = jnp.cos(angle), jnp.sin(angle)
        v = jnp.stack([c * axis[0] + s * axis[1], -s * axis[0] + c * axis[1], axis[2]])  # Rz(-yaw) axis
        roll = -jnp.arcsin(jnp.clip(v[1], -1.0, 1.0))
        pitch = jnp.arctan2(v[0], v[2])
        return jnp.stack([angle, pitch, roll])
    raise ValueError(f"mount must be one of {MOUNTS}, got {mount!r}")


def mount_axis(mount: str) -> Array:
    """The mechanism's rotation axis in Sigma_b for a mount reading."""
    if mount not in MOUNTS:
        raise ValueError(f"mount must be one of {MOUNTS}, got {mount!r}")
    return jnp.eye(3)[0 if mount == "x" else 2]


def localize(points: Array, angle: Array, centre_b: Array, mount: str = "x") -> Pose:
    """The body pose from the three TS points (3, 3) (time order, world frame [m]), the
    single-axis sensor's angle [rad] and the rotation centre of the mechanism in Sigma_b
    `centre_b` (3,) [m]: origin = centre - R centre_b."""
    circle = circle_through(points[0], points[1], points[2])
    euler = attitude_from_axis(circle.axis, angle, mount)
    R = geo.rpy_to_matrix(euler[2], euler[1], euler[0])
    return Pose(circle.centre - R @ centre_b, R, euler)


def cube_points(position: Array, rotation: Array, centre_b: Array, radius: Array, phases: Array,
                mount: str = "x") -> Array:
    """Where the corner cube is (world frame, (K, 3)) at the mechanism angles `phases` (K,)
    [rad] for the body pose (position (3,), rotation (3, 3)): the forward model that
    `localize` inverts (and the tests' oracle)."""
    u = mount_axis(mount)
    e1 = jnp.eye(3)[2] if mount == "x" else jnp.eye(3)[0]  # a body direction normal to u
    e2 = jnp.cross(u, e1)
    local = centre_b[None] + radius * (jnp.cos(phases)[:, None] * e1[None] + jnp.sin(phases)[:, None] * e2[None])
    return position[None] + local @ rotation.T
