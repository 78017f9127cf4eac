"""`snake.kv`: T² Snake-3 joint-limit avoidance (Tanaka et al. 2019, Sec. IV-C5, V-B)
in the pure-JAX kinematic simulation (`kinsim`), against the cost weights K_V, the
null-space gain k_eta, the wheels' weight in W (`w_wheel`), the task gain K, the
switching period Delta T and the order of the switching modes, as a sweep analysis;
and the smooth loss that `jaxloco tune` minimises (`limit_loss`, objective `snake.kv`
in `tuning`).

The question it answers: from the zigzag posture with the base joints at 97 % of their
limits (Fig. 8), which weights bring the base back from the limits fastest while the
gripper tip stays where it is (head error) and the robot keeps a support margin?

One row is `experiments`' joint-limit setup: zigzag amplitude `amplitude`, gripper tip
held, psi_3 -> 110 deg, fixing state (sigma = 1) until `switch_at`, then modes
`mode_order` every `delta_t`; K_V = `control.kv_diagonal(kv_head_yaw, kv_head_pitch,
kv_base, kv_ratio)` (the paper: 15, 0.015, 9.6, 0.5); Eq. 20's support term with weight
`a2` (0: Eq. 19); joints limited to `joint_speed_max`. The horizon is `horizon` s in
steps of `dt` (feedforward control, as the paper's robot).

Metrics: `experiments.limit_metrics` (recovery_time, recovered, V0, final_V,
max_pos_error, max_att_error, min_margin, time_near_limit, order_score) plus final_margin (static
margin at the end [m]), final_area (area of the convex hull of all 14 base wheel
contacts at the end, whatever the mode [m^2]: the footprint Eq. 20 should widen),
head_ok (max_pos_error <= 30 mm and max_att_error <= 0.1 rad: the paper's "about 30 mm
and 0.1 rad"), and loss (`limit_loss`, smooth; what tuning minimises).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco import geometry as geo
from jaxloco.analysis import Analysis, Metric, Summary
from jaxloco.robots.snake import control, experiments, kinematics, kinsim, params

MODE_ORDERS = control.MODE_ORDERS
POS_TOL, ATT_TOL = experiments.PAPER_HEAD_ERROR  # 0.03 m, 0.1 rad

PARAMS = params.PARAMETERS.select(
    "kv_head_yaw", "kv_head_pitch", "kv_base", "kv_ratio", "k_eta", "w_wheel", "gain", "delta_t", "mode_order",
    "switch_at",
    "a2", "amplitude", "joint_speed_max", "recover_ratio", "w_limit", "horizon", "dt", "feedback",
)

METRICS = (
    Metric("recovery_time", "first time every base joint is below recover_ratio of its limit (horizon + dt if never)",
           "s"),
    Metric("recovered", "the base joints came below recover_ratio of their limits", kind="bool"),
    Metric("V0", "cost V at t = 0 (Eq. 19 / 20)"),
    Metric("final_V", "cost V at the end"),
    Metric("max_pos_error", "largest gripper-tip position error", "m"),
    Metric("max_att_error", "largest gripper-tip attitude error (norm of roll, pitch, yaw errors)", "rad"),
    Metric("max_pos_component_error", "largest single component (x, y or z) of the gripper-tip position error: "
           "as read off plots of the components (the paper's Fig. 9)", "m"),
    Metric("max_att_component_error", "largest single component (roll, pitch or yaw) of the attitude error", "rad"),
    Metric("head_ok", "max_pos_error <= 30 mm and max_att_error <= 0.1 rad (the paper's figures)", kind="bool"),
    Metric("min_margin", "smallest static stability margin of the grounded wheels' support polygon", "m"),
    Metric("final_margin", "static stability margin at the end", "m"),
    Metric("final_area", "area of the base's footprint at the end: the convex hull of all 14 base wheel contacts "
           "(mode-independent; the straight base is the smallest)", "m^2"),
    Metric("time_near_limit", "time with some base joint at >= 95 % of its limit", "s"),
    Metric("order_score", "order in which theta_4..theta_9 come below recover_ratio of their limits for good: "
           "+1 from the tail to the head (the paper's Fig. 10), -1 from the head to the tail "
           "(experiments.release_order_score)"),
    Metric("loss", "the tuning loss (limit_loss): head-error term + w_limit * near-limit term"),
)

STATUSES = (
    "ok",
    "failed: base joints not recovered within the horizon",
    "failed: head error above 30 mm / 0.1 rad",
    "diverged: non-finite state",
)

_KV_NAMES = ("kv_head_yaw", "kv_head_pitch", "kv_base", "kv_ratio")


def control_params(values: Mapping[str, jax.Array]) -> control.ControlParams:
    """`ControlParams` of one row (values: scalar arrays of the sweepable parameters)."""
    dtype = jnp.asarray(values["k_eta"]).dtype
    kv = control.kv_diagonal(*(values[n] for n in _KV_NAMES))
    order = jnp.asarray(MODE_ORDERS)[jnp.asarray(values["mode_order"], jnp.int32)]
    return experiments.limit_params(
        kv=kv.astype(dtype),
        k_eta=values["k_eta"],
        gain=jnp.full(control.N_TASK, values["gain"], dtype),
        delta_t=values["delta_t"],
        mode_order=order,
        switch_at=values["switch_at"],
        a2=values["a2"],
        weights=control.default_weights(w_wheel=values["w_wheel"]).astype(dtype),
    )


def limit_loss(recs: Mapping[str, jax.Array], recover_ratio: jax.Array, w_limit: jax.Array,
               temperature: float = 0.02) -> jax.Array:
    """Smooth tuning loss of a joint-limit rollout:
        mean_t [ (|e_p| / 30 mm)^2 + (|e_a| / 0.1 rad)^2 ]
        + w_limit * mean_t sum_j T softplus((|theta_j| / limit - recover_ratio) / T) / (1 - recover_ratio)
    e_p, e_a: the gripper tip's position and attitude errors (scaled by the paper's
    figures), theta_j the base yaw joints (temperature T): the first term is the head
    error, the second a smooth count of base joints above recover_ratio of their limit
    (about 1 per joint at the limit), averaged over time."""
    pos = jnp.sum(recs["error"][:, :3] ** 2, axis=-1) / POS_TOL**2
    att = jnp.sum(recs["error"][:, 3:6] ** 2, axis=-1) / ATT_TOL**2
    ratio = jnp.abs(recs["phi"][:, params.N_H :]) / params.YAW_LIMIT
    excess = temperature * jax.nn.softplus((ratio - recover_ratio) / temperature) / (1.0 - recover_ratio)
    return jnp.mean(pos + att) + w_limit * jnp.mean(jnp.sum(excess, axis=-1))


def rollout_config(horizon: float, dt: float, feedback: bool) -> kinsim.RolloutConfig:
    return kinsim.RolloutConfig(steps=round(horizon / dt) + 1, dt=dt, point="tip", feedback=bool(feedback))


def run_one(values: Mapping[str, jax.Array], config: kinsim.RolloutConfig) -> tuple[dict[str, jax.Array], dict]:
    """(metrics with status, records) of one row (scalar values of every sweepable
    parameter)."""
    dtype = jnp.asarray(values["k_eta"]).dtype
    x0, target = experiments.limit_setup(values["amplitude"], dtype)
    cp = control_params(values)
    plant = kinsim.PlantParams(joint_speed_max=values["joint_speed_max"])
    recs = kinsim.rollout(x0, target, cp, config, plant)
    m = experiments.limit_metrics(recs, values["recover_ratio"])
    w_h = kinematics.point_to_head(recs["w"][-1], "tip")
    joints = kinematics.full_joint_angles(recs["phi"][-1])
    pts = kinematics.wheel_contacts(w_h, joints).reshape(-1, 3)[:, :2]
    verts, valid = geo.convex_hull(pts, jnp.ones(pts.shape[0], bool))
    m["final_margin"] = recs["margin"][-1]
    m["final_area"] = geo.polygon_area(verts, valid)
    m["head_ok"] = (m["max_pos_error"] <= POS_TOL) & (m["max_att_error"] <= ATT_TOL)
    m["loss"] = limit_loss(recs, values["recover_ratio"], values["w_limit"])
    finite = jnp.all(jnp.isfinite(recs["phi"])) & jnp.all(jnp.isfinite(recs["w"]))
    m["status"] = jnp.where(
        ~finite, 3, jnp.where(~m["recovered"], 1, jnp.where(~m["head_ok"], 2, 0))
    ).astype(jnp.int32)
    return m, recs


def row(values: Mapping[str, Any], key: jax.Array) -> dict[str, jax.Array]:
    """`Analysis.row`: metrics and status of one row; horizon, dt and feedback are plain
    values (static). No randomness: the key is unused."""
    return run_one(values, rollout_config(values["horizon"], values["dt"], values["feedback"]))[0]


# ---------------------------------------------------------------------------- summary
def summarize(table) -> Summary:
    """The rows ranked: ok rows (recovered with the head within 30 mm / 0.1 rad) by
    recovery time, then the rest by loss; the first 10 and the paper's K_V row."""
    cols = {k: np.asarray(v) for k, v in table.to_pydict().items()}
    n = len(cols["loss"])
    ok = np.asarray(cols["status"]) == "ok"
    order = sorted(range(n), key=lambda i: (not ok[i], cols["recovery_time"][i] if ok[i] else cols["loss"][i]))
    paper = [
        i
        for i in range(n)
        if all(
            np.isclose(cols[k][i], d)
            for k, d in params.PARAMETERS.defaults(_KV_NAMES + ("k_eta", "w_wheel")).items()
            if k in cols  # tables written before w_wheel existed lack it
        )
    ]
    shown = order[:10] + [i for i in paper[:1] if i not in order[:10]]
    varying = [p.name for p in PARAMS if p.name in cols and len(set(np.asarray(cols[p.name]).tolist())) > 1]
    rows = []
    for i in shown:
        cells = [("paper " if i in paper else "") + str(i)]
        cells += [f"{cols[k][i]:g}" for k in varying]
        cells += [
            f"{cols['recovery_time'][i]:.1f}",
            f"{1e3 * cols['max_pos_error'][i]:.1f}",
            f"{cols['max_att_error'][i]:.3f}",
            f"{1e3 * cols['min_margin'][i]:.0f}",
            f"{cols['order_score'][i]:+.2f}",
            f"{cols['loss'][i]:.3f}",
        ]
        rows.append(tuple(cells))
    short = {"kv_head_yaw": "kv yaw", "kv_head_pitch": "kv pitch", "kv_base": "kv base", "kv_ratio": "ratio",
             "mode_order": "mode order"}
    return Summary(
        title=f"T² Snake-3 joint-limit avoidance: {int(ok.sum())}/{n} rows recovered with the head held",
        columns=("row", *(short.get(k, k) for k in varying), "recov. [s]", "tip err [mm]", "att err",
                 "margin [mm]", "joints' order", "loss"),
        rows=tuple(rows),
        notes=(
            ("ok = base joints below recover_ratio of their limits within the horizon and gripper-tip error "
             "<= 30 mm / 0.1 rad (the paper's Fig. 9 figures); ok rows first by recovery time, then the rest by "
             "loss; margin = smallest static margin [mm]; joints' order = order_score, +1 when theta_9 .. "
             "theta_4 leave their limits in that order (from the tail to the head, as the paper's Fig. 10)"),
            "paper K_V = diag(15, 0.015, 15, 0.015, 15, 0.015, 9.6, 4.8, 2.4, 1.2, 0.6, 0.3); k_eta = 0.1 and "
            "W = diag(l^2, w_wheel r^2) with w_wheel = 1 are ours (the paper gives neither)",
        ),
    )


KV = Analysis(
    name="snake.kv",
    doc="T² Snake-3 joint-limit avoidance by mode switching (kinematic simulation): recovery time, final V, "
    "head error and support margin against K_V, k_eta, K, Delta T and the mode order",
    params=PARAMS,
    metrics=METRICS,
    row=row,
    statuses=STATUSES,
    summarize=summarize,
    x64=True,
)
