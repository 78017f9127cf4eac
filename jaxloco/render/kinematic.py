"""Replays of kinematic analyses: the row's trajectory from the robot's own JAX code,
written into its MJCF model's qpos (and the terrain's mocap poses) frame by frame.

* `titan.stride`: the row's gait plan (the analysis' `row_plan`: `gait.plan_cycles` on
  the row's frame grid map) animated step by step: a COG shift moves the body
  along a smoothstep, a swing moves the foot through the planner's rectangular swing
  waypoints (`GaitPlan.swing_path`); leg joints from `kinematics.legs_inverse_kinematics`
  of the foot centres (ground point + foot radius along the slope normal) in the body
  frame. The body keeps the slope's attitude (the planner's yaw is 0). Time: the
  footstep executor's nominal `step_time` (3 s) per step. The frames of the map are
  drawn as beams (`jaxloco.sim.terrain.frames_on_slope`, same centre lines: the plan is
  shifted by whole frame intervals towards the origin, which the periodic map allows).
* `snake.kv`: the row's kinematic rollout (`analysis.run_one`: base pose and phi every
  control period) as the MJCF posture with the base flat on the ground
  (`kinematics.base_frame_pose`, as `model.pose_qpos_ctrl`); a red sphere marks the
  gripper-tip target.
* `leggrope.slope_cycle`: the row's cycle plan (`gait.plan_cycle`) sampled at every QP
  step (`gait.pose_at`), joints by `control.joint_targets`, on the row's slope.

Each replay recomputes some of the row's metrics from its own trajectory (titan: the
plan's metrics; snake: every metric; leg-grope: the plan margin), so a mismatch with the
table shows.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco.errors import SpecError
from jaxloco.render.replay import Replay, model_copy
from jaxloco.render.rows import Row

F64 = jnp.float64


def plain_data(tree: Mapping[str, Any]) -> dict[str, Any]:
    return {k: np.asarray(v).item() for k, v in tree.items()}


def _smooth(s: np.ndarray) -> np.ndarray:
    s = np.clip(s, 0.0, 1.0)
    return s * s * (3.0 - 2.0 * s)


def _polyline(points: np.ndarray, s: float) -> np.ndarray:
    """The point at arc-length fraction s in [0, 1] along the polyline `points` (K, 3)."""
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    total = seg.sum()
    if total <= 0.0:
        return points[-1].copy()
    target = s * total
    edges = np.concatenate([[0.0], np.cumsum(seg)])
    k = int(np.clip(np.searchsorted(edges, target, side="right") - 1, 0, len(seg) - 1))
    u = (target - edges[k]) / seg[k] if seg[k] > 0 else 1.0
    return points[k] + u * (points[k + 1] - points[k])


# ------------------------------------------------------------------------------ TITAN
TITAN_REACH = 12.0  # [m] the drawn frames reach at least this far from the origin


@functools.lru_cache(maxsize=8)
def _titan_model(frame_size: float, interval: float):
    """TITAN XI (`models/titan_xi.xml`) on frames of `frame_size` every `interval` m
    (a plain slope when frame_size is 0): (model, terrain)."""
    from jaxloco.robots.titan import model as titan_model
    from jaxloco.sim import terrain as tr

    spec = titan_model.load_spec()
    if frame_size > 0:
        count = 2 * math.ceil(TITAN_REACH / interval)
        terrain = tr.frames_on_slope(nx=count, ny=count, beam_width=frame_size, max_spacing=interval,
                                     max_beam_height=max(frame_size, 0.05), half_length=TITAN_REACH + 6.0,
                                     half_width=TITAN_REACH + 6.0)
    else:
        terrain = tr.slope(TITAN_REACH + 6.0, TITAN_REACH + 6.0)
    terrain.add_to(spec)
    return spec.compile(), terrain


def titan_plan(values: Mapping[str, Any]):
    """(start, plan, map, metrics) of a `titan.stride` row, from the analysis' own
    `row_plan` (the plan its metrics come from)."""
    from jaxloco.analysis import row_arrays
    from jaxloco.robots.titan import analysis

    arrays, static = row_arrays(analysis.STRIDE, values)
    params, gmap, start, plan = jax.jit(lambda a: analysis.row_plan({**static, **a}))(arrays)
    metrics = analysis.plan_metrics(plan, params.s_ne_c, arrays["softmin_tau"])
    return start, plan, gmap, metrics


def titan_stride(row: Row, frames_per_step: int | None = None) -> Replay:
    """`titan.stride` (module docstring)."""
    from jaxloco.robots.titan import analysis, kinematics
    from jaxloco.robots.titan import control as titan_control
    from jaxloco.robots.titan import model as titan_model
    from jaxloco.robots.titan import params as titan_params
    from jaxloco.sim import terrain as tr

    values = row.values
    if float(values.get("mix_block", 0.0)) > 0:
        raise SpecError("titan.stride: rendering a mixed field (mix_block > 0) is not supported; "
                        "plot the plan with jaxloco.robots.titan.plots instead")
    start, plan, _, metrics = titan_plan(values)
    status = analysis.STATUSES[int(metrics.pop("status"))]
    metrics = plain_data(metrics)
    feet = np.concatenate([np.asarray(start.feet)[None], np.asarray(plan.feet)])  # (S+1, 4, 3) map frame
    cog = np.concatenate([np.asarray(start.cog)[None], np.asarray(plan.cog)])  # (S+1, 3)
    swing = np.asarray(plan.swing_leg, int)
    ways = np.asarray(plan.swing_path, float)
    nesm = np.asarray(plan.nesm, float)
    n_steps = swing.shape[0]
    per = frames_per_step or max(2, 150 // max(n_steps, 1))

    frame_size, interval = float(values["frame_size"]), float(values["frame_interval"])
    slope = float(values["slope"])
    shift = np.zeros(3)
    shift[:2] = np.round(cog[:, :2].mean(axis=0) / interval) * interval  # whole intervals: same frame lines
    c, s = math.cos(slope), math.sin(slope)
    rot = np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])  # maps.map_to_world: rot_y(-slope)
    normal = rot[:, 2]
    body_quat = np.asarray(titan_control.body_quat(slope, 0.0, 0.0), float)

    model, terrain = _titan_model(frame_size, interval)
    model = model_copy(model)
    place = {"theta": slope, "direction": 0.0}
    if frame_size > 0:
        place.update(spacing=interval, beam_height=frame_size)
    pos, quat = (np.asarray(x, float) for x in terrain.place(place))
    rows = tr.mocap_ids(model, terrain)
    mocap_pos = np.zeros((model.nmocap, 3))
    mocap_quat = np.tile([1.0, 0.0, 0.0, 0.0], (model.nmocap, 1))
    mocap_pos[rows], mocap_quat[rows] = pos, quat

    bodies, feet_t, captions, times = [], [], [], []
    names = titan_params.LEG_NAMES
    step_time = titan_params.PARAMETERS.default("step_time")  # [s] the footstep executor's nominal step
    for k in range(-1, n_steps):
        subs = [1.0] if k < 0 else [(j + 1) / per for j in range(per)]
        for u in subs:
            if k < 0:
                body, foot = cog[0], feet[0].copy()
                text = "standard start"
            else:
                body = cog[k] + _smooth(u) * (cog[k + 1] - cog[k])
                foot = feet[k].copy()
                if swing[k] >= 0:
                    foot[swing[k]] = _polyline(ways[k], float(_smooth(u)))
                    what = f"swing {names[swing[k]]}"
                else:
                    what = "COG shift"
                cyc = k // 6
                text = f"cycle {cyc + 1} step {k % 6 + 1}/6: {what}  NESM {nesm[k]:.3f} m"
            bodies.append(body)
            feet_t.append(foot)
            captions.append(text)
            times.append((k + u) * step_time if k >= 0 else 0.0)
    bodies = (np.asarray(bodies) - shift) @ rot.T
    feet_w = (np.asarray(feet_t) - shift) @ rot.T + kinematics.FOOT_RADIUS * normal
    R = tr.quat_to_matrix(jnp.asarray(body_quat))
    local = np.einsum("ji,tlj->tli", np.asarray(R), feet_w - bodies[:, None, :])
    q, _ = jax.vmap(kinematics.legs_inverse_kinematics)(jnp.asarray(local))
    q = np.asarray(q)
    qpos = np.stack([titan_model.pose_qpos_ctrl(model, q[t], bodies[t], body_quat)[0] for t in range(len(bodies))])
    n = qpos.shape[0]
    return Replay(
        row=row, model=model, qpos=qpos, times=np.asarray(times), metrics=metrics, status=status,
        headline=("min_nesm", "distance_per_cycle", "n_failures", "nesm_ok"), kind="kinematic gait plan",
        mocap_pos=np.broadcast_to(mocap_pos, (n, *mocap_pos.shape)).copy(),
        mocap_quat=np.broadcast_to(mocap_quat, (n, *mocap_quat.shape)).copy(),
        captions=captions, camera={"azimuth": 135.0, "elevation": -25.0, "distance": 16.0},
    )


# ------------------------------------------------------------------------------ snake
@functools.lru_cache(maxsize=1)
def _snake_model():
    from jaxloco.robots.snake import scenarios

    return scenarios.build_model()


def snake_rollout(values: Mapping[str, Any]) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """(metrics with status code, records) of a `snake.kv` row (`analysis.run_one`)."""
    from jaxloco.analysis import row_arrays
    from jaxloco.robots.snake import analysis

    config = analysis.rollout_config(values["horizon"], values["dt"], values["feedback"])
    arrays, _ = row_arrays(analysis.KV, values)
    metrics, recs = jax.jit(lambda x: analysis.run_one(x, config))(arrays)
    return metrics, {k: np.asarray(r) for k, r in recs.items()}


def snake_qpos(model: Any, base: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """qpos (T, nq) of postures phi (T, 12) with the base flat on the ground at base
    (T, 3) = [x, y, heading] of link 7 (`model.pose_qpos_ctrl`, vectorised)."""
    from jaxloco.robots.snake import kinematics
    from jaxloco.robots.snake import model as snake_model
    from jaxloco.robots.snake import params as snake_params

    w_h = np.asarray(jax.vmap(kinematics.base_frame_pose)(jnp.asarray(base, F64), jnp.asarray(phi, F64)))
    joints = np.asarray(jax.vmap(kinematics.full_joint_angles)(jnp.asarray(phi, F64)))
    qpos = np.tile(model.qpos0, (base.shape[0], 1))
    qpos[:, :3] = w_h[:, :3]
    qpos[:, 3:7] = snake_model.rpy_to_quat(w_h[:, 3:].T).T
    adr = [model.joint(name).qposadr[0] for name in snake_params.JOINT_NAMES]
    qpos[:, adr] = joints
    return qpos


def snake_kv(row: Row) -> Replay:
    """`snake.kv` (module docstring)."""
    from jaxloco.robots.snake import analysis, experiments

    values = row.values
    metrics, recs = snake_rollout(values)
    status = analysis.STATUSES[int(metrics.pop("status"))]
    model, _ = _snake_model()
    model = model_copy(model)
    qpos = snake_qpos(model, recs["base"], recs["phi"])
    _, target = experiments.limit_setup(values["amplitude"], F64)
    tip_target = np.asarray(target.w0[:3], float)
    err = np.linalg.norm(recs["error"][:, :3], axis=1)
    captions = [f"mode {int(sg)}  max |phi|/limit {lr:.2f}  tip error {1e3 * e:.1f} mm"
                for sg, lr, e in zip(recs["sigma"], recs["limit_ratio"], err)]
    n = qpos.shape[0]
    return Replay(
        row=row, model=model, qpos=qpos, times=recs["t"], metrics=plain_data(metrics), status=status,
        headline=("recovery_time", "max_pos_error", "min_margin", "time_near_limit"),
        kind="kinematic simulation", captions=captions,
        markers=np.broadcast_to(tip_target, (n, 1, 3)).copy(), marker_size=0.015,
        camera={"azimuth": 250.0, "elevation": -50.0, "distance": 1.8},
    )


# -------------------------------------------------------------------------- leg-grope
@functools.lru_cache(maxsize=1)
def _leggrope_model():
    from jaxloco.robots.leggrope import model as lg_model
    from jaxloco.sim import terrain as tr

    spec = lg_model.load_spec()
    terrain = tr.slope(1.5, 1.0)
    terrain.add_to(spec)
    return spec.compile(), terrain


def leggrope_cycle(values: Mapping[str, Any], key: np.ndarray):
    """(plan, body (N, 3), toes (N, 4, 3), info) of a `leggrope.slope_cycle` row: the
    plan of `forces.simulate_cycle` and the pose at the end of each of its QP steps."""
    from jaxloco.analysis import row_arrays
    from jaxloco.robots.leggrope import analysis, gait

    arrays, static = row_arrays(analysis.SLOPE_CYCLE, values)
    config, _ = analysis.walk_config(values)
    dt = float(values["dt"])

    @jax.jit
    def run(arrays, key):
        params, walk, terrain, _, _ = analysis.row_setup({**static, **arrays}, key)
        plan = gait.plan_cycle(params, walk, terrain, config)

        def pose(i):
            info = gait.step_info(i, config, dt)
            body, toes = gait.pose_at(params, walk, plan, info, info.tau, config)
            return body, toes, info.grope, info.leg, info.phase

        return params, plan, jax.vmap(pose)(jnp.arange(config.n_steps))

    params, plan, (body, toes, grope, leg, phase) = run(arrays, jnp.asarray(key))
    return params, plan, np.asarray(body), np.asarray(toes), (np.asarray(grope), np.asarray(leg), np.asarray(phase))


def leggrope_slope_cycle(row: Row) -> Replay:
    """`leggrope.slope_cycle` (module docstring)."""
    import mujoco

    from jaxloco.robots.leggrope import control, gait
    from jaxloco.robots.leggrope import model as lg_model
    from jaxloco.robots.leggrope.params import LEG_NAMES
    from jaxloco.sim import terrain as tr

    values = row.values
    params, plan, body, toes, (grope, leg, phase) = leggrope_cycle(values, row.key)
    R = np.asarray(plan.R_GR)
    q = np.asarray(jax.vmap(lambda b, t: control.joint_targets(params, plan.R_GR, b, t))(
        jnp.asarray(body), jnp.asarray(toes)))
    model, terrain = _leggrope_model()
    model = model_copy(model)
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, R.reshape(-1))
    b0 = np.concatenate([body[:1], body])
    q0 = np.concatenate([q[:1], q])
    qpos = np.tile(model.qpos0, (b0.shape[0], 1))
    qpos[:, :3] = b0
    qpos[:, 3:7] = quat
    adr = [model.joint(f"{l}_{j}").qposadr[0] for l in LEG_NAMES for j in lg_model.JOINTS]
    qpos[:, adr] = q0
    n = qpos.shape[0]
    pos, quat_t = (np.asarray(x, float) for x in terrain.place({"theta": values["theta"], "direction": 0.0}))
    rows = tr.mocap_ids(model, terrain)
    mocap_pos = np.zeros((model.nmocap, 3))
    mocap_quat = np.tile([1.0, 0.0, 0.0, 0.0], (model.nmocap, 1))
    mocap_pos[rows], mocap_quat[rows] = pos, quat_t
    dt = float(values["dt"])
    times = np.arange(n) * dt
    captions = ["start"] + [f"grope {g + 1}/4 {LEG_NAMES[l]}  phase {gait.PHASES[p]}" for g, l, p in
                            zip(grope, leg, phase)]
    return Replay(
        row=row, model=model, qpos=qpos, times=times, metrics={"plan_margin": float(plan.margin)}, status=None,
        headline=("slip_free", "min_s_norm", "max_relaxation", "plan_margin"), kind="kinematic cycle plan",
        mocap_pos=np.broadcast_to(mocap_pos, (n, *mocap_pos.shape)).copy(),
        mocap_quat=np.broadcast_to(mocap_quat, (n, *mocap_quat.shape)).copy(),
        captions=captions, camera={"azimuth": 150.0, "elevation": -25.0, "distance": 0.9},
    )
