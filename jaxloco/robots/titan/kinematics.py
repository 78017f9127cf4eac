"""TITAN XI leg geometry and kinematics (pure JAX), shared by the MJCF model and the
footstep executor.

The paper (Hodoshima et al., JRM 19(1), 2007) gives only the envelope (Table 1: 4.8 x
5.0 x 3.0 m, leg length 3.7 m, 7,000 kg), "legs have 3 DOF driven by hydraulic
cylinders" and a fan-shaped reachable area "due to rotation around a pivot" (Fig. 3:
R_in, R_out, R_theta). The planar layout (pivots, neutral feet, the fan, H_g, foot
radius) is the gait planner's, imported from `params.py` so that the planner's
footholds are reachable by the simulated legs; what only the model needs is chosen here:

Body frame Sigma_b (the `body` of the model, origin at the trunk's centre of mass, x
forward, y left, z up). Leg i (0 LF "fl", 1 RF "fr", 2 LR "rl", 3 RR "rr", the order of
`params.LEG_NAMES`) has:
  * a vertical pivot (hip yaw q0) at params.PIVOTS[i] = (+-1.1, +-1.2, 0) m; q0 = 0
    points the vertical leg plane along the fan's centre line, azimuth YAW0[i] =
    params.LEG_AXIS_ANGLES[i] (+-45 deg / +-135 deg, outward on the diagonals); q0 > 0
    turns it counter-clockwise seen from above;
  * in that plane (x_l outward, z up) a hip pitch joint q1 on the pivot axis and a knee
    q2, both about +y_l, so positive angles turn links downwards; thigh L1 = 1.6 m and
    shank L2 = 2.1 m (L1 + L2 = 3.7 m, Table 1 "leg length"); the foot is a contact sphere
    of radius FOOT_RADIUS (0.04 m; the pad's radius is params.FOOT_RADIUS, see
    `model`) centred at the shank end:
        r = L1 cos q1 + L2 cos(q1 + q2),   z = -L1 sin q1 - L2 sin(q1 + q2)
    with the knee above the pivot-foot line (q2 > 0, "knee up", as on large sprawled
    walking machines);
  * reachable area (Fig. 3): the annular sector about the pivot with radii R_IN..R_OUT
    (0.6..2.3 m, horizontal distance pivot - foot centre) and opening R_THETA (90 deg)
    centred on YAW0[i]. At the home height the two links reach all of it (distance
    pivot - foot centre 1.48..2.67 m, within |L2 - L1| = 0.5 .. 3.7 m).

Home pose (keyframe `home`): body origin HOME_HEIGHT = params.H_G = 1.5 m above flat
ground, feet under params.NEUTRAL_FEET (+-2.1, +-2.2) m; the knees are then right above
the feet (vertical shanks), 2.35 m above the ground.
"""

from __future__ import annotations

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco.robots.titan import params

Array = jax.Array

LEG_NAMES = ("fl", "fr", "rl", "rr")  # = params.LEG_NAMES ("LF", "RF", "LR", "RR")
JOINT_NAMES = ("yaw", "pitch", "knee")
PIVOTS = np.asarray(params.PIVOTS, float)  # (4, 3) [m] in Sigma_b
YAW0 = np.asarray(
    params.LEG_AXIS_ANGLES, float
)  # (4,) [rad] azimuth of the leg plane at q0 = 0
L1, L2 = 1.6, 2.1  # [m] thigh, shank
FOOT_RADIUS = 0.04  # [m] contact sphere of the foot (the pad's radius is P.FOOT_RADIUS)
R_IN, R_OUT, R_THETA = float(params.R_IN), float(params.R_OUT), float(params.R_THETA)  # Fig. 3
HOME_HEIGHT = float(params.H_G)  # [m] body origin above flat ground in the home pose (H_g)

# masses [kg] (ours; Table 1 gives 7,000 kg in all): `model` builds the MJCF from these and
# `com_offset` puts the centre of mass where the MJCF has it
TRUNK_MASS = 4800.0  # box centred on the body origin
TOWER_MASS = 100.0  # per leg: a vertical cylinder on the pivot, centre TOWER_Z
TOWER_Z = 0.55  # [m] centre height of a tower in Sigma_b (model: from the trunk's bottom, -0.4 m, to 1.5 m)
HUB_MASS, THIGH_MASS, SHANK_MASS, FOOT_MASS = 50.0, 200.0, 150.0, 50.0
SHANK_END_GAP = 0.2  # [m] the shank's capsule stops this short of the foot


def home_feet() -> np.ndarray:
    """Foot centres (4, 3) in Sigma_b of the home pose on flat ground."""
    out = np.asarray(params.NEUTRAL_FEET, float).copy()
    out[:, 2] = FOOT_RADIUS - HOME_HEIGHT
    return out


def _planar(q1: Array, q2: Array) -> tuple[Array, Array]:
    r = L1 * jnp.cos(q1) + L2 * jnp.cos(q1 + q2)
    z = -L1 * jnp.sin(q1) - L2 * jnp.sin(q1 + q2)
    return r, z


def foot_position(leg: int | Array, q: Array) -> Array:
    """Foot centre (3,) in Sigma_b of leg `leg` (0..3) at joint angles q (3,) [rad]."""
    pivots = jnp.asarray(PIVOTS, q.dtype)
    yaw0 = jnp.asarray(YAW0, q.dtype)
    r, z = _planar(q[1], q[2])
    psi = yaw0[leg] + q[0]
    return pivots[leg] + jnp.stack([r * jnp.cos(psi), r * jnp.sin(psi), z])


def feet_positions(q: Array) -> Array:
    """Foot centres (4, 3) in Sigma_b for joint angles q (4, 3) or (12,)."""
    q = jnp.reshape(q, (4, 3))
    return jax.vmap(foot_position)(jnp.arange(4), q)


def knee_position(leg: int | Array, q: Array) -> Array:
    """Knee (thigh end) (3,) in Sigma_b."""
    pivots = jnp.asarray(PIVOTS, q.dtype)
    psi = jnp.asarray(YAW0, q.dtype)[leg] + q[0]
    r, z = L1 * jnp.cos(q[1]), -L1 * jnp.sin(q[1])
    return pivots[leg] + jnp.stack([r * jnp.cos(psi), r * jnp.sin(psi), z])


def inverse_kinematics(leg: int | Array, foot: Array) -> tuple[Array, Array]:
    """Joint angles (3,) [rad] placing the foot centre of leg `leg` at `foot` (3,) in
    Sigma_b (knee-up branch), and a reach value (> 0 when the target is reachable by the
    two links; targets out of reach are clipped onto the workspace boundary). Closed
    form, differentiable away from the singular extended / folded poses."""
    dtype = jnp.result_type(foot, float)
    foot = jnp.asarray(foot, dtype)
    d = foot - jnp.asarray(PIVOTS, dtype)[leg]
    psi = jnp.arctan2(d[1], d[0])
    q0 = _wrap(psi - jnp.asarray(YAW0, dtype)[leg])
    r = jnp.sqrt(d[0] ** 2 + d[1] ** 2)
    dist2 = r * r + d[2] * d[2]
    c2 = (dist2 - L1**2 - L2**2) / (2 * L1 * L2)
    reach = 1.0 - jnp.abs(c2)
    eps = 1e-9
    q2 = jnp.arccos(jnp.clip(c2, -1.0 + eps, 1.0 - eps))
    beta = jnp.arctan2(-d[2], r)  # depression of the pivot-foot line
    gamma = jnp.arctan2(L2 * jnp.sin(q2), L1 + L2 * jnp.cos(q2))
    return jnp.stack([q0, beta - gamma, q2]), reach


def legs_inverse_kinematics(feet: Array) -> tuple[Array, Array]:
    """`inverse_kinematics` of all four legs: feet (4, 3) in Sigma_b -> q (4, 3), reach (4,)."""
    return jax.vmap(inverse_kinematics)(jnp.arange(4), feet)


def in_reach_area(leg: int | Array, foot: Array) -> Array:
    """Whether the foot centre `foot` (3,) in Sigma_b lies in the fan of leg `leg`
    (R_IN <= horizontal distance to the pivot <= R_OUT, |azimuth - YAW0| <= R_THETA / 2)."""
    d = foot - jnp.asarray(PIVOTS, foot.dtype)[leg]
    r = jnp.sqrt(d[0] ** 2 + d[1] ** 2)
    ang = _wrap(jnp.arctan2(d[1], d[0]) - jnp.asarray(YAW0, foot.dtype)[leg])
    return (r >= R_IN) & (r <= R_OUT) & (jnp.abs(ang) <= 0.5 * R_THETA)


def leg_mass_moment(leg: int | Array, foot: Array) -> Array:
    """Sum of mass x centre of mass [kg m] (3,) in Sigma_b of the links of leg `leg` (hub
    on the pivot, thigh pivot-knee, shank capsule from the knee to SHANK_END_GAP short of
    the foot, foot sphere) with its foot centre at `foot` (3,) in Sigma_b (knee up)."""
    q, _ = inverse_kinematics(leg, foot)
    pivot = jnp.asarray(PIVOTS, q.dtype)[leg]
    knee = knee_position(leg, q)
    tip = foot_position(leg, q)  # = foot where reachable
    shank_c = knee + (tip - knee) * (0.5 * (L2 - SHANK_END_GAP) / L2)
    return (HUB_MASS * pivot + THIGH_MASS * 0.5 * (pivot + knee) + SHANK_MASS * shank_c
            + FOOT_MASS * tip)


def total_mass() -> float:
    """The robot's mass [kg]: trunk, four towers, four legs (7,000 kg, Table 1)."""
    return TRUNK_MASS + 4 * (TOWER_MASS + HUB_MASS + THIGH_MASS + SHANK_MASS + FOOT_MASS)


def com_offset(feet: Array) -> Array:
    """Whole-robot centre of mass (3,) [m] in Sigma_b (relative to the body origin, the
    trunk's centre) with the foot centres at `feet` (4, 3) in Sigma_b: the legs' 400 kg of
    moving links each shift it by up to a few cm as their feet move."""
    dtype = jnp.result_type(feet, float)
    towers = jnp.asarray(PIVOTS, dtype).at[:, 2].set(TOWER_Z)
    legs = jax.vmap(leg_mass_moment)(jnp.arange(4), jnp.asarray(feet, dtype))
    return (jnp.sum(legs, axis=0) + TOWER_MASS * jnp.sum(towers, axis=0)) / total_mass()


def _wrap(a: Array) -> Array:
    return jnp.arctan2(jnp.sin(a), jnp.cos(a))


def home_joint_angles() -> np.ndarray:
    """Joint angles (4, 3) [rad] of the home pose (NumPy, same formulas as
    `inverse_kinematics`)."""
    out = np.zeros((4, 3))
    for i, foot in enumerate(home_feet()):
        d = foot - PIVOTS[i]
        r = math.hypot(d[0], d[1])
        q0 = math.atan2(d[1], d[0]) - YAW0[i]
        c2 = (r * r + d[2] ** 2 - L1**2 - L2**2) / (2 * L1 * L2)
        q2 = math.acos(c2)
        q1 = math.atan2(-d[2], r) - math.atan2(
            L2 * math.sin(q2), L1 + L2 * math.cos(q2)
        )
        out[i] = [math.atan2(math.sin(q0), math.cos(q0)), q1, q2]
    return np.round(out, 9)


@functools.cache
def swing_com_height(lift: float = float(params.SWING_HEIGHT)) -> float:
    """Height [m] along z_b of the whole-robot centre of mass above the body origin while
    a leg swings: the home stance with one foot raised by `lift`, the largest over the
    legs (2.1 cm at the executor's 0.5 m lift; at the body origin in the home stance)."""
    raised = np.repeat(np.asarray(home_feet(), float)[None], 4, axis=0)
    raised[np.arange(4), np.arange(4), 2] += lift  # leg k raised in stance k
    # a constant, also when first called inside a jit: one program compiled ahead of time
    # and run (a plain jit under `jax.ensure_compile_time_eval` ran op by op: ~50 compilations)
    program = jax.jit(jax.vmap(com_offset)).lower(raised).compile()
    with jax.ensure_compile_time_eval():
        return float(np.max(np.asarray(program(raised))[:, 2]))
