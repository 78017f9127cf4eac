"""Leg kinematics of the leg-grope quadruped: a yaw joint (i1) then two pitch joints
(i2, i3) per leg, links of lengths l1, l2, l3 (Table 1).

Frame: all positions are in the robot frame Sigma_R [m]; joint angles q = (theta_i1,
theta_i2, theta_i3) [rad]. theta_i1 rotates the leg about z_R from its mount direction
(`LegGropeParams.mount_angles`); theta_i2 > 0 lifts the thigh; theta_i3 is the knee,
negative in the usual "knee-up" stance. The leg is singular at theta_i3 = n pi, as the
paper states.

D-H parameters of leg i (standard convention, base frame at the hip rotated by the
mount angle about z_R):
    joint 1: theta = theta_i1, d = 0, a = l1, alpha = +pi/2
    joint 2: theta = theta_i2, d = 0, a = l2, alpha = 0
    joint 3: theta = theta_i3, d = 0, a = l3, alpha = 0
`foot_position` is the closed form; `foot_position_dh` evaluates the D-H chain; the two
Jacobians (closed form, autodiff) are tested against each other and against MuJoCo.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxloco import geometry as geo
from jaxloco.robots.leggrope.params import LegGropeParams

Array = jax.Array


def _planar(q: Array, lengths: Array) -> tuple[Array, Array]:
    """Radial distance rho from the yaw axis and height zeta of the foot above the hip."""
    l1, l2, l3 = lengths[0], lengths[1], lengths[2]
    rho = l1 + l2 * jnp.cos(q[1]) + l3 * jnp.cos(q[1] + q[2])
    zeta = l2 * jnp.sin(q[1]) + l3 * jnp.sin(q[1] + q[2])
    return rho, zeta


def foot_position(params: LegGropeParams, leg: int | Array, q: Array) -> Array:
    """Toe position of `leg` (0..3) in Sigma_R for joint angles q (3,)."""
    hip = params.hips()[leg]
    yaw = params.mount_angles()[leg] + q[0]
    rho, zeta = _planar(q, jnp.asarray(params.link_lengths))
    return hip + jnp.stack([rho * jnp.cos(yaw), rho * jnp.sin(yaw), zeta])


def leg_base_transform(params: LegGropeParams, leg: int | Array) -> Array:
    """4x4 transform of the leg's D-H base frame in Sigma_R."""
    return geo.make_transform(geo.rot_z(params.mount_angles()[leg]), params.hips()[leg])


def leg_frames_dh(params: LegGropeParams, leg: int | Array, q: Array) -> Array:
    """The four D-H frames (hip, after joint 1, 2, 3 = toe) of a leg in Sigma_R, (4, 4, 4)."""
    lengths = jnp.asarray(params.link_lengths, q.dtype)
    alpha = jnp.array([0.5 * jnp.pi, 0.0, 0.0], q.dtype)
    return geo.dh_chain(q, jnp.zeros(3, q.dtype), lengths, alpha, base=leg_base_transform(params, leg))


def foot_position_dh(params: LegGropeParams, leg: int | Array, q: Array) -> Array:
    """Toe position from the D-H chain (equals `foot_position`)."""
    return leg_frames_dh(params, leg, q)[-1, :3, 3]


def foot_jacobian(params: LegGropeParams, leg: int | Array, q: Array) -> Array:
    """Closed-form Jacobian d(toe position in Sigma_R)/dq, (3, 3)."""
    lengths = jnp.asarray(params.link_lengths)
    l2, l3 = lengths[1], lengths[2]
    yaw = params.mount_angles()[leg] + q[0]
    c, s = jnp.cos(yaw), jnp.sin(yaw)
    rho, zeta = _planar(q, lengths)
    c2, c23, s23 = jnp.cos(q[1]), jnp.cos(q[1] + q[2]), jnp.sin(q[1] + q[2])
    zero = jnp.zeros_like(rho)
    d_rho = jnp.stack([zero, -zeta, -l3 * s23])  # d rho / dq
    d_zeta = jnp.stack([zero, l2 * c2 + l3 * c23, l3 * c23])  # d zeta / dq
    d_yaw = jnp.stack([jnp.ones_like(rho), zero, zero])
    row_x = d_rho * c - rho * s * d_yaw
    row_y = d_rho * s + rho * c * d_yaw
    return jnp.stack([row_x, row_y, d_zeta])


def foot_jacobian_autodiff(params: LegGropeParams, leg: int | Array, q: Array) -> Array:
    """Jacobian of `foot_position_dh` by forward-mode autodiff."""
    return jax.jacfwd(lambda qq: foot_position_dh(params, leg, qq))(q)


def link_com_positions(params: LegGropeParams, leg: int | Array, q: Array) -> Array:
    """Midpoints of links i1, i2, i3 (uniform rods) in Sigma_R, (3, 3)."""
    lengths = jnp.asarray(params.link_lengths, q.dtype)
    l1, l2, l3 = lengths[0], lengths[1], lengths[2]
    hip = params.hips()[leg]
    yaw = params.mount_angles()[leg] + q[0]
    radial = jnp.stack([jnp.cos(yaw), jnp.sin(yaw), jnp.zeros_like(yaw)])
    up = jnp.array([0.0, 0.0, 1.0], q.dtype)
    knee1 = hip + l1 * radial
    knee2 = knee1 + l2 * (jnp.cos(q[1]) * radial + jnp.sin(q[1]) * up)
    toe = knee2 + l3 * (jnp.cos(q[1] + q[2]) * radial + jnp.sin(q[1] + q[2]) * up)
    return jnp.stack([0.5 * (hip + knee1), 0.5 * (knee1 + knee2), 0.5 * (knee2 + toe)])


def inverse_kinematics(params: LegGropeParams, leg: int | Array, toe: Array) -> tuple[Array, Array]:
    """Joint angles putting the toe of `leg` at `toe` (Sigma_R), knee-up branch
    (theta_i3 < 0). Returns (q, reach_margin): reach_margin [m] is the distance of the
    hip-2-to-toe length from the nearest limit of the 2-link annulus [|l2-l3|, l2+l3]
    and the radial clearance from the yaw axis; negative means unreachable (q is then
    the clipped, nearest configuration and stays finite)."""
    lengths = jnp.asarray(params.link_lengths, toe.dtype)
    l1, l2, l3 = lengths[0], lengths[1], lengths[2]
    rel = toe - params.hips()[leg]
    yaw = jnp.arctan2(rel[1], rel[0])
    q1 = _wrap(yaw - params.mount_angles()[leg])
    r = jnp.sqrt(rel[0] ** 2 + rel[1] ** 2) - l1
    z = rel[2]
    dist = jnp.sqrt(r * r + z * z)
    reach = jnp.minimum(l2 + l3 - dist, dist - jnp.abs(l2 - l3))
    cos3 = jnp.clip((dist * dist - l2 * l2 - l3 * l3) / (2 * l2 * l3), -1.0 + 1e-12, 1.0 - 1e-12)
    q3 = -jnp.arccos(cos3)
    q2 = jnp.arctan2(z, r) - jnp.arctan2(l3 * jnp.sin(q3), l2 + l3 * jnp.cos(q3))
    return jnp.stack([q1, q2, q3]), jnp.minimum(reach, r + l1)


def _wrap(a: Array) -> Array:
    return jnp.arctan2(jnp.sin(a), jnp.cos(a))
