"""The task-space controller (`control`, Eqs. 12-20) driving T² Snake-3 in MuJoCo
(`scenarios.snake_scenario`, native backend), and the paper's two experiments run there.

Per control period (Sec. IV-C): the mode schedule (`control.update_mode`), the input u
of Eq. 12 at the controller's view of the robot; the joint targets integrate the
commanded joint speeds (the paper's "target angle calculated using the numerical
integral"; the position servos follow as fast as their torque allows), the base
active wheels get the commanded speeds up to `wheel_speed_max`, and the mode's wheels
are lifted by the base pitch joints (`scenarios.actuator_command`).

The controller's view (Sec. IV-C2, V-A):
  * feedforward (`feedback=False`, the paper's robot): a copy of the no-skid model
    (`kinsim.integrate`) integrated with the commanded u from the posture at t = 0; the
    simulator is never read after the first observation;
  * feedback (`feedback=True`, Fig. 7(b)): w from the simulated head / gripper-tip pose
    ("motion capture") and phi from the joint encoders; the joint targets still
    integrate the commanded speeds, so a steady servo error is integrated away.

Parameters (keys of the simulation's params dict, `PARAM_DEFAULTS`, batchable): the
gains and schedule of `ControlParams` (K_V from the four numbers of
`control.kv_diagonal`), the wheels' speed limit, and the target: w~_d(t) = w~(0) +
delta s(t) (`kinsim.Target`) with w~(0) the controlled variable at t = 0 and delta =
(d_x, d_y, d_z, d_roll, d_pitch, d_yaw, d_psi3) [m, rad]; `psi3_target` (if finite)
replaces the SCP's start value. The target passes through the teleoperator model
(`operator`: joystick correction of the seen position error, pausing the script and
commanding the switching state at a joint limit), off by default.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco.robots.snake import control, experiments, kinematics, kinsim, operator, predictive, scenarios
from jaxloco.robots.snake import params as snake_params
from jaxloco.sim.rollout import RolloutResult, rollout
from jaxloco.sim.scenario import Controller

Array = jax.Array
DELTA_KEYS = ("d_x", "d_y", "d_z", "d_roll", "d_pitch", "d_yaw", "d_psi3")

PARAM_DEFAULTS: dict[str, float] = {
    # K_V (control.kv_diagonal), K [1/s], Eq. 20 weight, Delta T [s], row of control.MODE_ORDERS, W's wheel weight
    **snake_params.PARAMETERS.defaults(
        ("k_eta", "kv_head_yaw", "kv_head_pitch", "kv_base", "kv_ratio", "gain", "a2", "delta_t", "mode_order",
         "w_wheel")
    ),
    "fixed_mode": 1,
    "switch_at": float("inf"),  # [s]
    "enter_ratio": 2.0,  # automatic switching off
    "exit_ratio": 0.9,
    "wheel_speed_max": kinsim.WHEEL_SPEED_MAX,  # [rad/s]
    "t0": experiments.T_START,  # [s] the target starts to change
    "duration": experiments.RAMP,  # [s] ... over this time
    **{k: 0.0 for k in DELTA_KEYS},
    "psi3_target": float("nan"),  # [rad] SCP target (nan: hold its start value)
    "hold_until": 0.0,  # [s] no null-space motion (k_eta = 0) before this time (settling)
    **operator.PARAM_DEFAULTS,  # the teleoperator (`operator`): off by default
}


def control_params(p: Mapping[str, Array]) -> control.ControlParams:
    """`ControlParams` from one simulation's params dict."""
    dtype = jnp.asarray(p["k_eta"]).dtype
    kv = control.kv_diagonal(p["kv_head_yaw"], p["kv_head_pitch"], p["kv_base"], p["kv_ratio"]).astype(dtype)
    return control.ControlParams(
        gain=jnp.full(control.N_TASK, p["gain"], dtype),
        weights=control.default_weights(w_wheel=p["w_wheel"]).astype(dtype),
        k_eta=p["k_eta"],
        kv=kv,
        a2=p["a2"],
        delta_t=p["delta_t"],
        mode_order=jnp.asarray(control.MODE_ORDERS)[jnp.asarray(p["mode_order"]).astype(jnp.int32)],
        fixed_mode=jnp.asarray(p["fixed_mode"]).astype(jnp.int32),
        switch_at=p["switch_at"],
        enter_ratio=p["enter_ratio"],
        exit_ratio=p["exit_ratio"],
    )


class TaskSpaceState(NamedTuple):
    """The state of `task_space_controller`'s policy."""

    est: kinsim.SnakeState  # the feedforward estimate of the robot (Sec. IV-C2)
    target: kinsim.Target  # the operator's script of w_d
    mode: control.ModeState  # fixing / switching state (`control.update_mode`)
    phi_cmd: Array  # (12,) the joint targets sent last [rad]
    chosen: Array  # () int32, the mode the look-ahead chose for this slot
    slot: Array  # () int32, the switching slot it was chosen in (-1: none)
    operator: Any  # `operator.step`'s state
    intent: Array  # (6,) the pose the operator wants for the controlled point


def task_space_controller(control_dt: float, point: str = "tip", feedback: bool = False,
                          prediction: predictive.Prediction | None = None) -> Controller:
    """The Eq. 12 controller as a `jaxloco.sim` controller (module docstring); `point`:
    the controlled point ("tip": the gripper tip, "head": w_h of Sec. V-A);
    `prediction`: in the switching state, each Delta T slot's mode is the best look-ahead
    (`predictive.mode_scores` from the controller's view) instead of the fixed order."""
    dt = float(control_dt)

    def seen_pose(obs):
        return obs["tip"] if point == "tip" else obs["head"]

    def init(p, obs):
        dtype = obs["phi"].dtype
        base = obs["base"]  # link 7's pose (6,): x, y, z, roll, pitch, yaw
        est = kinsim.SnakeState(jnp.stack([base[0], base[1], base[5]]), obs["phi"], jnp.zeros(snake_params.N_W, dtype))
        w0 = kinsim.point_pose(est, point=point) if not feedback else seen_pose(obs)
        wt0 = control.controlled_variable(w0, obs["phi"])
        wt0 = wt0.at[6].set(jnp.where(jnp.isfinite(p["psi3_target"]), p["psi3_target"], wt0[6]))
        if "script_delta" in p:  # an operator's script: K smooth steps (`kinsim.Target`)
            target = kinsim.Target(wt0, jnp.asarray(p["script_delta"], dtype), jnp.asarray(p["script_t0"], dtype),
                              jnp.asarray(p["script_duration"], dtype))
        else:
            delta = jnp.stack([jnp.asarray(p[k], dtype) for k in DELTA_KEYS])
            target = kinsim.Target(wt0, delta, jnp.asarray(p["t0"], dtype), jnp.asarray(p["duration"], dtype))
        seen0 = seen_pose(obs)
        return TaskSpaceState(est, target, control.initial_mode_state(dtype), obs["phi"], jnp.asarray(1, jnp.int32),
                              jnp.asarray(-1, jnp.int32), operator.initial_state(seen0), seen0)

    def policy(p, s, obs):
        t = obs["time"]
        cp = control_params(p)
        cp = cp.with_(k_eta=jnp.where(t < p["hold_until"], 0.0, cp.k_eta))
        est = s.est
        if feedback:
            w, phi = seen_pose(obs), obs["phi"]
        else:
            w, phi = kinsim.point_pose(est, point=point), est.phi
        op, command = operator.step(
            s.operator,
            s.target,
            t,
            seen_pose(obs),
            operator.base_limit_ratio(obs["phi"]),
            dt,
            p["operator_gain"],
            p["operator_limit"],
            p["operator_enter"],
            p["operator_exit"],
            p["operator_min_switch"],
        )
        cp = cp.with_(switch_at=jnp.where(command.switching, -jnp.inf, cp.switch_at))
        mode, sigma = control.update_mode(t, phi, s.mode, cp)
        chosen, slot = s.chosen, s.slot
        if prediction is not None:
            b = obs["base"]  # link 7's measured pose; the estimate's without feedback
            view = kinsim.SnakeState(jnp.stack([b[0], b[1], b[5]]) if feedback else est.base, phi, est.rho)
            k = jnp.floor((t - mode.t_enter) / cp.delta_t + 1e-9).astype(jnp.int32)
            fresh = mode.switching & (k != slot)
            held = kinsim.Target(command.wd, jnp.zeros_like(command.wd))  # the target held while switching
            pick = predictive.chooser(held, cp, dt, point, prediction)
            chosen = jax.lax.cond(fresh, lambda: jnp.asarray(pick(view, t), jnp.int32), lambda: chosen)
            sigma = jnp.where(mode.switching, chosen, sigma).astype(jnp.int32)
            slot = jnp.where(mode.switching, k, -1)
        grounded = control.grounded_of(sigma)
        wd, wd_dot = command.wd, command.wd_dot
        mats = kinematics.augmented_matrices(w, phi, grounded, point=point)
        terms = control.control_terms(w, phi, wd, wd_dot, grounded, cp, None, point, mats)
        lim = jnp.asarray(control.PHI_LIMITS, phi.dtype)
        phi_cmd = jnp.clip(s.phi_cmd + dt * terms.u[: snake_params.N_PHI], -lim, lim)
        rho_dot = jnp.clip(terms.u[snake_params.N_PHI :], -p["wheel_speed_max"], p["wheel_speed_max"])
        if not feedback:
            est, _ = kinsim.integrate(est, terms.u, mats, jnp.asarray(dt, phi.dtype), None, point)
        state = TaskSpaceState(est, s.target, mode, phi_cmd, chosen, slot, op, command.intent)
        return state, phi_cmd, rho_dot, grounded

    return scenarios.make_controller(init, policy, name=f"task_space_{'fb' if feedback else 'ff'}_{point}")


def params_batch(n: int = 1, **overrides) -> dict[str, Array]:
    """Scenario + controller parameters for n simulations (`scenarios.params_batch`)."""
    return scenarios.params_batch(n, defaults=PARAM_DEFAULTS, **overrides)


# ---------------------------------------------------------------- Table III in MuJoCo
# [s] settling before the experiment's clock starts (the head part sags under its servos)
SETTLE = snake_params.PARAMETERS.default("settle")


def run_accuracy(feedback: bool = False, mu: float = 1.0, control_dt: float = 0.02, settle: float = SETTLE,
                 progress: bool = False, twist_compliance: float = 0.0) -> dict[str, Any]:
    """Sec. V-A in MuJoCo: six simulations (one per Table III row), head controlled,
    fixing state sigma = 1: displacements (6, 6), errors (6,) [%], the largest wheel
    side slip [m/s] per row and the rollout. The simulation starts with the servos at
    their targets and no load; the robot settles for `settle` s (the head part sags by
    several cm) before the paper's clock starts (its t = 0, the change at t = 1);
    `twist_compliance` [rad/(N m)] > 0: the base twists (`scenarios.twisting_base`)."""
    horizon = settle + experiments.ACCURACY_HORIZON + 0.1
    sc = scenarios.snake_scenario(horizon, control_dt, task_space_controller(control_dt, "head", feedback),
                                  twist_compliance=twist_compliance)
    deltas = {k: np.zeros(6) for k in DELTA_KEYS}
    for i, k in enumerate(DELTA_KEYS[:6]):
        deltas[k][i] = experiments.ACCURACY_DELTAS[i]
    t0 = settle + experiments.T_START
    res = rollout(sc, params_batch(6, mu=mu, t0=t0, **deltas), progress=progress)
    disp = experiments.relative_displacement(res.times, np.asarray(res.records["head"]), t0 + experiments.RAMP, t0)
    return {
        "displacement": disp,
        "error": experiments.accuracy_errors(disp),
        "max_slip": np.asarray(res.metrics["max_slip"]),
        "result": res,
    }


# ------------------------------------------------------------ Figs. 8-10 in MuJoCo
def run_joint_limit(overrides: Mapping[str, Any] | None = None, n: int = 1, horizon: float = experiments.LIMIT_HORIZON,
                    feedback: bool = False, control_dt: float = 0.02, mu: float = 1.0, settle: float = SETTLE,
                    progress: bool = False, point: str = "head", prediction: predictive.Prediction | None = None,
                    twist_compliance: float = 0.0) -> tuple[RolloutResult, dict[str, np.ndarray]]:
    """Sec. V-B in MuJoCo: the zigzag posture, the controlled point (`point`: "head", as
    in the paper's Fig. 9, which plots w_h; "tip" for the gripper tip) held, fixing state
    until 2 s then switching every Delta T (params overrides, batch of n), after `settle` s
    of settling with the null-space term off (the paper's clock starts then: switch_at is
    counted from it); `twist_compliance` [rad/(N m)] > 0: the base twists at its joints
    (`scenarios.twisting_base`). Returns the rollout and `limit_records` from the paper's t = 0."""
    phi0 = experiments.zigzag_phi()
    ctrl = task_space_controller(control_dt, point, feedback, prediction)
    sc = scenarios.snake_scenario(settle + horizon, control_dt, ctrl, phi0=phi0, twist_compliance=twist_compliance)
    over = {"switch_at": experiments.SWITCH_AT, "psi3_target": snake_params.SCP_TARGET, "mu": mu, **(overrides or {})}
    over["switch_at"] = np.asarray(over["switch_at"], float) + settle
    over["hold_until"] = settle
    params = params_batch(n, **over)
    res = rollout(sc, params, progress=progress)
    return res, limit_records(res, params, settle, point)


def _limit_signals_one(p, wt_i, phi_i, g_i, tgt, point):
    """Task error, V and static margin over one simulation's records."""
    cp = control_params(p)
    err = jax.vmap(lambda a: control.task_error(a, tgt))(wt_i)
    V = jax.vmap(lambda w, f, g: control.cost(w, f, g, cp, point=point))(wt_i[:, :6], phi_i, g_i)
    w_h = jax.vmap(lambda w: kinematics.point_to_head(w, point))(wt_i[:, :6])
    margin = jax.vmap(lambda h, f, g: control.support_distances(h, f, g)[2])(w_h, phi_i, g_i)
    return err, V, margin


_limit_signals = jax.jit(jax.vmap(_limit_signals_one, in_axes=(0, 0, 0, 0, 0, None)), static_argnums=5)


def limit_records(res: RolloutResult, params: Mapping[str, Array], settle: float = 0.0,
                  point: str = "head") -> dict[str, np.ndarray]:
    """Records of a MuJoCo joint-limit rollout in `kinsim.rollout`'s layout (batch
    first) from t = settle on (t counted from there): t, w (measured pose of the
    controlled point `point`, "head" or "tip"), phi (measured), error (that pose and psi_3
    against the target: the pose measured at t = settle, psi_3 -> psi3_target; angles
    wrapped), V (Eq. 19 / 20 at the measured pose),
    margin (static margin of the commanded mode's support polygon at the measured
    posture), limit_ratio, sigma (the commanded mode), slip (lateral wheel slip)."""
    keep = res.times >= settle - 1e-9
    tip = np.asarray(res.records[point])[:, keep]
    phi = np.asarray(res.records["phi"])[:, keep]
    grounded = np.asarray(res.records["grounded_cmd"])[:, keep]
    times = res.times[keep] - settle
    n = tip.shape[0]
    psi3_t = np.asarray(params["psi3_target"])
    target = np.concatenate([tip[:, :1], phi[:, :1, snake_params.SCP_INDEX : snake_params.SCP_INDEX + 1]], -1)
    target[:, 0, 6] = np.where(np.isfinite(psi3_t), psi3_t, target[:, 0, 6])
    wt = np.concatenate([tip, phi[..., snake_params.SCP_INDEX : snake_params.SCP_INDEX + 1]], -1)

    p = {k: jnp.asarray(v) for k, v in params.items()}
    err, V, margin = _limit_signals(p, jnp.asarray(wt), jnp.asarray(phi), jnp.asarray(grounded),
                                    jnp.asarray(target[:, 0]), point)
    modes = np.asarray(snake_params.MODES)
    sigma = 1 + np.argmax(np.all(grounded[..., None, :] == modes, axis=-1), axis=-1)
    t = np.broadcast_to(times, (n, times.size))
    return {
        "t": t,
        "w": tip,
        "phi": phi,
        "error": np.asarray(err),
        "V": np.asarray(V),
        "margin": np.asarray(margin),
        "limit_ratio": np.asarray(
            jax.vmap(control.limit_ratio)(jnp.asarray(phi.reshape(-1, snake_params.N_PHI)))
        ).reshape(n, -1),
        "sigma": sigma,
        "slip": np.asarray(res.records["slip"])[:, keep],
    }
