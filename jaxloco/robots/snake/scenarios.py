"""T² Snake-3 in MuJoCo (Tanaka et al., IEEE T-RO 35(1), 2019): the actuator command of a
control law's output (joint targets, base wheel speeds, mode) with the wheels of the mode
lifted by the base pitch joints (Sec. II-A), and a flat-ground `jaxloco.sim.Scenario`
that runs it closed loop, on native MuJoCo or, on the model's MJX variant (`mjx_variant`:
the ground a plane only the wheels touch), on MJX.

Wheel lifting (`lift_angles`). Sec. II-A: "If some of the pitch joints slightly rotate,
the robot can lift each wheel from the ground"; psi_b = psi_4..psi_8 only lift wheels.
Design: a height profile h_i along the base, 0 for the grounded pairs and `lift_height`
for the lifted ones (Table II row = grounded mask of base pairs 1..7). Base pairs 1..6
are coaxial with psi_3..psi_8, 2 l apart along the base; pair 7 is on the tail link,
l + TAIL_AXLE = 2 l - r behind psi_8 (segment 6 = links 17, 18, on which pairs 6 and 7
sit). Straight base: segment i (pair i -> pair i + 1, i = 1..6, length L_i) inclines by

    beta_i = asin((h_{i+1} - h_i) / L_i)      (beta > 0: its rear end higher)

about its axle (link frames R_seg = Rz(heading) Ry(beta)), and since R_rear = R_front
Ry(psi) (`kinematics`), the pitch angle at pair i + 1 is psi_{3+i} = beta_{i+1} - beta_i
(i = 1..5): psi > 0 raises the front link, as in `params`. Implemented exactly for any
base yaw angles theta_4..theta_9 (argument theta_b): walking the chain from link 7 (flat,
unrolled, on pair 1's axle), the height of the next axle is a sinusoid A cos(psi) + B
sin(psi) + C of the next pitch angle (the first one being beta_1 of link 7 itself), solved
in closed form, the root nearest 0 kept; for a straight base this is the asin formula.
Axle midpoints are the design variables: a wheel's lowest point is r below its axle
whatever the link's pitch, so a lifted pair of a straight base clears the ground by
exactly lift_height; `kinematics.wheel_pairs`' link-fixed contact points differ by
r (1 - cos beta) < 0.6 mm at 20 mm lift. A bent base also rolls the links behind a
bent yaw joint slightly (axle tilt ~ sin(beta) sin(theta)), which the design ignores:
at theta = +-0.6 rad the link-fixed contact points of grounded pairs sit up to 0.7 mm
off the ground (tested).

Head part attitude (`dpsi3`). The first base segment carries pair 1 (psi_3) and the head
part hangs on psi_3: when it tilts (beta_1 != 0: mode 6 lifts pair 2), the head part
would pitch with it (R_link6 = R_link7 Ry(-psi_3)). Adding dpsi3 = beta_1 to the psi_3
servo target keeps R_link6, i.e. the head part's attitude (it turns about the psi_3 axle,
which stays on the ground: pair 1 is grounded in every mode of Table II).

Actuator command (`actuator_command`): the 17 joint position targets (phi entries,
psi_b of `lift_angles`, psi_3 + dpsi3), base wheels (model pairs 3..9) at rho_dot
[rad/s], head wheels (model pairs 1, 2) at rest. Lifted pairs' rho_dot are passed
through unchanged (the control law's free variables; they spin in the air).

Scenario (`snake_scenario`): the robot (`models/t2snake3.xml`) on flat ground
(`jaxloco.sim.terrain.flat`, top face z = 0), control period `control_dt`. Terrain
friction params["mu"] per simulation (`friction_field` on the ground and on the robot's
geoms: MuJoCo combines the two geoms' frictions by their maximum, and the robot's own
is 1, so setting only the ground would leave every mu < 1 without effect). Initial
state: the posture `phi0` with the base on the ground at params["x0"], ["y0"],
["heading0"] and the wheels of params["mode"] lifted by `lift_angles` (exact: the base
segments inclined, lifted wheels `lift_height` above the ground, the servos holding it),
at rest.

Geometry read from the state (qpos, qvel; exact, no Euler-angle singularity): the chain
of `kinematics.link_frames` relative to the head, put in the world by the free joint's
position and quaternion. Per wheel pair: the clearance (lowest point of its two wheel
cylinders above z = 0, the flat ground), contact = clearance < CONTACT_TOL; the lateral
slip = velocity of the pair's contact point (`kinematics.wheel_pairs`, r below the axle
midpoint, body-fixed) along the axle (the quantity Eq. 2 sets to zero; the paper blames
its 34 % y error on the head-end base wheel slipping, Sec. V-A); the rolling slip of the
active wheel = forward velocity of the wheel's material point at its contact (link
motion minus r times the measured wheel spin: Eq. 3's residual).

Observation (dict; what a controller sees; `state_geometry` plus time, phi, contact):
time (), head (6,) w_h = [x, y, z, roll, pitch, yaw] (R = Rz Ry Rx,
`jaxloco.sim.metrics.quat_to_rpy`), tip (6,) the gripper tip pose w (head attitude),
base (6,) pose of link 7, joints (17,) theta_1, psi_1, ..., theta_9, joint_vel (17,),
phi (12,) the measured phi, wheel_speed (9,) active wheels [rad/s], clearance (9,)
model pairs 1..9 [m], contact (7,) bool base pairs 1..7, slip (9,), roll_slip (9,)
[m/s] model pairs (unmasked), tilt () [rad]. All from the state after the last
physics step (qpos, qvel), none from MuJoCo's derived fields.

Records: head (6,), tip (6,), base (6,) pose of link 7 (first base link, on the psi_3
axle), joints (17,), phi (12,), contact (7,), clearance (9,), slip (7,) [m/s] lateral
slip of base pairs in contact (0 when lifted), roll_slip (7,) [m/s] rolling slip of base
active wheels in contact (0 when lifted), and the last command of a `make_controller`
controller: phi_cmd (12,), rho_dot_cmd (7,), grounded_cmd (7,) (measured phi, zeros and
the measured contacts before its first step; zeros for other controllers).

Metrics: final_x, final_y, final_z, final_roll, final_pitch, final_yaw (head, last
record), max_slip (largest |lateral slip| of a grounded pair), max_roll_slip, min_contacts
(fewest base pairs in contact in a record), max_tilt (largest angle of link 7's z from the
vertical; it includes the designed inclination beta_1, 0.11 rad in mode 6), fell
(max_tilt > params["fall_tilt"]), status (0 ok, 1 fell).

Params (`PARAM_DEFAULTS`, `params_batch`): mu, lift_height [m], mode (int 1..6, the
initial mode: lifted wheels at t = 0, and the mode of `constant_controller`), rho_dot
[rad/s] (`constant_controller`'s base wheel speed), x0, y0 [m], heading0 [rad] (initial
base placement), fall_tilt [rad], head_kp [N m/rad], head_kv [N m s/rad] (the head part's
six position servos, per simulation; defaults: the model's); a controller's own keys are added with
`params_batch(..., defaults=...)`.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from jaxloco import geometry as geo
from jaxloco.errors import SpecError
from jaxloco.robots.snake import kinematics
from jaxloco.robots.snake import model as snake_model
from jaxloco.robots.snake import params as snake_params
from jaxloco.sim import metrics as sm
from jaxloco.sim import terrain as tr
from jaxloco.sim.backend import BACKENDS
from jaxloco.sim.data import SimData
from jaxloco.sim.scenario import Controller, InitialState, ModelField, Scenario, friction_field, position_servo_fields
from jaxloco.sim.scenario import params_batch as sim_params_batch

Array = jax.Array
Policy = Callable[[Mapping[str, Any], Any, Any], tuple[Any, Array, Array, Array]]

LIFT_HEIGHT = 0.02  # [m] default lift of a wheel pair (wheel lowest point above ground)
CONTACT_TOL = 0.003  # [m] a wheel pair touches when its clearance is below this. 3 mm: `lift_angles` places
# axle midpoints and ignores the roll of a bent base, so in the zigzag of Sec. V-B a narrow pair beside a wide one
# (params.WIDE_PAIRS) rests 2-2.5 mm above the ground while the wide pair's lower wheel carries it
CONTROL_DT = 0.02  # [s] default control period (50 Hz)
STATUSES = ("ok", "fell")

PARAM_DEFAULTS: dict[str, float] = {
    "mu": snake_params.PARAMETERS.default("mu"),  # ground friction
    "lift_height": LIFT_HEIGHT,  # [m]
    "mode": 1,  # Table II mode at t = 0 (and of constant_controller)
    "rho_dot": 0.0,  # [rad/s] constant_controller's base wheel speed
    "x0": 0.0,  # [m] initial base placement: psi_3 axle (x, y) ...
    "y0": 0.0,  # [m]
    "heading0": 0.0,  # [rad] ... and heading of link 7
    "fall_tilt": 0.5,  # [rad] link 7 tilted more than this: fell
    "head_kp": snake_model.KP,  # [N m/rad] stiffness of the head part's six servos (model.py)
    "head_kv": snake_model.KV,  # [N m s/rad] their damping
}
INT_KEYS = ("mode",)

_PAIR_LINK = np.asarray(snake_params.PAIR_LINKS) - 1  # 0-based link of each of the 9 pairs
_BASE_LINK = _PAIR_LINK[snake_params.BASE_PAIRS[0]]  # link 7 (0-based 6)


# ----------------------------------------------------------------------- wheel lifting
def _wrap(x: Array) -> Array:
    return jnp.arctan2(jnp.sin(x), jnp.cos(x))


def lift_angles(
    grounded: Array,
    lift_height: Array,
    theta_b: Array | None = None,
    params: snake_params.SnakeParams | None = None,
) -> tuple[Array, Array]:
    """Base pitch angles psi_b = psi_4..psi_8 (5,) [rad] that put the axle midpoints of
    base pairs 1..7 at heights r + (0 if grounded else lift_height) above the plane of
    pair 1's axle with link 7 unrolled, and dpsi3 () [rad] = beta_1, the correction to
    add to the psi_3 target so that the head part keeps its attitude (module docstring).

    grounded (7,) bool: a row of `params.MODES` (data: jit / vmap over modes);
    lift_height [m]; theta_b (6,) the base yaw angles theta_4..theta_9 (phi[6:]; default
    0, a straight base). Each pitch angle is the exact solution of its axle-height
    equation (a sinusoid in the angle) along the chain, so a bent base lifts the pairs by
    exactly the same heights; the solution nearest 0 is taken.
    """
    params = snake_params.default_params() if params is None else params
    dtype = jnp.result_type(lift_height, float) if theta_b is None else jnp.result_type(lift_height, theta_b, float)
    grounded = jnp.asarray(grounded, bool)
    h = jnp.where(grounded, 0.0, jnp.asarray(lift_height, dtype))  # (7,)
    theta = jnp.zeros(snake_params.N_B, dtype) if theta_b is None else jnp.asarray(theta_b, dtype)
    l = jnp.asarray(params.link_length, dtype)
    rear = jnp.concatenate([jnp.full(snake_params.N_B - 1, l), jnp.asarray(params.tail_axle, dtype)[None]])
    R = jnp.eye(3, dtype=dtype)  # frame of the link in front of the current pitch joint
    angles = []
    for i in range(snake_params.N_B):  # segment i: pair i + 1 -> pair i + 2 (0-based i)
        # axle-to-axle vector in the frame behind the pitch joint (before its rotation)
        u = jnp.stack([-l, 0.0 * l, 0.0 * l]) + geo.rot_z(-theta[i]) @ jnp.stack([-rear[i], 0.0 * l, 0.0 * l])
        g = R[2]  # world z in the current frame: height change = g . Ry(psi) u
        A = g[0] * u[0] + g[2] * u[2]
        B = g[0] * u[2] - g[2] * u[0]
        C = g[1] * u[1]
        amp = jnp.sqrt(A * A + B * B)
        ang = jnp.arctan2(B, A)
        c = jnp.arccos(jnp.clip((h[i + 1] - h[i] - C) / amp, -1.0, 1.0))
        psi_m, psi_p = _wrap(ang - c), _wrap(ang + c)
        psi = jnp.where(jnp.abs(psi_m) <= jnp.abs(psi_p), psi_m, psi_p)
        angles.append(psi)
        R = R @ geo.rot_y(psi) @ geo.rot_z(-theta[i])  # the next segment's rear link
    beta = jnp.stack(angles)  # beta_1 (link 7's inclination), then psi_4 .. psi_8
    return beta[1:], beta[0]


@functools.cache
def _actuator_ids() -> tuple[np.ndarray, np.ndarray]:
    """Actuator indices of the 17 joint servos (JOINT_NAMES order) and of the 9 wheel
    velocity servos (model pairs 1..9), from the model file."""
    m = snake_model.load_model()
    joints = np.array([m.actuator(n).id for n in snake_params.JOINT_NAMES])
    wheels = np.array([m.actuator(n).id for n in snake_model.WHEEL_NAMES])
    return joints, wheels


def joint_targets(
    phi_target: Array, grounded: Array, lift_height: Array, params: snake_params.SnakeParams | None = None
) -> Array:
    """The 17 joint position targets (theta_1, psi_1, ..., theta_9): phi_target with
    psi_b of `lift_angles` (the base yaw angles of phi_target) and psi_3 + dpsi3."""
    phi_target = jnp.asarray(phi_target)
    psi_b, dpsi3 = lift_angles(grounded, lift_height, phi_target[snake_params.N_H:], params)
    dtype = jnp.result_type(phi_target, psi_b)
    phi = phi_target.astype(dtype).at[snake_params.SCP_INDEX].add(dpsi3.astype(dtype))
    return kinematics.full_joint_angles(phi, psi_b.astype(dtype))


def actuator_command(
    phi_target: Array,
    rho_dot: Array,
    grounded: Array,
    lift_height: Array,
    params: snake_params.SnakeParams | None = None,
) -> Array:
    """ctrl (nu = 26,) of the model: joint servo targets (`joint_targets`), base wheels
    (model pairs 3..9) at rho_dot (7,) [rad/s], head wheels (pairs 1, 2) at 0.

    phi_target (12,) [rad]; grounded (7,) bool (the mode); lift_height [m]."""
    joint_ids, wheel_ids = _actuator_ids()
    q = joint_targets(phi_target, grounded, lift_height, params)
    wheels = jnp.zeros(snake_params.N_PAIRS, q.dtype).at[snake_params.BASE_PAIRS].set(jnp.asarray(rho_dot, q.dtype))
    nu = len(joint_ids) + len(wheel_ids)
    return jnp.zeros(nu, q.dtype).at[joint_ids].set(q).at[wheel_ids].set(wheels)


# --------------------------------------------------------------------- initial placement
def _axis_quat(axis: int, angle: Array) -> Array:
    half = 0.5 * jnp.asarray(angle)
    q = jnp.zeros((4,), half.dtype).at[0].set(jnp.cos(half))
    return q.at[axis + 1].set(jnp.sin(half))


def _quat_conj(q: Array) -> Array:
    return q * jnp.asarray([1.0, -1.0, -1.0, -1.0], q.dtype)


def placed_head_pose(
    base: Array,
    joints: Array,
    grounded: Array,
    lift_height: Array,
    params: snake_params.SnakeParams | None = None,
) -> tuple[Array, Array]:
    """Head position (3,) and quaternion (4,) (free joint qpos) that put the base on the
    ground for joint angles `joints` (17,) designed by `joint_targets`: link 7's origin
    (the psi_3 axle) at (base[0], base[1], r + h_1), link 7 oriented Rz(base[2])
    Ry(beta_1) (its segment's inclination of `lift_angles`)."""
    params = snake_params.default_params() if params is None else params
    joints = jnp.asarray(joints)
    dtype = joints.dtype
    base = jnp.asarray(base, dtype)
    grounded = jnp.asarray(grounded, bool)
    _, beta1 = lift_angles(grounded, lift_height, joints[snake_params.N_H + 2 * np.arange(snake_params.N_B)], params)
    h1 = jnp.where(grounded[0], 0.0, jnp.asarray(lift_height, dtype))
    _, ps = kinematics.link_frames(jnp.zeros(6, dtype), joints, params)
    # link 7 relative to the head: the product of the joint rotations before it
    q_rel = jnp.asarray([1.0, 0.0, 0.0, 0.0], dtype)
    for k in range(_BASE_LINK):
        qk = _axis_quat(1, joints[k]) if snake_params.JOINT_IS_PITCH[k] else _axis_quat(2, -joints[k])
        q_rel = tr.quat_mul(q_rel, qk)
    q7 = tr.quat_mul(tr.quat_z(base[2]), _axis_quat(1, beta1.astype(dtype)))
    quat = tr.quat_mul(q7, _quat_conj(q_rel))
    quat = quat / jnp.linalg.norm(quat)
    p7 = jnp.stack([base[0], base[1], jnp.asarray(params.wheel_radius, dtype) + h1])
    pos = p7 - tr.quat_to_matrix(quat) @ ps[_BASE_LINK]
    return pos, quat


# ------------------------------------------------------------------- state geometry
def layout_of(m: mujoco.MjModel) -> dict[str, np.ndarray]:
    """Where the robot's joints sit in qpos / qvel of the model `m`: "joint_qpos",
    "joint_dof" (17,), "wheel_dof" (9,), and "twist_qpos", "twist_dof" (6,) only where
    the base twists (`twisting_base`)."""
    lay = {
        "joint_qpos": np.array([m.joint(n).qposadr[0] for n in snake_params.JOINT_NAMES]),
        "joint_dof": np.array([m.joint(n).dofadr[0] for n in snake_params.JOINT_NAMES]),
        "wheel_dof": np.array([m.joint(f"{n}_active").dofadr[0] for n in snake_model.WHEEL_NAMES]),
    }
    if mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, TWIST_JOINTS[0]) >= 0:
        lay["twist_qpos"] = np.array([m.joint(n).qposadr[0] for n in TWIST_JOINTS])
        lay["twist_dof"] = np.array([m.joint(n).dofadr[0] for n in TWIST_JOINTS])
    return lay


@functools.cache
def _layout() -> dict[str, np.ndarray]:
    """`layout_of` the robot-only model (`models/t2snake3.xml`, a rigid base)."""
    return layout_of(snake_model.load_model())


def state_geometry(qpos: Array, qvel: Array, params: snake_params.SnakeParams | None = None,
                   layout: Mapping[str, np.ndarray] | None = None) -> dict[str, Array]:
    """What the scenario reads from one simulation's state (see the module docstring):
    head, tip, base (6,) poses, joints, joint_vel (17,), wheel_speed (9,), clearance
    (9,), slip (9,) lateral slip of each pair's contact point, roll_slip (9,) rolling slip
    of each active wheel, tilt () of link 7 [rad]. `layout`: `layout_of` the simulated
    model (default: the robot-only model's); with a twisting base the pairs are turned
    by the twists (`kinematics.twisted`)."""
    params = snake_params.default_params() if params is None else params
    lay = _layout() if layout is None else layout
    qpos, qvel = jnp.asarray(qpos), jnp.asarray(qvel)
    dtype = qpos.dtype
    p_h, quat = qpos[:3], qpos[3:7] / jnp.linalg.norm(qpos[3:7])
    R_h = tr.quat_to_matrix(quat)
    v_h, w_b = qvel[:3], qvel[3:6]  # free joint: world linear, body angular velocity
    joints, jvel = qpos[lay["joint_qpos"]], qvel[lay["joint_dof"]]
    twists = "twist_qpos" in lay
    # the base's twist as one more angle behind the joints (static: whether the model has the hinge)
    angles = jnp.concatenate([joints, qpos[lay["twist_qpos"]]]) if twists else joints
    rates = jnp.concatenate([jvel, qvel[lay["twist_dof"]]]) if twists else jvel
    spin = qvel[lay["wheel_dof"]]
    zero = jnp.zeros(6, dtype)
    wy = kinematics.pair_wheel_y(params, dtype)  # (9,)
    d = (snake_params.ACTIVE_SIDE * wy)[:, None]

    def rel(q):  # in the head frame: pair contact points, active wheels' contacts, axes
        axle, contact, R = kinematics.wheel_pairs(zero, q[:snake_params.N_JOINTS], params,
                                                  q[snake_params.N_JOINTS:] if twists else None)
        return contact, contact + d * R[:, :, 1], axle, R

    (c_rel, a_rel, axle_rel, R_rel), (dc, da, _, _) = jax.jvp(rel, (angles,), (rates,))

    def world_vel(point, dpoint):
        return v_h + (jnp.cross(w_b, point) + dpoint) @ R_h.T

    R_pair = jnp.einsum("ij,pjk->pik", R_h, R_rel)  # (9, 3, 3)
    x_ax, y_ax = R_pair[:, :, 0], R_pair[:, :, 1]
    slip = jnp.sum(world_vel(c_rel, dc) * y_ax, -1)
    roll_slip = jnp.sum(world_vel(a_rel, da) * x_ax, -1) - params.wheel_radius * spin
    # clearance: lowest point of each wheel cylinder (radius r, half width hw, axle y)
    axle = p_h + axle_rel @ R_h.T
    a_z = y_ax[:, 2]
    drop = params.wheel_radius * jnp.sqrt(jnp.clip(1.0 - a_z**2, 0.0, 1.0)) + snake_params.WHEEL_HALF_WIDTH * jnp.abs(
        a_z
    )
    centre_z = axle[:, 2][:, None] + wy[:, None] * jnp.stack([a_z, -a_z], -1)
    clearance = jnp.min(centre_z, -1) - drop
    Rs, ps = kinematics.link_frames(zero, joints, params)
    R7, p7 = R_h @ Rs[_BASE_LINK], p_h + R_h @ ps[_BASE_LINK]
    rpy = sm.quat_to_rpy(quat)
    head = jnp.concatenate([p_h, rpy])
    tip = jnp.concatenate([p_h + params.gripper_tip * R_h[:, 0], rpy])
    return {
        "head": head,
        "tip": tip,
        "base": jnp.concatenate([p7, geo.matrix_to_rpy(R7)]),
        "joints": joints,
        "joint_vel": jvel,
        "wheel_speed": spin,
        "clearance": clearance,
        "slip": slip,
        "roll_slip": roll_slip,
        "tilt": jnp.arccos(jnp.clip(R7[2, 2], -1.0, 1.0)),
    }


# ----------------------------------------------------------------------- controllers
class CommandState(NamedTuple):
    """The state of a controller made by `make_controller`: the policy's own state and
    its last command (recorded by the scenario)."""

    policy: Any  # the policy's state (a pytree)
    phi_target: Array  # (12,) joint targets [rad]
    rho_dot: Array  # (7,) base wheel speeds [rad/s]
    grounded: Array  # (7,) bool, the mode's grounded pairs


def make_controller(init: Callable[[Mapping[str, Any], Any], Any], policy: Policy, name: str = "snake") -> Controller:
    """A `Controller` from a policy that outputs the control law's quantities:
    init(params, obs) -> state, policy(params, state, obs) -> (state, phi_target (12,),
    rho_dot (7,) [rad/s], grounded (7,) bool). The action is `actuator_command` with
    params["lift_height"]. The controller's state is a `CommandState`."""

    def c_init(p, obs):
        dtype = obs["phi"].dtype
        return CommandState(init(p, obs), obs["phi"], jnp.zeros(snake_params.N_W, dtype), obs["contact"])

    def c_step(p, state, obs):
        s, phi_t, rho, grounded = policy(p, state.policy, obs)
        dtype = obs["phi"].dtype
        phi_t = jnp.asarray(phi_t, dtype)
        rho = jnp.asarray(rho, dtype)
        grounded = jnp.asarray(grounded, bool)
        ctrl = actuator_command(phi_t, rho, grounded, jnp.asarray(p["lift_height"], dtype))
        return CommandState(s, phi_t, rho, grounded), ctrl

    return Controller(init=c_init, step=c_step, name=name)


def mode_mask(mode: Array) -> Array:
    """Grounded mask (7,) of Table II mode `mode` (1..6, traced ok)."""
    return jnp.asarray(snake_params.MODES)[jnp.clip(jnp.asarray(mode) - 1, 0, snake_params.N_MODES - 1)]


def constant_controller(phi: np.ndarray | None = None) -> Controller:
    """Holds phi (default params.INITIAL_PHI), every base wheel at params["rho_dot"], mode
    params["mode"] (for holding / driving tests and benchmarks)."""
    phi = np.asarray(snake_params.INITIAL_PHI if phi is None else phi, float)

    def policy(p, s, obs):
        dtype = obs["phi"].dtype
        rho = jnp.full(snake_params.N_W, jnp.asarray(p["rho_dot"], dtype))
        return s, jnp.asarray(phi, dtype), rho, mode_mask(p["mode"])

    return make_controller(lambda p, obs: jnp.zeros(()), policy, name="constant")


# --------------------------------------------------------------------------- scenario
def _with_fixture_ctrl(controller: Controller, fixture: Fixture) -> Controller:
    """The controller with the fixture's actuators' ctrl appended to its command."""

    def step(p, state, obs):
        state, ctrl = controller.step(p, state, obs)
        extra = jnp.asarray(fixture.ctrl(p, obs["time"]), ctrl.dtype)
        return state, jnp.concatenate([ctrl, extra])

    return Controller(init=controller.init, step=step, name=controller.name)


@dataclass(frozen=True)
class Fixture:
    """Bodies added to the scene beside the ground (e.g. a force plate, a gripper's
    object): `add(spec)` adds them after the ground, so every other index stays; those
    named `bodies` are mocap bodies and `pose(params, dtype)` gives their positions
    (k, 3) and quaternions (k, 4) per simulation (free bodies start where `add` put
    them); the MuJoCo sensors `sensors` (added by `add`) are recorded as "fixture" (their
    readings concatenated); the actuators `actuators` (added by `add`, after the robot's)
    get `ctrl(params, time)` appended to the controller's command. `mjx(spec)`, if
    given, changes what `add` added into what MJX can simulate, in the MJX variant
    (`mjx_variant`, after its own changes), keeping every index."""

    add: Callable[[mujoco.MjSpec], None]
    bodies: tuple[str, ...]
    pose: Callable[[Mapping[str, Any], Any], tuple[Array, Array]]
    sensors: tuple[str, ...] = ()
    # actuators `add` appends after the robot's, and their ctrl (k,) from (params, time [s])
    actuators: tuple[str, ...] = ()
    ctrl: Callable[[Mapping[str, Any], Array], Array] | None = None
    mjx: Callable[[mujoco.MjSpec], None] | None = None


# Collision bits of the MJX variant (`mjx_variant`): a geom's own bit is its contype, the bits of what it touches
# its conaffinity (MuJoCo collides two geoms when either one's contype meets the other's conaffinity)
MJX_FLOOR, MJX_WHEEL, MJX_GRIPPER, MJX_OBJECT = 4, 1, 8, 16


@functools.cache
def _robot_geoms() -> tuple[frozenset[str], frozenset[str]]:
    """(names of the robot's colliding geoms, names of its wheel cylinders) in `models/t2snake3.xml`."""
    m = snake_model.load_model()
    colliding = [m.geom(g).name for g in range(m.ngeom) if m.geom_contype[g] == snake_model.ROBOT_CONTYPE]
    wheels = [n for n in colliding if m.geom_type[m.geom(n).id] == mujoco.mjtGeom.mjGEOM_CYLINDER]
    return frozenset(colliding), frozenset(wheels)


def mjx_variant(spec: mujoco.MjSpec, floor: tuple[str, ...]) -> None:
    """Turn the scene `spec` (robot, flat ground `floor`: the terrain's geom names, a
    fixture) into the model MJX can simulate, in place, every index kept. MJX has no
    cylinder-box collision (`mjx.put_model` refuses the wheels on the ground box), and
    every geom pair that may collide costs it every step, near or not. So:
      * the ground box becomes a plane at its top face (z = 0);
      * only the wheel cylinders collide with it (cylinder-plane), and the gripper
        capsule with the fixture's objects; the links' boxes and the gripper collide
        with nothing else (in the snake's analyses only the wheels touch the ground,
        apart from the tail link in the L-shaped postures, docs/simulation.md);
      * a fixture's geoms collide with the gripper, and those of a free body (the pipe)
        with the ground too (`MJX_*` collision bits).
    Friction, masses, servos and everything else are the native model's."""
    robot, wheels = _robot_geoms()
    free = {geom.name for body in spec.bodies for geom in body.geoms
            if any(j.type == mujoco.mjtJoint.mjJNT_FREE for j in body.joints)}
    for geom in spec.geoms:
        if geom.name in floor:
            half = list(geom.size)
            geom.type = mujoco.mjtGeom.mjGEOM_PLANE
            geom.size = [half[0], half[1], 0.05]
            geom.pos = [geom.pos[0], geom.pos[1], geom.pos[2] + half[2]]  # the box's top face
            geom.contype, geom.conaffinity = MJX_FLOOR, 0
        elif geom.name in wheels:
            geom.contype, geom.conaffinity = MJX_WHEEL, MJX_FLOOR
        elif geom.name == "gripper":
            geom.contype, geom.conaffinity = MJX_GRIPPER, MJX_OBJECT
        elif geom.name in robot:
            geom.contype, geom.conaffinity = 0, 0
        elif geom.contype or geom.conaffinity:  # a fixture's object
            geom.contype, geom.conaffinity = MJX_OBJECT, MJX_FLOOR if geom.name in free else 0


WHEEL_FLOOR_FRICTION = (0.005, 0.0001)  # torsional [m], rolling [m]: the terrain's (`build_model`)


def build_model(fixture: Fixture | None = None, backend: str = "native",
                wheel_creep: float = 0.0, twist_compliance: float = 0.0) -> tuple[mujoco.MjModel, tr.Terrain]:
    """The robot (`models/t2snake3.xml`) on flat ground (top face z = 0), with the
    fixture's bodies if given; for `backend` "mjx" its MJX variant (`mjx_variant`, then
    the fixture's `mjx`), with the same indices. `wheel_creep` [s] > 0: the wheels'
    friction on the ground creeps (`creeping_wheels`; native only); `twist_compliance`
    [rad/(N m)] > 0: the base twists at its joints (`twisting_base`)."""
    if backend not in BACKENDS:
        raise ValueError(f"backend: expected one of {', '.join(BACKENDS)}, got {backend!r}")
    if wheel_creep < 0.0 or (wheel_creep > 0.0 and backend != "native"):
        raise SpecError(f"wheel_creep: {wheel_creep:g} s needs a value >= 0 and native MuJoCo (backend {backend!r})")
    if not twist_compliance >= 0.0:
        raise SpecError(f"twist_compliance: {twist_compliance:g} rad/(N m) needs a value >= 0")
    spec = snake_model.load_spec()
    if twist_compliance > 0.0:
        twisting_base(spec, twist_compliance)
    terrain = tr.flat(half_extent=10.0, half_depth=0.5)
    terrain.add_to(spec, friction=(PARAM_DEFAULTS["mu"], *WHEEL_FLOOR_FRICTION))
    if fixture is not None:
        fixture.add(spec)
    if wheel_creep > 0.0:
        creeping_wheels(spec, tuple(terrain.body_names()), wheel_creep)
    if backend == "mjx":
        mjx_variant(spec, tuple(terrain.body_names()))
        if fixture is not None and fixture.mjx is not None:
            fixture.mjx(spec)
    return spec.compile(), terrain


def pair_friction_fields(m: mujoco.MjModel, key: str = "mu") -> tuple[ModelField, ...]:
    """The sliding friction (both tangent directions) of the model's explicit contact
    pairs (`creeping_wheels`) set per simulation to params[key]; none without pairs."""
    if m.npair == 0:
        return ()
    rows = np.repeat(np.arange(m.npair), 2)
    cols = np.tile(np.array([0, 1]), m.npair)
    return (ModelField("pair_friction", (rows, cols), lambda p: jnp.full(rows.shape, p[key])),)


def creeping_wheels(spec: mujoco.MjSpec, floor: tuple[str, ...], creep: float) -> None:
    """Give the wheels' grip on the floor a time constant `creep` [s] (a rubber tyre's
    sideways give), in place: each wheel-floor contact becomes an explicit MuJoCo pair
    (condim 3) with solreffriction (creep, 1), replacing the dynamic one (a body
    exclusion), on an elliptic friction cone (the pyramidal cone, the model's default,
    ignores solreffriction; the cone is the whole model's). A side load then moves a
    wheel sideways at a speed that grows with the load instead of holding it until mu N.
    The pairs' sliding friction is set per simulation with params["mu"] (`pair_friction_fields`).
    Measured on Tables IV-V and III in docs/snake.md; default (ours) 0: hard friction."""
    wheels = [g for g in spec.geoms if g.name in _robot_geoms()[1]]
    torsion, rolling = WHEEL_FLOOR_FRICTION
    for wheel in wheels:
        for floor_geom in floor:
            spec.add_pair(geomname1=wheel.name, geomname2=floor_geom, condim=3,
                          friction=[PARAM_DEFAULTS["mu"]] * 2 + [torsion, rolling, rolling],
                          solreffriction=[creep, 1.0])
            spec.add_exclude(bodyname1=wheel.parent.name, bodyname2=spec.geom(floor_geom).parent.name)
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC


# the base's twist hinges (`twisting_base`), behind theta_4 .. theta_9
TWIST_JOINTS = tuple(f"twist{k}" for k in range(4, 4 + snake_params.N_B))
TWIST_DAMPING = 0.5  # [N m s/rad] of the twist hinge, default (ours)
TWIST_ARMATURE = 0.001  # [kg m^2] of the twist hinge, ours (the rotor inertia a joint servo would add)


def twisting_base(spec: mujoco.MjSpec, compliance: float) -> None:
    """Let the base twist at each of its joints, in place: behind every base yaw joint
    theta_4 .. theta_9 a passive hinge about the next link's long axis (x), in that
    link's body (links 8, 10, ..., 18), with stiffness 1 / `compliance` [N m/rad] each
    and damping `TWIST_DAMPING`. Link 7 (the psi_3 axle's pair) and the raised head part
    then roll on pair 3's wheels against the springs and their own weight when pushed
    across the base, and each unit of the base keeps its wheels on the ground: the
    "mechanical stiffness" the paper finds insufficient (Secs. V-B, V-D), as the twist
    of the base's joints. Measured on Tables III-V, the joint-limit run and the
    operations in docs/snake.md; default (ours) 0: a rigid base. The added joints move
    the qpos / qvel addresses behind theta_4 (read them from the model, `layout_of(m)`)."""
    for k, name in enumerate(TWIST_JOINTS):
        spec.body(f"link{kinematics.TWIST_LINKS[k] + 1}").add_joint(
            name=name, type=mujoco.mjtJoint.mjJNT_HINGE, axis=[1.0, 0.0, 0.0], stiffness=1.0 / compliance,
            damping=TWIST_DAMPING, armature=TWIST_ARMATURE)


def snake_scenario(
    horizon_s: float = 5.0,
    control_dt: float = CONTROL_DT,
    controller: Controller | None = None,
    phi0: np.ndarray | None = None,
    record_every: int = 1,
    fixture: Fixture | None = None,
    backend: str = "native",
    wheel_creep: float = 0.0,
    twist_compliance: float = 0.0,
) -> Scenario:
    """T² Snake-3 on flat ground for `horizon_s` seconds at the control period
    `control_dt` [s] (a multiple of the 2 ms physics step), recording every
    `record_every` control periods, driven by `controller` (default
    `constant_controller(phi0)`), starting in the posture phi0 (12,) (default
    params.INITIAL_PHI, Sec. V-A; a params entry "phi0" (12,) per simulation replaces
    it) with the wheels of params["mode"] lifted; `fixture`: bodies beside the ground;
    `backend` "mjx": on the MJX variant of the model (`build_model`); `wheel_creep` [s]
    > 0: the wheels' grip on the floor creeps (`creeping_wheels`); `twist_compliance`
    [rad/(N m)] > 0: the base twists at its joints (`twisting_base`)."""
    m, terrain = build_model(fixture, backend, wheel_creep, twist_compliance)
    phi0 = np.asarray(snake_params.INITIAL_PHI if phi0 is None else phi0, float)
    controller = controller or constant_controller(phi0)
    if fixture is not None and fixture.actuators:
        controller = _with_fixture_ctrl(controller, fixture)
    substeps = max(1, round(control_dt / m.opt.timestep))
    ctrl_dt = substeps * m.opt.timestep
    horizon = max(record_every, round(horizon_s / ctrl_dt))
    horizon -= horizon % record_every
    rows = tr.mocap_ids(m, terrain)
    ground = np.array([m.geom(n).id for n in terrain.body_names()])
    robot = np.array(sorted(m.geom(n).id for n in _robot_geoms()[0]))
    lay = layout_of(m)  # the ground (a mocap body) and a fixture's joints come after the robot's
    assert twist_compliance > 0.0 or all(np.array_equal(lay[k], v) for k, v in _layout().items())
    assert all(m.actuator(n).id == a for n, a in zip(snake_params.JOINT_NAMES, _actuator_ids()[0], strict=True))
    wheel_qpos = np.array([m.joint(f"wheel{i + 1}_{s}").qposadr[0] for i in range(snake_params.N_PAIRS)
                           for s in ("active", "passive")])
    sp = snake_params.default_params()
    base_pairs = np.asarray(snake_params.BASE_PAIRS)
    fixture_rows = np.array([m.body_mocapid[m.body(b).id] for b in fixture.bodies], int) if fixture else None
    fixture_adr = np.concatenate([m.sensor_adr[m.sensor(n).id] + np.arange(m.sensor_dim[m.sensor(n).id])
                                  for n in fixture.sensors]) if fixture and fixture.sensors else None

    def initial_state(p, key):
        dtype = jnp.result_type(p["lift_height"], float)
        pos, quat = terrain.place({"height": 0.0 * p["lift_height"]})
        full_pos = jnp.zeros((m.nmocap, 3), dtype).at[rows].set(pos)
        full_quat = jnp.zeros((m.nmocap, 4), dtype).at[rows].set(quat)
        if fixture is not None:
            f_pos, f_quat = fixture.pose(p, dtype)
            full_pos, full_quat = full_pos.at[fixture_rows].set(f_pos), full_quat.at[fixture_rows].set(f_quat)
        grounded = mode_mask(p["mode"])
        lift = jnp.asarray(p["lift_height"], dtype)
        start = jnp.asarray(p.get("phi0", phi0), dtype)
        ctrl = actuator_command(start, jnp.zeros(snake_params.N_W, dtype), grounded, lift)
        if fixture is not None and fixture.actuators:
            ctrl = jnp.concatenate([ctrl, jnp.asarray(fixture.ctrl(p, jnp.zeros((), dtype)), dtype)])
        joints = joint_targets(start, grounded, lift)
        base = jnp.stack([p["x0"], p["y0"], p["heading0"]]).astype(dtype)
        p_h, q_h = placed_head_pose(base, joints, grounded, lift, sp)
        qpos = jnp.asarray(m.qpos0, dtype).at[:3].set(p_h).at[3:7].set(q_h)
        qpos = qpos.at[lay["joint_qpos"]].set(joints).at[wheel_qpos].set(0.0)
        return InitialState(qpos=qpos, qvel=jnp.zeros(m.nv, dtype), ctrl=ctrl, mocap_pos=full_pos,
                            mocap_quat=full_quat)

    def observe(data: SimData):
        g = state_geometry(data.qpos, data.qvel, sp, lay)
        contact = g["clearance"][base_pairs] < CONTACT_TOL
        return {"time": data.time, "phi": g["joints"][snake_params.PHI_JOINTS], "contact": contact, **g}

    def record(p, data: SimData, obs, c, e):
        g = obs
        contact = obs["contact"]
        dtype = obs["phi"].dtype
        if isinstance(c, CommandState):
            cmd = (c.phi_target, c.rho_dot, c.grounded)
        else:
            cmd = (
                jnp.zeros(snake_params.N_PHI, dtype),
                jnp.zeros(snake_params.N_W, dtype),
                jnp.zeros(snake_params.N_W, bool),
            )
        own = c.policy if isinstance(c, CommandState) else None
        intent = {"intent": own.intent} if hasattr(own, "intent") else {}
        return {
            "head": obs["head"],
            "tip": obs["tip"],
            "base": g["base"],
            "joints": obs["joints"],
            "phi": obs["phi"],
            "contact": contact,
            "clearance": obs["clearance"],
            "slip": jnp.where(contact, g["slip"][base_pairs], 0.0),
            "roll_slip": jnp.where(contact, g["roll_slip"][base_pairs], 0.0),
            "tilt": g["tilt"],
            "phi_cmd": cmd[0],
            "rho_dot_cmd": cmd[1],
            "grounded_cmd": cmd[2],
            **({"fixture": data.sensordata[fixture_adr]} if fixture_adr is not None else {}),
            **intent,  # the operator's intended pose of the controlled point (`operator`), if the controller has one
        }

    def summarize(p, r, final):
        head = r["head"][-1]
        max_tilt = jnp.max(r["tilt"])
        fell = max_tilt > p["fall_tilt"]
        names = ("final_x", "final_y", "final_z", "final_roll", "final_pitch", "final_yaw")
        return {
            **{k: head[i] for i, k in enumerate(names)},
            "max_slip": jnp.max(jnp.abs(r["slip"])),
            "max_roll_slip": jnp.max(jnp.abs(r["roll_slip"])),
            "min_contacts": jnp.min(jnp.sum(r["contact"], -1)),
            "max_tilt": max_tilt,
            "fell": fell,
            "status": jnp.where(fell, 1, 0),
        }

    return Scenario(
        name="snake.flat" if backend == "native" else "snake.flat_mjx",
        model=m,
        controller=controller,
        initial_state=initial_state,
        observe=observe,
        record=record,
        summarize=summarize,
        horizon=horizon,
        substeps=substeps,
        record_every=record_every,
        model_fields=(friction_field(np.concatenate([ground, robot])),
                      *position_servo_fields(_actuator_ids()[0][:snake_params.N_H], "head_kp", "head_kv"),
                      *pair_friction_fields(m)),
        statuses=STATUSES,
    )


def params_batch(n: int = 1, defaults: Mapping[str, float] | None = None, **overrides) -> dict[str, jax.Array]:
    """A batch of n parameter dicts: PARAM_DEFAULTS (plus a controller's `defaults`) with
    `overrides` (scalars or arrays of length n); "mode" is int."""
    return sim_params_batch({**PARAM_DEFAULTS, **(defaults or {})}, n, overrides, int_keys=INT_KEYS)
