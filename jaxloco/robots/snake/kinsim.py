"""Pure-JAX kinematic simulation of T² Snake-3 under the task-space controller
(`control`): the wheels do not skid, the base part stays flat on the ground z = 0 and
the joints follow their commanded speeds up to the servos' limits. jit, vmap (over
gains, targets, initial postures) and grad (for tuning) work on `rollout`.

The plant. State: the planar pose [x, y, heading] of the first base link (link 7,
`kinematics.base_of`), phi (12) and the wheel angles rho (7). Per control period dt
(explicit Euler):
  * position servos: the controller's commanded joint speeds are integrated into target
    angles (as on the robot, Sec. IV-C2) and each joint moves towards its target at most
    at the servo speed (`PlantParams`: MX-106R joints 4.7 rad/s = 45 rpm no load), so
    a target that ran ahead is caught up later; the wheels turn at the commanded speed
    up to the MX-28AR's 6 rad/s (as the MJCF),
  * w_dot is the least-squares solution of the mode's constraints A_sigma w_dot =
    B_sigma u (Eq. 7): exact when u satisfies them (the controller's u does, Eqs.
    13-14), the best no-skid fit when a lagging servo or a joint stop made it
    inconsistent (the real wheels would skid),
  * the base pose moves with d(base)/d(w, phi) (w_dot, phi_dot), so the base can never
    leave the plane by integration drift, and phi stops at its limits (Table I).

Controller variants (Sec. IV-C2, V-A): feedforward (the paper's experiments): the
controller integrates its own commanded u on a copy of the same model and never reads
the plant; feedback: it reads the plant's w and phi (Fig. 7(b), "measured by the motion
capture system"). Both are exact copies of each other until the servos fall behind
their targets or a joint reaches its limit; the MuJoCo scenario (`sim_control`) adds
the real errors (compliant servos, wheel slip, lift transients).

Targets: w~_d(t) = w~_0 + delta s(t) with a smooth step s from `t0` over `duration`
(zero speed at both ends), the paper's "target value begins to change at t = 1".
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import jax
import jax.numpy as jnp

from jaxloco import linalg
from jaxloco.robots.snake import control, kinematics
from jaxloco.robots.snake import params as snake_params

Array = jax.Array
JOINT_SPEED_MAX = snake_params.PARAMETERS.default("joint_speed_max")  # [rad/s] Dynamixel MX-106R, 45 rpm at 12 V
WHEEL_SPEED_MAX = 6.0  # [rad/s] MX-28AR (55 rpm), as `model.WHEEL_SPEED`


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class Target:
    """w~_d(t) = w0 + delta * s((t - t0) / duration), s a smooth step 0 -> 1; or a script
    of K such steps, delta (K, 7), t0 (K,), duration (K,), summed (an operator's
    joystick commands as a time series)."""

    w0: Array  # (7,) [w (6), psi_3]
    delta: Array  # (7,) or (K, 7)
    t0: Array = 1.0  # [s], or (K,)
    duration: Array = 4.0  # [s], or (K,)

    def at(self, t: Array) -> tuple[Array, Array]:
        """(w~_d (7,), w~_d_dot (7,)) at time t."""
        tau = jnp.clip((t - self.t0) / self.duration, 0.0, 1.0)
        s = tau - jnp.sin(2 * jnp.pi * tau) / (2 * jnp.pi)
        inside = (t > self.t0) & (t < self.t0 + self.duration)
        s_dot = jnp.where(inside, (1.0 - jnp.cos(2 * jnp.pi * tau)) / self.duration, 0.0)
        if jnp.ndim(self.delta) == 2:  # a script: the steps add up
            return self.w0 + jnp.sum(s[:, None] * self.delta, 0), jnp.sum(s_dot[:, None] * self.delta, 0)
        return self.w0 + self.delta * s, self.delta * s_dot


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class PlantParams:
    """Servo limits of the kinematic plant."""

    joint_speed_max: Array = JOINT_SPEED_MAX  # [rad/s]
    wheel_speed_max: Array = WHEEL_SPEED_MAX  # [rad/s]


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class SnakeState:
    """Kinematic state: base = [x, y, heading] of link 7 (m, rad), phi (12,), rho (7,)."""

    base: Array
    phi: Array
    rho: Array


def initial_state(phi: Array, base: Array | None = None) -> SnakeState:
    phi = jnp.asarray(phi)
    base = jnp.zeros(3, phi.dtype) if base is None else jnp.asarray(base, phi.dtype)
    return SnakeState(base, phi, jnp.zeros(snake_params.N_W, phi.dtype))


def head_pose(state: SnakeState, params=None) -> Array:
    """w_h (6,) of a state (base flat on the ground)."""
    return kinematics.base_frame_pose(state.base, state.phi, params=params)


def point_pose(state: SnakeState, params=None, point: str = "tip") -> Array:
    """Pose w (6,) of the controlled point ("tip" or "head")."""
    return kinematics.head_to_point(head_pose(state, params), point, params)


def integrate(
    state: SnakeState, u: Array, matrices: tuple[Array, Array], dt: Array, params=None, point: str = "tip"
) -> tuple[SnakeState, Array]:
    """One Euler step of the no-skid model with input u (19,) in the mode whose
    augmented matrices (A~, B~) (kinematics.augmented_matrices) are given: (next state,
    w_dot (6,) of the controlled point). Joints stop at their limits: a joint speed
    that would pass its stop is cut to reach it, and the body moves with the joint
    speeds actually realized (the least-squares w_dot of the cut input)."""
    At, Bt = matrices
    A, B = At[: kinematics.N_ROWS, :6], Bt[: kinematics.N_ROWS]
    lim = jnp.asarray(control.PHI_LIMITS, state.phi.dtype)
    phi = jnp.clip(state.phi + dt * u[: snake_params.N_PHI], -lim, lim)
    phi_dot = (phi - state.phi) / dt
    rhs = B @ jnp.concatenate([phi_dot, u[snake_params.N_PHI :]])
    w_dot = linalg.spd_solve(A.T @ A, A.T @ rhs)
    w = point_pose(state, params, point)

    def base_fn(w_, phi_):
        return kinematics.base_of(kinematics.point_to_head(w_, point, params), phi_, params=params)

    _, base_dot = jax.jvp(base_fn, (w, state.phi), (w_dot, phi_dot))
    return SnakeState(state.base + dt * base_dot, phi, state.rho + dt * u[snake_params.N_PHI :]), w_dot


def servo_input(phi: Array, phi_cmd: Array, rho_dot: Array, dt: Array, plant: PlantParams) -> Array:
    """The input u (19,) the servos realize in one period: each joint moves towards its
    target angle phi_cmd (position servo) at most at joint_speed_max, so a target that
    ran ahead is caught up later; the wheels turn at the commanded speed up to
    wheel_speed_max."""
    joint = jnp.clip((phi_cmd - phi) / dt, -plant.joint_speed_max, plant.joint_speed_max)
    wheel = jnp.clip(rho_dot, -plant.wheel_speed_max, plant.wheel_speed_max)
    return jnp.concatenate([joint, wheel])


@dataclass(frozen=True)
class RolloutConfig:
    """Static settings of a rollout (they fix the compiled program)."""

    steps: int = 1000  # control periods
    dt: float = 0.02  # [s] control period
    point: str = "tip"  # controlled point: "tip" (w) or "head" (w_h, Sec. V-A)
    feedback: bool = False  # False: the paper's feedforward control (Sec. IV-C2)
    record_every: int = 1


def rollout(
    x0: SnakeState,
    target: Target,
    cp: control.ControlParams,
    config: RolloutConfig = RolloutConfig(),
    plant: PlantParams = PlantParams(),
    params: snake_params.SnakeParams | None = None,
    choose: Callable[[SnakeState, Array], Array] | None = None,
) -> dict[str, Array]:
    """Closed loop from x0 for `config.steps` periods. `choose` (optional): in the
    switching state, at the start of every Delta T slot, choose(state the controller
    sees, t) -> the mode for the slot, instead of the next mode of cp.mode_order
    (`predictive.chooser`: the paper's "optimal mode" of its ref. [21]). Records (n, ...) of
    t [s], w (6,) and psi3 of the plant, w_h (6,), base (3,), phi (12,), error (7,)
    (plant w~ - w~_d, angles wrapped), ctrl_error (7,) (what the controller saw), V
    (the cost at the plant state, Eq. 19/20), sigma, switching, margin (static
    stability margin of the grounded wheels' support polygon [m]), u (19,) (the
    servos' input, `servo_input`)
    and limit_ratio (max |phi_i| / limit_i)."""
    dtype = x0.phi.dtype
    dt = jnp.asarray(config.dt, dtype)
    point = config.point

    def aug(state: SnakeState, grounded):
        w = point_pose(state, params, point)
        return w, kinematics.augmented_matrices(w, state.phi, grounded, params=params, point=point)

    lim = jnp.asarray(control.PHI_LIMITS, dtype)

    def step(carry, k):
        truth, est, mode, phi_cmd, chosen, last_slot = carry
        t = k * dt
        seen = truth if config.feedback else est
        mode, sigma = control.update_mode(t, seen.phi, mode, cp)
        if choose is not None:
            slot = jnp.floor((t - mode.t_enter) / cp.delta_t + 1e-9).astype(jnp.int32)
            fresh = mode.switching & (slot != last_slot)
            picked = jax.lax.cond(fresh, lambda: jnp.asarray(choose(seen, t), jnp.int32), lambda: chosen)
            sigma = jnp.where(mode.switching, picked, sigma).astype(jnp.int32)
            chosen, last_slot = picked, jnp.where(mode.switching, slot, -1)
        grounded = control.grounded_of(sigma)
        wd, wd_dot = target.at(t)
        w_seen, mats_seen = aug(seen, grounded)
        terms = control.control_terms(w_seen, seen.phi, wd, wd_dot, grounded, cp, params, point, mats_seen)
        phi_cmd = jnp.clip(phi_cmd + dt * terms.u[: snake_params.N_PHI], -lim, lim)  # the servos' target angles
        u = servo_input(truth.phi, phi_cmd, terms.u[snake_params.N_PHI :], dt, plant)
        if config.feedback:
            w_true, mats_true = w_seen, mats_seen
            est_next = est
        else:
            w_true, mats_true = aug(truth, grounded)
            est_next, _ = integrate(est, terms.u, mats_seen, dt, params, point)
        wt_true = control.controlled_variable(w_true, truth.phi)
        rec = {
            "t": t,
            "w": w_true,
            "psi3": truth.phi[snake_params.SCP_INDEX],
            "base": truth.base,
            "phi": truth.phi,
            "error": control.task_error(wt_true, wd),
            "ctrl_error": terms.error,
            "V": control.cost(w_true, truth.phi, grounded, cp, params, point),
            "sigma": sigma,
            "switching": mode.switching,
            "margin": control.support_distances(
                kinematics.point_to_head(w_true, point, params), truth.phi, grounded, params
            )[2],
            "u": u,
            "limit_ratio": control.limit_ratio(truth.phi),
        }
        truth_next, _ = integrate(truth, u, mats_true, dt, params, point)
        return (truth_next, est_next, mode, phi_cmd, chosen, last_slot), rec

    mode0 = control.initial_mode_state(dtype)
    ks = jnp.arange(config.steps)
    carry0 = (x0, x0, mode0, x0.phi, jnp.asarray(cp.fixed_mode, jnp.int32), jnp.asarray(-1, jnp.int32))
    _, recs = jax.lax.scan(step, carry0, ks.astype(dtype))
    if config.record_every > 1:
        recs = jax.tree_util.tree_map(lambda r: r[:: config.record_every], recs)
    return recs


def hold_target(x0: SnakeState, params=None, point: str = "tip", psi3: Array | None = None) -> Target:
    """The target that holds the controlled point where x0 puts it (and psi_3 at
    `psi3`, default its initial value): the joint-limit experiment's w~_d (Sec. V-B)."""
    w0 = control.controlled_variable(point_pose(x0, params, point), x0.phi)
    if psi3 is not None:
        w0 = w0.at[6].set(psi3)
    return Target(w0, jnp.zeros_like(w0), jnp.asarray(0.0, w0.dtype), jnp.asarray(1.0, w0.dtype))

