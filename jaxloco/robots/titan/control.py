"""TITAN XI's quasi-static footstep executor (Sections 6.4, 7, 8.3, 8.4): the controller of
`scenarios.make_scenario`, pure JAX, one simulation, fixed shapes (the rollout vmaps it).

A plan's step k runs from settle_time + k step_time for `step_time` seconds (the
params entries of `scenarios.PARAM_DEFAULTS` and `scenarios.Plan.params`):
  * body shift (swing -1): the body target moves along the straight line from the
    previous body position to body[k] (smoothstep in time), all four feet held at their
    world positions;
  * swing of leg u (Sec. 6.4.1, rectangular trajectory, body still): the foot centre
    rises along the body z axis (the virtual contact plane's normal) to `swing_height`
    above the higher of its start and target, moves parallel to the plane above the
    target, then descends to the target and PRESS below it; as soon as its touch sensor
    reads more than `contact_force` (fraction of M g) in the descent, the foot target
    stops there ("lower until contact", the unevenness-absorbing gait of Fig. 6);
  * at the start of each step the targets of the feet in contact are re-referenced to
    where they stand (`anchor_to_feet`: each foot's offset along the normal, the common
    slip in the plane), the body correction shifted to match;
  * the swing target is offset by the mean in-plane deviation of the supporting feet
    from their targets (slip, the body correction below), so that the foot lands at
    its planned world position;
  * joint targets: `kinematics.legs_inverse_kinematics` of the foot targets in the
    commanded body frame, with the body placed where the whole-robot centre of mass
    (the legs' mass included, `body_for_com`) is at its target, plus a correction `corr`
    that integrates the error of the whole-robot centre of mass (in the plane) and of
    the body origin (along the normal) against the planned body position (gain
    `body_gain` [1/s], at most MAX_CORR per axis), and the commanded attitude turned by
    a small rotation `corr_rot` integrating the body attitude error (same gain, at most
    MAX_CORR_ROT per axis); see `executor_step`.

Frames: world, z up; the body attitude is the slope plane's (z_b along its normal)
turned by `heading` about it (`body_quat`). Units SI, radians.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco import geometry as geo
from jaxloco import linalg
from jaxloco import stability as stab
from jaxloco.robots.titan import kinematics
from jaxloco.robots.titan import model as titan_model
from jaxloco.sim import terrain as tr
from jaxloco.sim.scenario import Controller

Array = jax.Array

CONTROL_DT = 0.04  # [s]
PRESS = 0.03  # [m] the descent goes this far below the target if no contact comes first
MAX_CORR = 0.2  # [m] largest body position correction per axis
MAX_CORR_ROT = 0.1  # [rad] largest body attitude correction per axis
SWING_RISE = 0.25  # fraction of a swing spent rising (and descending); the rest moves across
UNLOAD = 0.1  # fraction of a step spent moving the load between the legs (the swing foot rises after it)
# servo lag kv / kp [s] per joint (12,): the planned speed is fed forward through it
SERVO_LAG = np.tile(np.asarray(titan_model.KV) / np.asarray(titan_model.KP), 4)
SERVO_COMPLIANCE = np.tile(1.0 / np.asarray(titan_model.KP), 4)  # [rad / (N m)] per joint (12,)


class ExecutorState(NamedTuple):
    """The executor's state (world frame, metres, radians)."""

    k: Array  # () int: the step running (-1 before the plan, n_steps after it)
    feet: Array  # (4, 3) foot centre targets at the start of step k
    body: Array  # (3,) body target at the start of step k
    feet_end: Array  # (4, 3) foot centre targets where step k ends
    body_end: Array  # (3,) body target where step k ends
    latched: Array  # () bool: the swing foot touched down in this step
    hold: Array  # (3,) where the swing foot touched down
    corr: Array  # (3,) body position correction
    corr_rot: Array  # (3,) body attitude correction (small world-frame rotation)
    target: Array  # (3,) the whole-robot COG target for the next control period (the plan's, support_shift added)


class StepTargets(NamedTuple):
    """What the executor commands at one instant (`step_targets`)."""

    k: Array  # () step index
    swing: Array  # () swing leg (-1: a body shift or no step)
    feet: Array  # (4, 3) foot centre targets
    body: Array  # (3,) body target
    descending: Array  # () bool: the swing foot is in its descent
    phase: Array  # () fraction of the step elapsed (1 outside the plan)


def body_quat(theta: Array, direction: Array, heading: Array) -> Array:
    """Commanded body attitude (w, x, y, z): z_b along the plane normal, yawed by `heading`."""
    n = tr.slope_normal(theta, direction)
    return tr.quat_mul(tr.quat_tilt(n), tr.quat_z(heading))


def frames(p) -> tuple[Array, Array]:
    """The slope normal (3,) and the commanded body rotation matrix (3, 3) of params p."""
    n = tr.slope_normal(p["theta"], p["direction"])
    return n, tr.quat_to_matrix(body_quat(p["theta"], p["direction"], p["heading"]))


def tether_force(p, weight: float) -> Array:
    """The tethers' force (3,) [N]: `tether` M g sin(theta) up the fall line."""
    uphill, _ = tr.slope_axes(p["theta"], p["direction"])
    return p["tether"] * weight * jnp.sin(p["theta"]) * uphill


def leg_targets(p, feet_c: Array, body_c: Array, rot: Array | None = None) -> Array:
    """Joint targets (12,) for foot centres feet_c (4, 3), body position body_c and the
    commanded attitude turned by the small world-frame rotation `rot` (3,)."""
    _, R = frames(p)
    if rot is not None:
        R = geo.rpy_to_matrix(rot[0], rot[1], rot[2]) @ R
    q, _ = kinematics.legs_inverse_kinematics((feet_c - body_c[None]) @ R)
    return q.reshape(-1)


def body_for_com(p, feet_c: Array, com: Array) -> Array:
    """Body origin (3,) [m, world] that puts the whole-robot centre of mass at `com` in the
    slope plane (the normal component is the body origin's own), with the foot centres at
    `feet_c` (4, 3, world) and the commanded attitude: com - the in-plane part of
    `kinematics.com_offset` (the legs' mass), scaled by p["mass_feedforward"] (0: the body
    is placed at `com`). Two fixed-point passes (the offset moves by ~6 % of the body)."""
    n, R = frames(p)
    body = com
    for _ in range(2):
        off = R @ kinematics.com_offset((feet_c - body[None]) @ R)
        body = com - p["mass_feedforward"] * (off - (off @ n) * n)
    return body


def smooth(s: Array) -> Array:
    """Smoothstep of s clipped to [0, 1]."""
    s = jnp.clip(s, 0.0, 1.0)
    return s * s * (3.0 - 2.0 * s)


def end_time(p, n_steps: int) -> Array:
    """When the plan's last step ends [s]."""
    return p["settle_time"] + n_steps * p["step_time"]


def executor_init(p, obs) -> ExecutorState:
    """The state before the first step: the plan's start, no correction."""
    n, _ = frames(p)
    feet = p["plan_feet0"] + kinematics.FOOT_RADIUS * n
    body = p["plan_body0"]
    zero = jnp.zeros(3, feet.dtype)
    return ExecutorState(k=jnp.asarray(-1, jnp.int32), feet=feet, body=body, feet_end=feet, body_end=body,
                         latched=jnp.asarray(False), hold=zero, corr=zero, corr_rot=zero, target=body)


def step_targets(p, n_steps: int, weight: float, c: ExecutorState, obs) -> tuple[StepTargets, ExecutorState]:
    """The commanded step, swing leg, foot centre and body targets at obs["time"], and the
    state with the step's bookkeeping updated (the corrections unchanged)."""
    n, _ = frames(p)
    t = obs["time"] - p["settle_time"]
    k_raw = jnp.floor(t / p["step_time"]).astype(jnp.int32)
    k = step_index(p, n_steps, obs["time"])
    phase = jnp.where((k_raw >= 0) & (k_raw < n_steps), t / p["step_time"] - k_raw, 1.0)
    # a new step: bank the previous one (its final targets become the start)
    new = k != c.k
    feet_prev = jnp.where(new, c.feet_end, c.feet)
    body_prev = jnp.where(new, c.body_end, c.body)
    latched = jnp.where(new, False, c.latched)
    hold = jnp.where(new, c.hold * 0.0, c.hold)
    kk = jnp.clip(k, 0, n_steps - 1)
    active = (k >= 0) & (k < n_steps)
    u = jnp.where(active, p["plan_swing"][kk], -1)
    body_goal = jnp.where(active & (u < 0), p["plan_body"][kk], body_prev)
    body_t = body_prev + (body_goal - body_prev) * smooth(phase)
    # swing foot (rectangular trajectory along n)
    uu = jnp.maximum(u, 0)
    start = feet_prev[uu]
    # where the supporting feet really are against their targets (in the plane): the
    # offset of the commanded frame from the world (foot slip, the body correction); the
    # swing foot aims off by the same so that it lands at its planned world position
    support = (jnp.arange(4) != u)[:, None]
    drift = jnp.sum(jnp.where(support, obs["feet"] - feet_prev, 0.0), axis=0) / jnp.sum(support)
    drift = drift - (drift @ n) * n
    goal = p["plan_feet"][kk, uu] + kinematics.FOOT_RADIUS * n - drift
    top = jnp.maximum(
        jnp.maximum(start @ n, goal @ n) + p["swing_height"], p["plan_swing_top"][kk] + kinematics.FOOT_RADIUS
    )
    start_top = start + (top - start @ n) * n
    goal_top = goal + (top - goal @ n) * n
    bottom = goal - PRESS * n
    a = SWING_RISE
    up = start + (start_top - start) * smooth((phase - UNLOAD) / (a - UNLOAD))
    across = start_top + (goal_top - start_top) * smooth((phase - a) / (1 - 2 * a))
    down = goal_top + (bottom - goal_top) * smooth((phase - (1 - a)) / a)
    descending = (u >= 0) & (phase >= 1 - a)
    foot = jnp.where(phase < a, up, jnp.where(phase < 1 - a, across, down))
    touched = obs["touch"][uu] > p["contact_force"] * weight
    first = descending & touched & ~latched
    hold = jnp.where(first, foot, hold)
    latched = latched | first
    foot = jnp.where(latched, hold, foot)
    swinging = (jnp.arange(4) == u)[:, None]
    feet_t = jnp.where(swinging, foot[None], feet_prev)
    feet_end = jnp.where(swinging, jnp.where(latched, hold, bottom)[None], feet_prev)  # where this step ends
    state = c._replace(k=k, feet=feet_prev, body=body_prev, feet_end=feet_end, body_end=body_goal, latched=latched,
                       hold=hold)
    return StepTargets(k, u, feet_t, body_t, descending, phase), state


def attitude_error(R_plan: Array, quat: Array) -> Array:
    """The small world-frame rotation (3,) from the measured attitude `quat` to R_plan."""
    M = R_plan @ tr.quat_to_matrix(quat).T
    return 0.5 * jnp.array([M[2, 1] - M[1, 2], M[0, 2] - M[2, 0], M[1, 0] - M[0, 1]])


def step_index(p, n_steps: int, time: Array) -> Array:
    """The plan step running at `time` [s] (-1 before the plan, n_steps after it)."""
    k_raw = jnp.floor((time - p["settle_time"]) / p["step_time"]).astype(jnp.int32)
    return jnp.clip(k_raw, -1, n_steps)


def anchor_to_feet(p, n_steps: int, weight: float, c: ExecutorState, obs) -> ExecutorState:
    """At the start of a step, the targets of the feet in contact re-referenced to where
    they stand (p["anchor_feet"] 1: fully, 0: never): along the normal each foot's own
    offset, in the plane the feet's common (mean) slip; the body correction moves by the
    mean shift, so that the commanded body does not jump.

    Why: the executor commands the legs from world foot targets. Without re-referencing,
    (a) along the normal each touchdown latches a target off by the servos' sag (before
    the load feedforward a foot latched where it touched carried 0.3 % of the weight
    after one cycle and each lift-off of a loaded leg ratcheted the correction up by the
    sag); (b) in the plane the supporting feet's common slip (1-2 cm per step,
    the four-legged closed chain on compliant servos) stays in the targets, the swing
    aims off by it (`step_targets`) and the correction holds it. Over the Sec. 8.3 field
    both grew until the correction saturated at MAX_CORR (the body 0.22 m low, the feet
    off by 0.2 m after ~8 cycles, then a foot on a frame). Per-foot differences in the
    plane are left alone: they are mostly the legs' elastic splay under load (resetting
    them made a standing robot's feet shuffle 7 cm in 20 s), and each foot is placed
    afresh by its own swing every cycle."""
    n, _ = frames(p)
    new = step_index(p, n_steps, obs["time"]) != c.k
    contact = obs["touch"] > p["contact_force"] * weight
    use = (p["anchor_feet"] * jnp.where(new & contact, 1.0, 0.0))[:, None]
    dev = use * (obs["feet"] - c.feet_end)
    along = (dev @ n)[:, None] * n[None]  # per foot: each leg's compression
    mean_plane = jnp.sum(dev - along, axis=0) / jnp.maximum(jnp.sum(use), 1e-9)  # the common slip
    shift = use * (along + mean_plane[None])
    return c._replace(feet=c.feet + shift, feet_end=c.feet_end + shift,
                      corr=c.corr + jnp.sum(shift, axis=0) / jnp.maximum(jnp.sum(use), 1e-9))


def load_shares(com: Array, feet: Array, support: Array, up: Array) -> Array:
    """Static load shares (4,) of the feet (sum 1, 0 off the support): the minimum-norm
    weights w >= 0 with sum w_i (feet_i - com) = 0 in the plane normal to `up` (the
    direction against gravity plus tethers), so that the support forces w_i |g_eff| up
    carry the robot without a moment about its centre of mass. Three feet: the unique
    (barycentric) shares; four: the least-squares spread of the indeterminate stance."""
    a = jnp.array([1.0, 0.0, 0.0], feet.dtype)
    e1 = a - (a @ up) * up
    e1 = e1 / jnp.linalg.norm(e1)
    e2 = jnp.cross(up, e1)
    m = support.astype(feet.dtype)
    rel = feet - com[None]
    A = jnp.stack([jnp.ones(4, feet.dtype), rel @ e1, rel @ e2]) * m[None]
    w = A.T @ linalg.spd_solve(A @ A.T, jnp.array([1.0, 0.0, 0.0], feet.dtype))
    w = jnp.maximum(w, 0.0) * m
    return w / jnp.sum(w)


def load_feedforward(p, weight: float, now: StepTargets, q: Array, rot: Array) -> Array:
    """Joint target offsets (12,) [rad] that pre-deflect the servos by the static loads:
    each foot's expected support force f_i = w_i |g_eff| up (`load_shares` of the
    commanded COG over the step's support) needs the actuator torques -J_i^T f_i (J_i:
    the foot's Jacobian in Sigma_b at the joint targets q), which the servos give at
    ctrl - q = KP^-1 (-J_i^T f_i). The shares blend from the previous step's support to
    this step's over the first UNLOAD of the step (the swing foot stays down until then),
    so the load moves to the three supporting legs before a foot rises and back after it
    lands. Why: the servos are compliant (~1 cm at the foot under a leg's share); when a
    leg lifted, the other three sagged and the body tipped towards the lifted corner,
    taking 1.5 cm off the COG's distance to the support edge (1-2 mm of NESM) until the
    integral correction caught up. p["load_feedforward"] scales it (0: off)."""
    n, R = frames(p)
    R = geo.rpy_to_matrix(rot[0], rot[1], rot[2]) @ R
    g_eff = jnp.array([0.0, 0.0, -weight], q.dtype) + tether_force(p, weight)
    up = -g_eff / jnp.linalg.norm(g_eff)
    k = now.k
    prev_swing = jnp.where(k >= 1, p["plan_swing"][jnp.clip(k - 1, 0, p["plan_swing"].shape[0] - 1)], -1)
    legs = jnp.arange(4)
    w_prev = load_shares(now.body, now.feet, legs != prev_swing, up)
    w_now = load_shares(now.body, now.feet, legs != now.swing, up)
    blend = smooth(now.phase / UNLOAD)
    w = w_prev + (w_now - w_prev) * blend
    forces = (w[:, None] * jnp.linalg.norm(g_eff) * up[None]) @ R  # (4, 3) in Sigma_b
    jac = jax.vmap(jax.jacfwd(kinematics.foot_position, argnums=1))(legs, q.reshape(4, 3))  # (4, 3, 3)
    tau = -jnp.einsum("lij,li->lj", jac, forces).reshape(-1)
    return p["load_feedforward"] * jnp.asarray(SERVO_COMPLIANCE, q.dtype) * tau


EDGE_TAU = 0.005  # [m] support edges with this much more NE margin than the smallest weigh 1/e as much
MEAN_SLIP_WEIGHT = 0.01  # weight of the supporting feet's mean slip (against 1 for the critical edge)


def support_shift(p, n_steps: int, now: StepTargets, obs) -> Array:
    """The in-plane shift (3,) [m] of the COG target that gives each edge of the support
    polygon the NE margin the plan gave it, now that the supporting feet stand where
    they are (times p["support_relative"]; 0: the COG target is the plan's, in the
    world). Linearised weighted least squares over the planned support's hull edges e:
    grad S'_e . shift = S_e - S'_e, with S_e the planned edge's energy margin, S'_e the
    margin about the axis through the measured feet (3D: their heights count) and its
    in-plane gradient, each row scaled to unit gradient and weighted by
    exp(-(S_e - min S) / EDGE_TAU), so that the edges that set the margin count most; plus
    shift = the supporting feet's mean slip with weight MEAN_SLIP_WEIGHT (it fixes the
    direction along a lone critical edge). A common slip of every foot in the plane
    gives shift = that slip.

    Why: the planner's NE margin is a property of the COG against the support, and the
    supporting feet slip 1-2 cm per step (the four-legged closed chain on compliant
    servos), not all alike, and on a surveyed map stand a few mm off the planned heights;
    a COG held in the world lost up to 4 mm of NESM on the long field, one moved by the
    feet's mean slip up to 1.4 mm, one that kept the planar edge distances 0.08 mm."""
    n, _ = frames(p)
    kk = jnp.clip(now.k, 0, n_steps - 1)
    planned = jnp.where(now.k >= 0, p["plan_feet"][kk], p["plan_feet0"])  # ground contacts
    actual = obs["feet"] - kinematics.FOOT_RADIUS * n
    support = jnp.arange(4) != now.swing
    g_eff = jnp.array([0.0, 0.0, -1.0], actual.dtype) + tether_force(p, 1.0)
    up = -g_eff / jnp.linalg.norm(g_eff)
    a = jnp.where(jnp.abs(n[0]) < 0.9, jnp.array([1.0, 0.0, 0.0]), jnp.array([0.0, 1.0, 0.0]))
    e1 = a - (a @ n) * n
    e1 = e1 / jnp.linalg.norm(e1)
    B = jnp.stack([e1, jnp.cross(n, e1)]).astype(actual.dtype)  # (2, 3) in-plane axes
    s_plan, E = stab.ne_edge_margins(now.body, planned, support, up)

    def margins(shift2):  # (value, value): jacfwd's aux gives the margins with their Jacobian
        s = stab.ne_edge_margins(now.body + shift2 @ B, actual, support, up)[0]
        return s, s

    s_min = jnp.min(jnp.where(E, s_plan, jnp.inf))
    sup = support[:, None].astype(actual.dtype)
    mean_slip = B @ (jnp.sum(sup * (actual - planned), axis=0) / jnp.sum(sup))
    shift2 = jnp.zeros(2, actual.dtype)
    for _ in range(2):  # Gauss-Newton: the margins are smooth, two steps reach ~1e-5 m
        grad, s_act = jax.jacfwd(margins, has_aux=True)(shift2)  # (4, 4, 2), (4, 4)
        norm = jnp.linalg.norm(grad, axis=-1)
        unit = grad / jnp.where(norm > 0, norm, 1.0)[..., None]
        gap = (s_plan - s_act) / jnp.where(norm > 0, norm, 1.0)
        w = jnp.where(E & (norm > 0), jnp.exp(-(s_plan - s_min) / EDGE_TAU), 0.0)
        M = jnp.einsum("ij,ijk,ijl->kl", w, unit, unit) + MEAN_SLIP_WEIGHT * jnp.eye(2, dtype=actual.dtype)
        rhs = jnp.einsum("ij,ij,ijk->k", w, gap, unit) + MEAN_SLIP_WEIGHT * (mean_slip - shift2)
        shift2 = shift2 + linalg.solve_2x2(M, rhs)
    return p["support_relative"] * (shift2 @ B)


def executor_step(p, n_steps: int, weight: float, c: ExecutorState, obs) -> tuple[ExecutorState, Array]:
    """One control period: the next state and the action (12 joint targets [rad], then the
    tether force (3,) [N]).

    Integral action: the legs' servo sag under load and the touchdown latches would
    otherwise add up over the plan, and the legs' mass (450 kg each) moves the centre of
    mass off the trunk's by up to ~7 cm; so the legs are commanded as if the body were at
    the target + corr, which drives the whole-robot centre of mass onto the planned COG
    in the plane and the body origin to its planned height along the normal; likewise
    the attitude (without it the body pitched 0.03 rad down the 30 deg slope over four
    cycles). The servos' damping acts on the joint speed (MuJoCo position actuators have
    no speed input): the planned speed is fed forward through the position target, ctrl
    = q(t + dt/2) + (kv / kp) dq/dt, so that kp (ctrl - q) - kv dq = kp (q_d - q) + kv
    (dq_d - dq); without it the legs lag by (kv / kp) dq (6 cm in a swing) and the lags of
    the four supporting legs differ, pushing the feet to slip."""
    c = anchor_to_feet(p, n_steps, weight, c, obs)
    now, state = step_targets(p, n_steps, weight, c, obs)
    n, R_plan = frames(p)
    now = now._replace(body=now.body + support_shift(p, n_steps, now, obs))
    err = now.body - obs["com"]
    err = err + ((obs["com"] - obs["body"]) @ n) * n
    running = (obs["time"] > p["settle_time"]) & (obs["time"] < end_time(p, n_steps))
    gain = jnp.where(running, p["body_gain"] * CONTROL_DT, 0.0)
    corr = jnp.clip(c.corr + gain * err, -MAX_CORR, MAX_CORR)
    rot = jnp.clip(c.corr_rot + gain * attitude_error(R_plan, obs["quat"]), -MAX_CORR_ROT, MAX_CORR_ROT)
    q0 = leg_targets(p, now.feet, body_for_com(p, now.feet, now.body) + corr, rot)
    later, _ = step_targets(p, n_steps, weight, c, {**obs, "time": obs["time"] + CONTROL_DT})
    later = later._replace(body=later.body + support_shift(p, n_steps, later, obs))
    state = state._replace(corr=corr, corr_rot=rot, target=later.body)
    q1 = leg_targets(p, later.feet, body_for_com(p, later.feet, later.body) + corr, rot)
    lag = jnp.asarray(SERVO_LAG, q0.dtype)
    q = 0.5 * (q0 + q1) + lag * (q1 - q0) / CONTROL_DT + load_feedforward(p, weight, now, q0, rot)
    return state, jnp.concatenate([q, tether_force(p, weight)])


def make_controller(n_steps: int, weight: float) -> Controller:
    """The executor for plans of `n_steps` steps on a robot of `weight` [N]."""

    def step(p, c, obs):
        return executor_step(p, n_steps, weight, c, obs)

    return Controller(executor_init, step, name="quasi-static footstep executor")
