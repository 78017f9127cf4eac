"""The paper's experiments (Tanaka et al., IEEE T-RO 35(1), 2019, Sec. V-A, V-B) as
data and metrics, for the kinematic simulation (`kinsim`) and MuJoCo (`scenarios`).

Relative position accuracy (Sec. V-A, Table III): the controlled point is the head
(w_h); from phi = INITIAL_PHI (base straight) each component of w_h is changed alone by
the Table III target (0.2 m, 0.1 m, -0.1 m, pi/2, -pi/6, pi/4), starting at t = 1 s;
the displacement is the mean of w_h over [t_e + 4, t_e + 5] minus its mean over
[0, 1] (t_e: end of the target's change) and the error is |measured - target| /
|target| of the changed component. The paper does not give the speed of the change:
we ramp each target over RAMP = 4 s (a smooth step, `kinsim.Target`), fixing state
sigma = 1 throughout.

Joint-limit avoidance (Sec. V-B, Figs. 8-10): the zigzag posture, head part as in
Sec. V-A, base yaw joints theta_4..theta_9 = +-1.1 rad alternating (Fig. 10: "in the
neighborhood of the joint angle limit (1.1 rad)"; the sign of theta_4 is not given, we
start with +); the target holds the gripper tip where it starts and psi_3 at its SCP
target 110 deg; Delta T = 1 s, fixing state for t < 2 s then switching; K_V of the
paper. Metrics (`limit_metrics`): recovery time (first time every base joint is below
`recover_ratio` of its limit), final V, largest head position / attitude errors,
smallest static stability margin of the grounded wheels, time spent near a limit, and
the order in which the base joints leave their limits (`release_order_score`).
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco.robots.snake import control, kinsim, params

Array = jax.Array

# --- Sec. V-A, Table III
RAMP = params.PARAMETERS.default("ramp")  # [s] our duration of each target change (not in the paper)
T_START = 1.0  # [s] the target begins to change at t = 1
ACCURACY_HORIZON = T_START + RAMP + 5.0  # [s] t_e + 5
ACCURACY_NAMES = ("x", "y", "z", "alpha", "beta", "gamma")
ACCURACY_DELTAS = np.array([0.2, 0.1, -0.1, math.pi / 2, -math.pi / 6, math.pi / 4])  # [m] / [rad]
# Table III, "Exp. (Mean)" of the changed component and the "Error" row [%]
PAPER_ACCURACY_MEAN = np.array([0.20, 0.066, -0.10, 1.54, -0.55, 0.79])
PAPER_ACCURACY_ERROR = np.array([1.0, 34.0, 1.5, 1.9, 6.0, 0.4])
# Table III, the full mean displacement rows (x, y, z [m], alpha, beta, gamma [rad])
PAPER_ACCURACY_ROWS = np.array(
    [
        [0.20, 0.0052, 0.0024, 0.0092, -0.0047, -0.012],
        [-0.069, 0.066, 0.014, -0.055, -0.055, -0.075],
        [-0.011, 0.0040, -0.10, 0.013, -0.013, 0.0075],
        [-0.054, -0.035, 0.030, 1.54, -0.060, -0.063],
        [0.00062, 0.0015, 0.0061, 0.019, -0.55, -0.0060],
        [-0.018, 0.00032, 0.027, 0.050, -0.12, 0.79],
    ]
)

# Table III, "Exp. (SD)" rows (the same layout)
PAPER_ACCURACY_SD = np.array(
    [
        [0.0025, 0.0015, 0.00082, 0.0061, 0.015, 0.0059],
        [0.0036, 0.0033, 0.00071, 0.0053, 0.0047, 0.0039],
        [0.0017, 0.00081, 0.00090, 0.0042, 0.0050, 0.0033],
        [0.0042, 0.0018, 0.0011, 0.014, 0.0051, 0.0037],
        [0.0013, 0.0011, 0.00094, 0.0061, 0.0063, 0.0047],
        [0.0020, 0.0016, 0.00057, 0.0073, 0.0070, 0.0084],
    ]
)

# --- Sec. V-B, Figs. 8-10
ZIGZAG_AMPLITUDE = params.PARAMETERS.default("amplitude")  # [rad]
SWITCH_AT = params.PARAMETERS.default("switch_at")  # [s]
LIMIT_HORIZON = 30.0  # [s] our run length (Fig. 9's time axis is not in the text)
PAPER_HEAD_ERROR = (0.030, 0.1)  # [m], [rad] "about 30 mm and 0.1 rad"


def zigzag_phi(amplitude: float = ZIGZAG_AMPLITUDE) -> np.ndarray:
    """phi (12,) of the joint-limit experiment: head part of Sec. V-A, base yaw joints
    +-amplitude alternating from theta_4 = +amplitude."""
    phi = np.array(params.INITIAL_PHI, float)
    phi[params.N_H :] = amplitude * (-1.0) ** np.arange(params.N_B)
    return phi


def limit_params(**changes) -> control.ControlParams:
    """Controller settings of Sec. V-B: K_V of the paper, Delta T = 1 s, fixing state
    (sigma = 1) until the operator's command at t = 2 s, no automatic switching."""
    base = {"switch_at": SWITCH_AT, "enter_ratio": 2.0, "delta_t": 1.0}
    base.update(changes)
    return control.paper_params(**base)


def limit_setup(amplitude: Array = ZIGZAG_AMPLITUDE, dtype=None) -> tuple[kinsim.SnakeState, kinsim.Target]:
    """(initial state, target) of the joint-limit experiment (gripper tip held, psi_3
    -> 110 deg); `amplitude` may be traced."""
    dtype = dtype or jnp.result_type(float)
    signs = jnp.asarray((-1.0) ** np.arange(params.N_B), dtype)
    phi = jnp.asarray(params.INITIAL_PHI, dtype).at[params.N_H :].set(jnp.asarray(amplitude, dtype) * signs)
    x0 = kinsim.initial_state(phi)
    return x0, kinsim.hold_target(x0, point="tip", psi3=jnp.asarray(params.SCP_TARGET, dtype))


def accuracy_setup(dtype=None) -> tuple[kinsim.SnakeState, kinsim.Target]:
    """(initial state, target batch of 6) of Sec. V-A: head controlled, target ramps."""
    dtype = dtype or jnp.result_type(float)
    x0 = kinsim.initial_state(jnp.asarray(params.INITIAL_PHI, dtype))
    w0 = control.controlled_variable(kinsim.point_pose(x0, point="head"), x0.phi)
    delta = jnp.zeros((6, 7), dtype).at[jnp.arange(6), jnp.arange(6)].set(jnp.asarray(ACCURACY_DELTAS, dtype))
    targets = kinsim.Target(
        jnp.broadcast_to(w0, (6, 7)),
        delta,
        jnp.full(6, T_START, dtype),
        jnp.full(6, RAMP, dtype),
    )
    return x0, targets


def relative_displacement(t: np.ndarray, w: np.ndarray, t_end: float, t_start: float = T_START) -> np.ndarray:
    """Table III's Delta w_h: mean of w over [t_end + 4, t_end + 5] minus the mean over
    the second before the change starts, [t_start - 1, t_start] (the paper: [0, 1]);
    t (n,), w (..., n, 6), angles unwrapped first."""
    t, w = np.asarray(t), np.asarray(w, float).copy()
    w[..., 3:] = np.unwrap(w[..., 3:], axis=-2)
    late = (t >= t_end + 4.0 - 1e-9) & (t <= t_end + 5.0 + 1e-9)
    early = (t >= t_start - 1.0 - 1e-9) & (t <= t_start + 1e-9)
    return w[..., late, :].mean(-2) - w[..., early, :].mean(-2)


def accuracy_errors(displacements: np.ndarray) -> np.ndarray:
    """Errors [%] of the six experiments' changed components (6 x 6 displacements)."""
    changed = np.diagonal(np.asarray(displacements))
    return 100.0 * np.abs(changed - ACCURACY_DELTAS) / np.abs(ACCURACY_DELTAS)


def run_accuracy_kinematic(dt: float = 0.02, feedback: bool = False) -> dict[str, np.ndarray]:
    """Table III in the kinematic simulation: displacements (6, 6) and errors (6,) [%]."""
    x0, targets = accuracy_setup()
    steps = round(ACCURACY_HORIZON / dt) + 1
    config = kinsim.RolloutConfig(steps=steps, dt=dt, point="head", feedback=feedback)
    cp = control.ControlParams(enter_ratio=2.0)  # fixing state throughout
    recs = jax.jit(jax.vmap(lambda tg: kinsim.rollout(x0, tg, cp, config)))(targets)
    disp = relative_displacement(np.asarray(recs["t"][0]), np.asarray(recs["w"]), T_START + RAMP)
    return {"displacement": disp, "error": accuracy_errors(disp), "records": recs}


# ------------------------------------------------------------------------- metrics
def base_limit_ratio(phi: Array) -> Array:
    """max over the base yaw joints theta_4..theta_9 of |theta| / limit (phi (..., 12))."""
    return jnp.max(jnp.abs(phi[..., params.N_H :]) / params.YAW_LIMIT, axis=-1)


def limit_metrics(recs: dict[str, Array], recover_ratio: Array = 0.7, near_ratio: Array = 0.95) -> dict[str, Array]:
    """Scalar metrics of one joint-limit rollout (records of `kinsim.rollout` or of the
    MuJoCo scenario with the same keys): recovery_time [s] (first t with every base
    joint below recover_ratio of its limit; the horizon if never), recovered, V0,
    final_V, max_pos_error [m], max_att_error [rad] (norms of the controlled point's
    position / roll-pitch-yaw errors), max_pos_component_error [m],
    max_att_component_error [rad] (the largest single component, x, y or z / roll,
    pitch or yaw: what one reads off plots of w_h's components as the paper's Fig. 9),
    min_margin [m], time_near_limit [s] (time with some base joint at >= near_ratio of
    its limit), order_score (`release_order_score` of the joints leaving recover_ratio
    of their limits: +1 from the tail to the head, as the paper reports)."""
    t = recs["t"]
    dt = t[1] - t[0]
    ratio = base_limit_ratio(recs["phi"])
    below = ratio <= recover_ratio
    recovered = jnp.any(below)
    t_rec = jnp.where(recovered, t[jnp.argmax(below)], t[-1] + dt)
    pos = jnp.linalg.norm(recs["error"][:, :3], axis=-1)
    att = jnp.linalg.norm(recs["error"][:, 3:6], axis=-1)
    near = ratio >= near_ratio
    released = release_times(t, recs["phi"], recover_ratio)
    return {
        "recovery_time": t_rec,
        "recovered": recovered,
        "V0": recs["V"][0],
        "final_V": recs["V"][-1],
        "max_pos_error": jnp.max(pos),
        "max_att_error": jnp.max(att),
        "max_pos_component_error": jnp.max(jnp.abs(recs["error"][:, :3])),
        "max_att_component_error": jnp.max(jnp.abs(recs["error"][:, 3:6])),
        "min_margin": jnp.min(recs["margin"]),
        "time_near_limit": jnp.sum(near) * dt,
        "order_score": release_order_score(released),
    }


def release_times(t: Array, phi: Array, ratio: Array = 0.7) -> Array:
    """(6,) per base joint theta_4..theta_9 [s]: the first record time from which
    |theta| <= ratio * limit to the end (inf if never): the order in which the joints
    leave the limits. t (T,) [s], phi (T, 12) [rad]; jit / vmap."""
    t = jnp.asarray(t)
    out = jnp.abs(jnp.asarray(phi)[:, params.N_H :]) > ratio * params.YAW_LIMIT
    index = jnp.arange(t.shape[0])
    first_in = jnp.max(jnp.where(out, index[:, None], -1), axis=0) + 1
    return jnp.where(first_in < t.shape[0], t[jnp.minimum(first_in, t.shape[0] - 1)], jnp.inf)


def release_order_score(times: Array) -> Array:
    """Kendall-type score in [-1, 1] of `release_times` (6,): the mean over the 15
    pairs of base joints of +1 where the joint nearer the tail left its limit first,
    -1 where the one nearer the head did (0 where neither left). +1 is the paper's
    "the posture of the robot improved in order from the tail to the head" (Sec. V-B,
    Fig. 10): theta_9 first, theta_4 last."""
    head, tail = np.triu_indices(params.N_B, 1)  # head[k] is the joint nearer the head
    a, b = times[head], times[tail]
    return jnp.mean(jnp.where(jnp.isinf(a) & jnp.isinf(b), 0.0, jnp.sign(a - b)))
