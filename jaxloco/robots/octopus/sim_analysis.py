"""`octopus.step_climb`: the simulated OCTOPUS getting over a step (`scenarios.make_scenario`)
with the CLM controller (`clm.make_controller`; or the CCM baseline, `ccm`), as a sweep
analysis on the native MuJoCo backend (executor "host": the batch runs in `mujoco.batch`
on every core), or on MJX (fixed parameter `backend`).

The question it answers: for the CLM gains T0 (flipper torque threshold), Delta_A
(`flip_delta_a`), Delta_E (`delta_e`), Delta_F (`delta_f`), the crawler speed
(`clm_speed`) and the step height, does the robot get over the step, how long does it
take, and how close does it come to tipping (smallest static stability margin, largest
nose-up pitch and |roll|)?

The scenario kind, the controller and the backend are fixed per sweep (string parameters:
they change the compiled model or the controller); every other parameter varies per
simulation.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from jaxloco.analysis import Analysis, Metric, Simulation, Summary
from jaxloco.robots.octopus import ccm, clm, operator, scenarios
from jaxloco.robots.octopus.params import PARAMETERS
from jaxloco.sim.rollout import RolloutResult
from jaxloco.sim.scenario import seed_jitter

PARAMS = PARAMETERS.select(
    "kind", "controller",
    # terrain and physics
    "height", "distance", "yaw", "side_ratio", "block_gap", "mu", "distance_jitter", "yaw_jitter", "mu_jitter",
    # CLM gains (clm.PARAM_DEFAULTS)
    "T0", "flip_delta_a", "flip_delta_b", "delta_e", "delta_f", "clm_speed", "climb_paper", "flip_encoder",
    "climb_yield", "climb_rear_flippers", "climb_common_axis", "climb_per_side", "s_from_touch", "prepare_rear_init",
    "crawl_max_h", "operator_gain",
    # the CCM baseline
    "speed",
    # run
    "horizon", "nthread", "backend",
)

METRICS = (
    Metric("success", "the COG ends pass_distance beyond the last riser on top, no tipping, no divergence",
           kind="bool"),
    Metric("climb_time", "first time the success position holds (nan if never)", "s"),
    Metric("shortfall", "how far the COG still had to go, at its nearest, to pass_distance beyond the last riser "
           "(0: it got there; pit: back to the platform side of the edge; nan: diverged)", "m"),
    Metric("min_margin", "smallest static stability margin over the contacts that carry load (>= 3 contacts)", "m"),
    Metric("max_pitch", "largest nose-up pitch of the body (IMU)", "rad"),
    Metric("max_abs_roll", "largest |roll| of the body (IMU)", "rad"),
    Metric("tipped", "|roll| > roll_limit or nose-up pitch > pitch_limit at some time, or diverged", kind="bool"),
    Metric("final_x", "x of the COG at the end (first riser at `distance`)", "m"),
    Metric("final_z", "height of the COG at the end", "m"),
    Metric("arm_over_obstacle", "an arm roller carried load on top of an obstacle (>= 0.1 m up) and later on the "
           "floor again (the block task's arm sequence, paper Figs. 19-20)", kind="bool"),
    Metric("final_phase", "controller phase at the end (clm.PHASE_NAMES / ccm.PHASE_NAMES; -1: none)", kind="int"),
    Metric("t_diverged", "time the simulation diverged (nan: it did not)", "s"),
)

STATUSES = ("ok", "failed", "diverged", "tipped")
_SCENARIO_STATUS = {"ok": 0, "failed": 1}
RECORD_EVERY = 5  # control periods (0.1 s) between records


def scenario(plain: Mapping[str, Any]):
    """The climb scenario of a sweep: terrain kind, controller (with the operator) and horizon."""
    controller = str(plain["controller"])
    ctrl = operator.with_operator(clm.make_controller() if controller == "clm" else ccm.make_controller())
    return scenarios.make_scenario(str(plain["kind"]), ctrl, horizon_s=float(plain["horizon"]),
                                   record_every=RECORD_EVERY)


def params(values: Mapping[str, Any], keys: np.ndarray) -> dict[str, Any]:
    """One climb per row: its parameters, start distance, yaw and mu jittered from its key."""
    columns = {p.name: np.asarray(values[p.name]) for p in PARAMS if p.sweepable}
    u = seed_jitter(keys, 3)  # distance, yaw, mu
    columns["distance"] = columns["distance"] + u[:, 0] * columns.pop("distance_jitter")
    columns["yaw"] = columns["yaw"] + u[:, 1] * columns.pop("yaw_jitter")
    columns["mu"] = np.maximum(columns["mu"] + u[:, 2] * columns.pop("mu_jitter"), 0.1)
    return scenarios.params_batch(keys.shape[0], **columns)


def metrics(values: Mapping[str, Any], result: RolloutResult) -> dict[str, np.ndarray]:
    """The metrics and status of each row's climb."""
    out = {m.name: np.asarray(result.metrics[m.name]) for m in METRICS if m.name in result.metrics}
    out["t_diverged"] = result.t_diverged
    out["final_phase"] = np.asarray(result.records["phase"])[:, -1].astype(np.int64)
    diverged = result.diverged
    tipped = np.asarray(out["tipped"], bool) | diverged
    code = np.array([_SCENARIO_STATUS.get(s, 2) for s in result.status])
    code = np.where(diverged, 2, np.where(tipped, 3, code))
    out["tipped"] = tipped
    out["success"] = np.asarray(out["success"], bool) & ~diverged
    # a diverged run's COG flies off (or through the floor): how near it came means nothing
    out["shortfall"] = np.where(diverged, np.nan, np.asarray(out["shortfall"], float))
    out["status"] = code
    return out


# `Analysis.simulate`: one climb per row on the simulator's backend (also run by
# `octopus.paper` for each task's rows)
simulate = Simulation(scenario, params, metrics)


def _median(x: np.ndarray) -> float:
    x = x[np.isfinite(x)]
    return float(np.median(x)) if x.size else float("nan")


def _fmt(x: float, scale: float = 1.0, digits: int = 1) -> str:
    return "-" if not np.isfinite(x) else f"{x * scale:.{digits}f}"


PARAM_DEFAULTS = {p.name: p.default for p in PARAMS}
MAX_GROUP_VALUES = 6  # a swept parameter with at most this many values gets a row per value


def summarize(table) -> Summary:
    """Success rate and medians per step height, then per value of every other swept
    parameter with few values (the rest pooled)."""
    cols = {n: table.column(n).to_numpy(zero_copy_only=False) for n in table.column_names}
    swept = [p.name for p in PARAMS if p.name in cols
             and (table.schema.field(p.name).metadata or {}).get(b"role") == b"swept"]
    groups = ["height"] + [n for n in swept if n != "height"]
    status = cols["status"].astype(str)
    rows = []
    for name in groups:
        values = np.unique(cols[name])
        if name != "height" and values.size > MAX_GROUP_VALUES:
            continue
        for v in values:
            sel = cols[name] == v
            ok = sel & cols["success"].astype(bool)
            failed = sel & ~cols["success"].astype(bool)
            short = cols["shortfall"][failed] if "shortfall" in cols else np.zeros(0)  # older tables lack it
            rows.append((
                name, f"{float(v):g}", str(int(sel.sum())), f"{100 * np.mean(cols['success'][sel]):.0f}%",
                _fmt(_median(cols["climb_time"][ok]), 1.0, 1),
                _fmt(_median(short), 1000.0, 0),
                _fmt(_median(cols["min_margin"][sel]), 1000.0, 0),
                _fmt(_median(cols["max_pitch"][sel]), 180.0 / np.pi, 1),
                str(int(np.sum(status[sel] == "tipped"))), str(int(np.sum(status[sel] == "diverged"))),
            ))
    def first(name: str) -> str:  # a fixed string parameter (older tables may lack it)
        column = cols.get(name)
        return str(column[0]) if column is not None and len(column) else PARAM_DEFAULTS[name]

    kind, controller = first("kind"), first("controller").upper()
    backend = {"native": "native MuJoCo", "mjx": "MJX"}[first("backend")]
    return Summary(
        title=f"OCTOPUS {controller} getting over a step ({kind}, {backend})",
        columns=("param", "value", "runs", "success", "climb s", "short mm", "margin mm", "pitch deg", "tipped",
                 "div."),
        rows=tuple(rows),
        notes=(("climb s: median climb time of the successful runs; short mm: median shortfall of the others (how "
                "far their COG stayed, at its nearest, from pass_distance beyond the last riser); margin mm, pitch "
                "deg: medians of the min margin and the max nose-up pitch; tipped / div.: runs with that status"),
               "each block pools every other swept parameter; paper: CLM 100% on 400 mm, CCM 0%"),
    )


STEP_CLIMB = Analysis(
    name="octopus.step_climb",
    doc="The simulated OCTOPUS (CLM or CCM controller) getting over a step: success, time, min margin, max pitch.",
    params=PARAMS,
    metrics=METRICS,
    simulate=simulate,
    statuses=STATUSES,
    summarize=summarize,
    x64=True,
)
