"""`snake.reach`: T² Snake-3's gripper tip reaching a displaced target under the
task-space controller with feedback of the measured tip pose (Eqs. 12-15; `sim_control`,
`feedback=True`), simulated in MuJoCo, against the task gain K of Eq. 13 (`gain_k`, 1/s)
and k_eta; a sweep analysis on native MuJoCo (`mujoco.batch` on every core) or MJX
(fixed parameter `backend`), and the experiment that the MJX tuning objective
`snake.reach_gain` (`mjx_tuning`) differentiates.

The experiment ("reach"; a short version of the paper's Table III displacement runs,
Sec. V-A, with the gripper tip controlled instead of the head):
  * the robot starts in the posture of Sec. V-A (`params.INITIAL_PHI`, fixing state sigma
    = 1: base pairs 3 and 6 lifted) and settles for `settle` s with its servos holding
    that posture and the wheels at rest (the gripper tip sags by 8 cm and pitches down
    by 0.22 rad, then the head part rings down slowly on its soft servos). The settling
    runs once, in MuJoCo's C code (`settled_state`), and the reach starts from the
    settled state at t = 0 (it does not depend on the controller's gains);
  * the controller starts from the settled state: its joint targets are the held posture
    (the servos' targets of the settling), its target w~_d(0) is the measured tip pose
    and psi_3 at t = 0, so the loop starts at rest (u = 0);
  * the target tip position moves by delta = (d_x, d_y, d_z) [m] (world frame W,
    attitude and psi_3 held) along `kinsim.Target`'s smooth step, from t = t_start over
    `ramp` s; the controller feeds the target's speed forward and K times the measured
    error back.

Metrics (`reach_metrics`, from the recorded tip position every control period, 50 Hz):
the tip position error e(t) = p_tip(t) - p_target(t) [m, W]: final_error |e| at the
end, max_error (largest |e|), rms_error (root mean square over the whole run);
settle_time: from t_start until |e| stays within `settle_tol` to the end (nan: never,
within the horizon); overshoot: how far the tip goes past the target along delta, as a
fraction of |delta| (0 if it never passes); effort: the mean squared commanded joint
speed ||phi_dot_cmd||^2 [rad^2/s^2] (from the recorded joint targets); loss: what
`snake.reach_gain` minimises, mean_t |e|^2 / ERROR_SCALE^2 + w_effort * effort;
max_slip: largest lateral wheel slip [m/s]; status ok, fell or diverged.

Ground (fixed parameter): "box" is the scenario of `scenarios.snake_scenario` (a box
whose top face is z = 0; every robot geom collides); "plane" is the model that MJX can
simulate (`build_model`): MJX has no cylinder-box collision, so the ground is a plane at
z = 0 and only the wheel cylinders collide with it (the link boxes and the gripper stay
above the ground in this experiment: the base links' boxes are 1 cm above it, the head
part is raised; the two grounds' losses agree to 1e-5, e.g. 0.709427 and 0.709429 at K = 1 /s).
Same robot, masses, servos and friction otherwise. On the mjx backend the reach always
runs on "plane" (whichever `ground`): MJX's model of the box ground.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from typing import Any

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from jaxloco.analysis import Analysis, Metric, Simulation, Summary
from jaxloco.errors import SpecError
from jaxloco.robots.snake import kinsim, scenarios, sim_control, trials
from jaxloco.robots.snake import params as snake_params
from jaxloco.sim.backend import resolve
from jaxloco.sim.rollout import RolloutResult
from jaxloco.sim.scenario import Controller, InitialState, Scenario

Array = jax.Array

GROUNDS = ("box", "plane")
CONTROL_DT = 0.02  # [s] control period (50 Hz), 10 physics steps of 2 ms
SETTLE = 8.0  # [s] settling before the reach: the head part sags ~8 cm and rings down on its servos
# (2 s leave +-8 mm of bounce at the tip, 8 s less than 0.1 mm)
ERROR_SCALE = 0.01  # [m] the loss measures the tip error in units of 1 cm
DELTA_POS = ("d_x", "d_y", "d_z")

PARAMS = snake_params.PARAMETERS.select(
    "gain_k", "k_eta", "d_x", "d_y", "d_z", "t_start", "ramp", "settle_tol", "w_effort", "horizon", "settle",
    "ground", "nthread", "backend",
    # a MuJoCo reach: smaller gains and horizons than the kinematic snake.kv's
    k_eta={"hi": 10.0},
    horizon={"default": 3.0, "doc": "simulated time of the reach (after the settling)", "hi": 60.0},
    # the reach's short smooth step, swept (Table III's ramp is a fixed 4 s change)
    ramp={"default": 0.8, "doc": "duration of the target's smooth step", "lo": 0.0, "lo_open": True, "hi": 60.0,
          "sweepable": True},
    settle={"default": SETTLE, "doc": "settling time before the reach (servos holding the posture)"},
    ground={"choices": GROUNDS},
)

METRICS = (
    Metric("final_error", "tip position error |p_tip - p_target| at the end", "m"),
    Metric("max_error", "largest tip position error over the run", "m"),
    Metric("rms_error", "root mean square tip position error over the run", "m"),
    Metric("settle_time", "from t_start until the error stays within settle_tol (nan: not within the horizon)", "s"),
    Metric("overshoot", "largest travel past the target along delta / |delta| (0: none)", ""),
    Metric("effort", "mean squared commanded joint speed", "rad^2/s^2"),
    Metric("loss", "mean |e|^2 / (1 cm)^2 + w_effort * effort (the snake.reach_gain loss)", ""),
    Metric("max_slip", "largest lateral slip of a grounded wheel pair", "m/s"),
    Metric("t_diverged", "time the simulation diverged (nan: it did not)", "s"),
)
STATUSES = ("ok", "fell", "diverged")


# ------------------------------------------------------------------------------ model
def build_model(ground: str = "box") -> mujoco.MjModel:
    """The robot on flat ground (top face z = 0), geoms numbered as in
    `scenarios.build_model`: "box" is that model; "plane" is its MJX variant
    (`scenarios.mjx_variant`: the ground box a plane at z = 0, and only the wheel
    cylinders collide with it; module docstring)."""
    if ground not in GROUNDS:
        raise SpecError(f"ground: {ground!r} is not one of {', '.join(GROUNDS)}")
    return scenarios.build_model(backend="native" if ground == "box" else "mjx")[0]


@functools.lru_cache(maxsize=8)
def settled_state(ground: str = "box", settle: float = SETTLE) -> dict[str, np.ndarray]:
    """The state after `settle` s of `scenarios.snake_scenario`'s start (posture
    INITIAL_PHI, mode 1, default lift) with the servos holding that posture and the
    wheels at rest, simulated by `mujoco.mj_step` (float64): qpos, qvel, ctrl,
    mocap_pos, mocap_quat (numpy) and max_speed (largest |qvel| at the end, rad/s or
    m/s: how settled it is)."""
    m = build_model(ground)
    sc = scenarios.snake_scenario(1.0, CONTROL_DT)
    p = {k: np.asarray(v[0]) for k, v in scenarios.params_batch(1).items()}
    s0 = jax.tree_util.tree_map(np.asarray, sc.initial_state(p, jax.random.PRNGKey(0)))
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:], d.ctrl[:] = s0.qpos, s0.qvel, s0.ctrl
    d.mocap_pos[:], d.mocap_quat[:] = s0.mocap_pos, s0.mocap_quat
    mujoco.mj_forward(m, d)
    for _ in range(round(settle / m.opt.timestep)):
        mujoco.mj_step(m, d)
    return {
        "qpos": d.qpos.copy(), "qvel": d.qvel.copy(), "ctrl": d.ctrl.copy(),
        "mocap_pos": d.mocap_pos.copy(), "mocap_quat": d.mocap_quat.copy(),
        "max_speed": float(np.max(np.abs(d.qvel))),
    }


# ------------------------------------------------------------------------- controller
def reach_controller(control_dt: float = CONTROL_DT) -> Controller:
    """`sim_control.task_space_controller(control_dt, "tip", feedback=True)` started
    from a settled robot: its joint targets start at the held posture INITIAL_PHI (the
    settling's servo targets) instead of the measured, sagged joints, so that the loop
    starts at rest."""
    inner = sim_control.task_space_controller(control_dt, "tip", feedback=True)

    def init(p, obs):
        s = inner.init(p, obs)
        hold = jnp.asarray(snake_params.INITIAL_PHI, obs["phi"].dtype)
        return s._replace(policy=s.policy._replace(phi_cmd=hold), phi_target=hold)

    return Controller(init=init, step=inner.step, name="reach_fb_tip")


@functools.lru_cache(maxsize=8)
def reach_scenario(ground: str = "box", horizon: float = 3.0, settle: float = SETTLE) -> Scenario:
    """`scenarios.snake_scenario` on `build_model(ground)` driven by `reach_controller`,
    for `horizon` s from the settled state (`settled_state`), recording every control
    period. Params: `reach_params`."""
    m = build_model(ground)
    sc = scenarios.snake_scenario(horizon, CONTROL_DT, reach_controller(CONTROL_DT))
    # the scenario's indices (friction geoms, mocap rows, joints) were taken from its own model
    assert (m.ngeom, m.nq, m.nmocap, m.nu) == (sc.model.ngeom, sc.model.nq, sc.model.nmocap, sc.model.nu)
    assert all(m.geom(i).name == sc.model.geom(i).name for i in range(m.ngeom))
    s = settled_state(ground, float(settle))
    fixed = {k: s[k] for k in ("qpos", "qvel", "ctrl", "mocap_pos", "mocap_quat")}

    def initial_state(p, key):
        dtype = jnp.result_type(p["gain"], float)
        return InitialState(**{k: jnp.asarray(v, dtype) for k, v in fixed.items()})

    return sc.with_(model=m, initial_state=initial_state, name=f"snake.reach_{ground}")


def reach_params(n: int = 1, *, gain_k: Any = 1.0, k_eta: Any = 0.1, d_x: Any = 0.0, d_y: Any = 0.0,
                 d_z: Any = 0.03, t_start: Any = 0.1, ramp: Any = 0.8) -> dict[str, Array]:
    """The simulation params (batch of n, `sim_control.params_batch`) of a reach: K =
    gain_k [1/s], k_eta, the tip displacement (d_x, d_y, d_z) [m] from t_start [s]
    over ramp [s]; everything else at the controller's and scenario's defaults."""
    return sim_control.params_batch(n, gain=gain_k, k_eta=k_eta, d_x=d_x, d_y=d_y, d_z=d_z, t0=t_start, duration=ramp)


# ---------------------------------------------------------------------------- metrics
def reach_metrics(tip: Array, phi_cmd: Array, delta: Array, t_start: Array, ramp: Array, settle_tol: Array,
                  w_effort: Array, control_dt: float = CONTROL_DT) -> dict[str, Array]:
    """The module docstring's metrics of ONE simulation from its records every control
    period from t = 0: tip (n, 6) the measured gripper-tip pose [m, rad] (record 0 is
    the controller's start, so p_target(0) = tip[0, :3]), phi_cmd (n, 12) the joint
    targets [rad]; delta (3,) [m, W]; t_start, ramp, settle_tol as in PARAMS. Pure JAX
    (jit, vmap, jvp); loss, rms_error, final_error and effort are smooth in the records."""
    dtype = tip.dtype
    n = tip.shape[0]
    t = jnp.arange(n, dtype=dtype) * control_dt
    delta = jnp.asarray(delta, dtype)
    z = jnp.zeros(4, dtype)
    target = kinsim.Target(jnp.zeros(7, dtype), jnp.concatenate([delta, z]), jnp.asarray(t_start, dtype),
                      jnp.asarray(ramp, dtype))
    moved = jax.vmap(lambda ti: target.at(ti)[0][:3])(t)  # the target's displacement at t (the controller's)
    e = tip[:, :3] - (tip[0, :3] + moved)
    e2 = jnp.sum(e * e, -1)
    err = jnp.sqrt(e2 + jnp.finfo(dtype).tiny)
    rate = jnp.diff(phi_cmd, axis=0) / control_dt
    effort = jnp.mean(jnp.sum(rate * rate, -1))
    loss = jnp.mean(e2) / ERROR_SCALE**2 + w_effort * effort
    # settle time: the first record after the last one outside the band (from t_start on)
    after = t >= t_start - 1e-9
    out = after & (err > settle_tol)
    last_out = jnp.max(jnp.where(out, jnp.arange(n), -1))
    first_in = jnp.maximum(last_out + 1, jnp.argmax(after))
    settled = last_out < n - 1
    settle_time = jnp.where(settled, t[jnp.minimum(first_in, n - 1)] - t_start, jnp.nan)
    size = jnp.sqrt(jnp.sum(delta * delta))
    unit = delta / jnp.where(size > 0, size, 1.0)
    travel = (tip[:, :3] - tip[0, :3]) @ unit
    overshoot = jnp.where(size > 0, jnp.maximum(jnp.max(travel) - size, 0.0) / jnp.where(size > 0, size, 1.0), 0.0)
    return {
        "final_error": err[-1],
        "max_error": jnp.max(err),
        "rms_error": jnp.sqrt(jnp.mean(e2)),
        "settle_time": settle_time,
        "overshoot": overshoot,
        "effort": effort,
        "loss": loss,
    }



_batched_metrics = jax.jit(jax.vmap(reach_metrics, in_axes=(0, 0, 0, 0, 0, 0, 0)))


def params(values: Mapping[str, Any], keys: np.ndarray) -> dict[str, Any]:
    """One reach per row from the settled state: its gains and target."""
    v = {k: np.asarray(values[k], float) for k in ("gain_k", "k_eta", *DELTA_POS, "t_start", "ramp")}
    return reach_params(keys.shape[0], **v)


def metrics(values: Mapping[str, Any], result: RolloutResult) -> dict[str, np.ndarray]:
    """Each row's tracking metrics (`reach_metrics`), slip and status."""
    v = {k: np.asarray(values[k], float) for k in (*DELTA_POS, "t_start", "ramp", "settle_tol", "w_effort")}
    delta = np.stack([v[k] for k in DELTA_POS], -1)
    m = _batched_metrics(jnp.asarray(result.records["tip"]), jnp.asarray(result.records["phi_cmd"]),
                         jnp.asarray(delta), jnp.asarray(v["t_start"]), jnp.asarray(v["ramp"]),
                         jnp.asarray(v["settle_tol"]), jnp.asarray(v["w_effort"]))
    out = {k: np.asarray(x, float) for k, x in m.items()}
    out["max_slip"] = np.asarray(result.metrics["max_slip"], float)
    out["t_diverged"] = result.t_diverged
    out["status"] = trials.status(result.diverged, result.metrics["fell"])
    return out


def _reach_scenario(plain: Mapping[str, Any]) -> Scenario:
    """The reach of a sweep; on MJX on "plane" (its model of either ground: module docstring)."""
    ground = "plane" if resolve(str(plain["backend"])) == "mjx" else str(plain["ground"])
    return reach_scenario(ground, float(plain["horizon"]), float(plain["settle"]))


def summarize(table) -> Summary:
    """One line per row, grouped by target: K, errors [mm], settle time, overshoot, loss, status."""
    cols = {k: np.asarray(v) for k, v in table.to_pydict().items()}
    n = len(cols["gain_k"])
    order = sorted(range(n), key=lambda i: (cols["d_x"][i], cols["d_y"][i], cols["d_z"][i], cols["gain_k"][i],
                                            cols["k_eta"][i]))

    def mm(x: float) -> str:
        return "-" if not np.isfinite(x) else f"{1e3 * x:.1f}"

    rows = []
    for i in order:
        target = ",".join(f"{1e3 * cols[k][i]:+.0f}" for k in DELTA_POS)
        settle = cols["settle_time"][i]
        rows.append((
            target, f"{cols['gain_k'][i]:g}", f"{cols['k_eta'][i]:g}", mm(cols["final_error"][i]),
            mm(cols["max_error"][i]), mm(cols["rms_error"][i]), "-" if not np.isfinite(settle) else f"{settle:.2f}",
            f"{100 * cols['overshoot'][i]:.0f}", f"{cols['loss'][i]:.3f}", str(cols["status"][i]),
        ))
    ground = str(cols["ground"][0]) if "ground" in cols and n else "box"
    horizon = float(cols["horizon"][0]) if "horizon" in cols and n else float("nan")
    on_mjx = "backend" in cols and n and str(cols["backend"][0]) == "mjx"
    simulator = "MJX, plane ground" if on_mjx else f"native MuJoCo, {ground} ground"
    return Summary(
        title=f"T² Snake-3 gripper-tip reach, feedback task-space control ({simulator}, {horizon:g} s)",
        columns=("target dx,dy,dz [mm]", "K [1/s]", "k_eta", "final [mm]", "max [mm]", "rms [mm]", "settle [s]",
                 "overshoot %", "loss", "status"),
        rows=tuple(rows),
        notes=(
            ("errors: |p_tip - p_target| of the gripper tip [mm]; settle: from t_start until it stays within "
             "settle_tol ('-': not within the horizon); loss: the snake.reach_gain loss over this horizon"),
            ("K = 1 /s: control.py's default (the paper gives none); `jaxloco tune "
             "jaxloco/specs/snake_reach_gain_tune.toml` tunes it through MJX"),
        ),
    )


REACH = Analysis(
    name="snake.reach",
    doc="T² Snake-3 gripper tip reaching a displaced target under feedback task-space control (MuJoCo or MJX): "
    "tip errors, settle time and overshoot against the task gain K.",
    params=PARAMS,
    metrics=METRICS,
    simulate=Simulation(_reach_scenario, params, metrics),
    statuses=STATUSES,
    summarize=summarize,
    x64=True,
)
