"""`snake.operations`: T² Snake-3's three operations (Sec. V-D) as perturbed trials in
MuJoCo, one row per (operation, trial): picking up a T-joint pipe, rotating a gate
valve, opening a door with a knob (`operations`), driven by the operator's script
through the teleoperator model (`operator`).

The paper reports each operation once, as photographs (Figs. 13-14), with no numbers:
so every threshold here is ours. Per row:
  * the operation's measure: pipe_lift [m] (pick), valve_turn [rad] (valve), door_max
    and door_angle [rad] (door); NaN in the other operations' columns;
  * success (ours): the pipe came up at least half the 0.1 m lift; the valve turned at
    least 75 % of the gripper's 90 deg roll; the door opened at least 1.0 rad of the 1.2
    pulled for;
  * the gripper tip's largest and final distance from the operator's intended tip
    position (`operations.tip_errors`), and whether the largest stayed below 30 mm (the
    issue's bound, the paper's positioning tolerance in Sec. V-B);
  * stalls: how often the operator commanded the switching state at a base joint's limit
    (`operator`: Fig. 14 d, f), and the time spent switching [s].

Trials: floor friction mu + U(-1, 1) mu_jitter and the robot's start shifted by U(-1,
1) place_jitter in x and y (where the operator left it in front of the object; both
ours) from each row's seed. The controller's k_eta and W's wheel weight default to
`operations.OPERATION_GAINS` (ours, chosen for the door; the other experiments keep 0.1
and 1).

Simulator (fixed parameter `backend`): native MuJoCo, or MJX on the MJX variant
(`operations`: the gripper's adhesion a pulling tendon, the ground a plane).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from jaxloco.analysis import Analysis, Metric, Summary, mean_worst
from jaxloco.robots.snake import operations, trials
from jaxloco.robots.snake import operator as snake_operator
from jaxloco.robots.snake import params as snake_params
from jaxloco.sim.rollout import Simulator
from jaxloco.sim.scenario import seed_jitter

NAMES = tuple(operations.OPERATIONS)  # ("pick", "valve", "door")
TIP_BOUND = 0.03  # [m] the tip's allowed distance from the intended position
PICK_LIFT_MIN = 0.05  # [m] success: half the script's 0.1 m lift, ours
VALVE_TURN_MIN = 0.75 * np.pi / 2  # [rad] success: 75 % of the 90 deg roll, ours
DOOR_OPEN_MIN = 1.0  # [rad] success: of the 1.2 rad the operator pulls for, ours

PARAMS = snake_params.PARAMETERS.select(
    "operation", "operator_gain", "operator_enter", "operator_exit", "operator_min_switch", "k_eta", "w_wheel", "mu",
    "mu_jitter", "place_jitter", "twist_compliance", "nthread", "backend",
    operation={"choices": NAMES},
    # the operations' controller values (`operations.OPERATION_GAINS`, default (ours), chosen for the door)
    k_eta={"default": operations.OPERATION_GAINS["k_eta"]},
    w_wheel={"default": operations.OPERATION_GAINS["w_wheel"]},
)

METRICS = (
    Metric("success", "the operation's goal reached (pick: pipe_lift >= 0.05 m; valve: valve_turn >= 75 % of 90 deg; "
           "door: door_max >= 1.0 rad; thresholds ours)", kind="bool"),
    Metric("pipe_lift", "the pipe's height gained by the end (pick; nan otherwise)", "m"),
    Metric("valve_turn", "the handwheel's angle turned by the end (valve; nan otherwise)", "rad"),
    Metric("door_max", "the widest the door opened (door; nan otherwise)", "rad"),
    Metric("door_angle", "the door's angle at the end (door; nan otherwise)", "rad"),
    Metric("max_tip_error", "largest distance of the gripper tip from the operator's intended position", "m"),
    Metric("final_tip_error", "the same at the end", "m"),
    Metric("tip_ok", "max_tip_error below 30 mm", kind="bool"),
    Metric("stalls", "times the operator commanded the switching state at a base joint's limit", kind="int"),
    Metric("switch_time", "time spent in the switching state", "s"),
    trials.T_DIVERGED,
)
STATUSES = trials.STATUSES
MEASURES = ("pipe_lift", "valve_turn", "door_max", "door_angle")


def trial_params(operation: str, values: Mapping[str, np.ndarray], keys: np.ndarray) -> dict[str, Any]:
    """Simulation params of n trials of one operation from their rows' values and PRNG keys (n, 2)."""
    op = operations.OPERATIONS[operation]
    n = keys.shape[0]
    u = seed_jitter(keys, 3)
    mu = np.maximum(np.asarray(values["mu"], float) + u[:, 0] * np.asarray(values["mu_jitter"], float), trials.MU_MIN)
    shift = u[:, 1:] * np.asarray(values["place_jitter"], float)[:, None]
    operator = {k: np.asarray(values[k], float) for k in snake_operator.PARAM_DEFAULTS if k in values}
    gains = {k: np.asarray(values.get(k, v), float) for k, v in operations.OPERATION_GAINS.items()}
    start = op.start_params(n)  # how the robot stands at the object; the jitter shifts it
    x0, y0 = start.pop("x0", 0.0) + shift[:, 0], start.pop("y0", 0.0) + shift[:, 1]
    params = operations.script_params(op.script, op.grip_at, n, mu=mu, x0=x0, y0=y0, **gains, **start, **operator)
    params["key"] = np.asarray(keys, np.uint32)
    return params


def stall_counts(switching: np.ndarray) -> np.ndarray:
    """(n,) the number of entries into the switching state of (n, T) bool records."""
    s = np.asarray(switching, bool)
    return np.sum(s[:, 1:] & ~s[:, :-1], -1) + s[:, 0]


def success(operation: str, m: Mapping[str, np.ndarray]) -> np.ndarray:
    """Whether each trial reached the operation's goal (module docstring)."""
    if operation == "pick":
        return m["pipe_lift"] >= PICK_LIFT_MIN
    if operation == "valve":
        return m["valve_turn"] >= VALVE_TURN_MIN
    return m["door_max"] >= DOOR_OPEN_MIN


def simulate(values: Mapping[str, Any], keys: np.ndarray, simulator: Simulator) -> dict[str, np.ndarray]:
    """`Analysis.simulate`: the rows of each operation in one rollout (values: (B,)
    columns of the sweepable parameters)."""
    n = keys.shape[0]
    v = {p.name: np.asarray(values[p.name]) for p in PARAMS if p.sweepable}
    names = v["operation"].astype(str)
    out = {m.name: np.full(n, np.nan) for m in METRICS}
    out["status"] = np.zeros(n, int)
    for name in NAMES:
        rows = np.flatnonzero(names == name)
        if rows.size == 0:
            continue
        op = operations.OPERATIONS[name]
        params = trial_params(name, {k: a[rows] for k, a in v.items()}, keys[rows])
        scenario = operations.operation_scenario(op.fixture, op.horizon, backend=simulator.backend,
                                                 twist_compliance=float(values["twist_compliance"]))
        res = simulator.run(scenario, params)
        m = operations.measure(op, res)
        switching = operations.switching_record(res)
        for key in (*MEASURES, "max_tip_error", "final_tip_error"):
            if key in m:
                out[key][rows] = m[key]
        out["success"][rows] = success(name, m)
        out["tip_ok"][rows] = m["max_tip_error"] < TIP_BOUND
        out["stalls"][rows] = stall_counts(switching)
        out["switch_time"][rows] = switching.sum(-1) * (res.times[1] - res.times[0])
        out["t_diverged"][rows] = res.t_diverged
        out["status"][rows] = trials.status(res.diverged, res.metrics["fell"])
    out["success"] = out["success"].astype(bool)
    out["tip_ok"] = out["tip_ok"].astype(bool)
    out["stalls"] = out["stalls"].astype(int)
    return out


def summarize(table) -> Summary:
    """Per operation and operator gain: successes, the measure, the tip errors and the
    stalls, mean (worst) over the trials."""
    cols = {n: table.column(n).to_numpy(zero_copy_only=False) for n in table.column_names}
    names = cols["operation"].astype(str)
    gains = cols["operator_gain"].astype(float)
    measure = {"pick": ("pipe_lift", "m", "min"), "valve": ("valve_turn", "rad", "min"), "door": ("door_max", "rad",
                                                                                                    "min")}
    rows = []
    for name in NAMES:
        for gain in np.unique(gains[names == name]):
            sel = (names == name) & (gains == gain)
            key, unit, worst = measure[name]
            rows.append((name, f"{gain:g}", f"{int(cols['success'][sel].sum())}/{int(sel.sum())}",
                         f"{key} [{unit}] {mean_worst(cols[key][sel], worst, 3)}",
                         mean_worst(1000 * cols["max_tip_error"][sel].astype(float), "max", 0),
                         mean_worst(1000 * cols["final_tip_error"][sel].astype(float), "max", 0),
                         f"{int(cols['tip_ok'][sel].sum())}/{int(sel.sum())}",
                         mean_worst(cols["stalls"][sel].astype(float), "max", 1)))
    return Summary(
        title="T² Snake-3 operations (Sec. V-D) in MuJoCo, the operator's script through the teleoperator model",
        columns=("operation", "operator gain [1/s]", "success", "measure mean (worst)", "max tip error [mm]",
                 "final tip error [mm]", "tip < 30 mm", "stalls"),
        rows=tuple(rows),
        notes=("mean (worst) over the trials; the paper reports one successful run of each (Figs. 13-14), no numbers",
               "operator gain 0: the paper's feedforward control alone; > 0: the operator corrects what they see"),
    )


OPERATIONS = Analysis(
    name="snake.operations",
    doc="T² Snake-3's operations (Sec. V-D: pick up a pipe, turn a valve, open a door) in MuJoCo under the operator's "
        "script and the teleoperator model: one row per (operation, perturbed trial).",
    params=PARAMS,
    metrics=METRICS,
    simulate=simulate,
    statuses=STATUSES,
    summarize=summarize,
    x64=True,
)
