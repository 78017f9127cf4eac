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
from functools import lru_cache
from typing import Any

import numpy as np

from jaxloco.analysis import Analysis, Metric, Param, Summary
from jaxloco.robots.octopus import ccm, clm, operator, scenarios
from jaxloco.sim.rollout import Simulator
from jaxloco.sim.scenario import seed_jitter

_CLM = clm.PARAM_DEFAULTS
_SC = scenarios.PARAM_DEFAULTS

PARAMS = (
    Param("kind", "step1", "terrain: one terrace, two terraces from the front, or from the side, a block "
          "(height) beside the robot's right side, or a pit (the robot on a platform of height whose edge is at "
          "distance, nothing beyond)", kind="str",
          choices=("step1", "step2_front", "step2_side", "block", "pit"), sweepable=False),
    Param("controller", "clm", "the CLM controller (crawlers, flippers and arms) or the CCM baseline (crawlers "
          "and flippers only)", kind="str", choices=("clm", "ccm"), sweepable=False),
    # terrain and physics
    Param("height", _SC["height"], "total step height", "m", lo=0.0, hi=scenarios.MAX_HEIGHT),
    Param("distance", _SC["distance"], "chassis origin to the first riser at t = 0", "m", lo=0.4, hi=3.0),
    Param("yaw", _SC["yaw"], "initial heading relative to the step normal", "rad", lo=-0.8, hi=0.8),
    Param("side_ratio", _SC["side_ratio"], "step2_side: right rise / left rise", "", lo=0.0, hi=1.0),
    Param("block_gap", _SC["block_gap"], "block: gap between the robot's right side and the block", "m",
          lo=0.0, hi=1.0),
    Param("mu", _SC["mu"], "terrain friction coefficient", "", lo=0.1, hi=2.0),
    Param("distance_jitter", 0.0, "distance + U(-1, 1) x this, from the row's seed (the simulation itself is "
          "deterministic: seeds only matter through the jitters)", "m", lo=0.0, hi=0.5),
    Param("yaw_jitter", 0.0, "yaw + U(-1, 1) x this, from the row's seed", "rad", lo=0.0, hi=0.5),
    Param("mu_jitter", 0.0, "mu + U(-1, 1) x this, from the row's seed (mu stays >= 0.1)", "", lo=0.0, hi=1.0),
    # CLM gains (clm.PARAM_DEFAULTS)
    Param("T0", _CLM["T0"], "CLM: front flipper torque threshold T0 (flipper rule Cases 1-3); default ours, the "
          "paper gives none", "N m", lo=1.0, hi=80.0),
    Param("flip_delta_a", _CLM["flip_delta_a"], "CLM: Delta_A, front flipper step of the torque rule; default ours",
          "rad/period", lo=0.001, hi=0.1),
    Param("flip_delta_b", _CLM["flip_delta_b"], "CLM: Delta_B, front flipper step of the torque rule; default ours",
          "rad/period", lo=0.001, hi=0.1),
    Param("delta_e", _CLM["delta_e"], "CLM: Delta_E, boom step of the climb / release (the level lift moves the "
          "EPRAs Delta_E l1 per period); default ours", "rad/period", lo=0.0005, hi=0.05),
    Param("delta_f", _CLM["delta_f"], "CLM: Delta_F, flipper step of the climb / release; default ours",
          "rad/period", lo=0.001, hi=0.1),
    Param("clm_speed", _CLM["clm_speed"], "CLM: crawler speed (default ours; the crawlers reach 63 mm/s, Table 3)",
          "m/s", lo=0.005, hi=0.063),
    Param("climb_paper", _CLM["climb_paper"], "CLM climb: 1 = the paper's Eqs. 28-29 (booms and front flippers "
          "turn down, crawlers drive); 0 = our level lift (not the paper's method)", "", lo=0.0, hi=1.0),
    Param("flip_encoder", _CLM["flip_encoder"], "paper climb reading: 1 = A' of Eq. 29 is the flipper encoder "
          "(\"obtained\"), 0 = the last command", "", lo=0.0, hi=1.0),
    Param("climb_yield", _CLM["climb_yield"], "paper climb reading: 1 = the front flippers' torque rule (Case 2) keeps "
          "running in CLIMB", "", lo=0.0, hi=1.0),
    Param("climb_rear_flippers", _CLM["climb_rear_flippers"], "paper climb reading: 1 = Eq. 29 turns the rear "
          "flippers too, 0 = the front ones (A of 'Crawler controls')", "", lo=0.0, hi=1.0),
    Param("s_from_touch", _CLM["s_from_touch"], "paper climb reading: 1 = S (Eq. 18) from the front flippers' "
          "touch-down on the step top, 0 = from the CLIMB start", "", lo=0.0, hi=1.0),
    Param("prepare_rear_init", _CLM["prepare_rear_init"], "PREPARE places the rear arms at their Table 2 start "
          "points (1, ours) or targets (0)", "", lo=0.0, hi=1.0),
    Param("crawl_max_h", _CLM["crawl_max_h"], "CLM: steps up to this H_EST are climbed by crawlers and flippers, "
          "arms carried (CRAWL: ours, not the paper's method; 0 = the arms climb every step)", "m", lo=0.0,
          hi=scenarios.MAX_HEIGHT),
    Param("operator_gain", operator.PARAM_DEFAULTS["operator_gain"], "operator steering (not the CLM: it cannot "
          "measure the yaw): track speed difference per rad of heading error while driving straight; 0 = no "
          "operator, the paper's rows", "m/s per rad", lo=0.0, hi=1.0),
    # the CCM baseline
    Param("speed", ccm.PARAM_DEFAULTS["speed"], "CCM: commanded crawler speed", "m/s", lo=0.005, hi=0.063),
    # run
    Param("horizon", 90.0, "simulated time", "s", lo=1.0, hi=600.0, sweepable=False),
    Param("nthread", 0, "physics threads (0: all cores; native backend)", "", kind="int", lo=0, hi=1024,
          sweepable=False),
    Param("backend", "native", "simulation backend: native MuJoCo (mujoco.batch, CPU) or MJX (one jitted scan; "
          "compiles about a minute on CPU)", kind="str", choices=("native", "mjx"), sweepable=False),
)

METRICS = (
    Metric("success", "the COG ends pass_distance beyond the last riser on top, no tipping, no divergence",
           kind="bool"),
    Metric("climb_time", "first time the success position holds (nan if never)", "s"),
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


@lru_cache(maxsize=4)
def _scenario(kind: str, controller: str, horizon: float):
    ctrl = operator.with_operator(clm.make_controller() if controller == "clm" else ccm.make_controller())
    return scenarios.make_scenario(kind, ctrl, horizon_s=horizon, record_every=RECORD_EVERY)


def simulate(values: Mapping[str, Any], keys: np.ndarray, simulator: Simulator) -> dict[str, np.ndarray]:
    """`Analysis.simulate`: one climb per row (values: (B,) columns of the sweepable
    parameters; kind, controller and horizon plain) on the simulator's backend."""
    scenario = _scenario(str(values["kind"]), str(values["controller"]), float(values["horizon"]))
    columns = {p.name: np.asarray(values[p.name]) for p in PARAMS if p.sweepable}
    u = seed_jitter(keys, 3)  # distance, yaw, mu
    columns["distance"] = columns["distance"] + u[:, 0] * columns.pop("distance_jitter")
    columns["yaw"] = columns["yaw"] + u[:, 1] * columns.pop("yaw_jitter")
    columns["mu"] = np.maximum(columns["mu"] + u[:, 2] * columns.pop("mu_jitter"), 0.1)
    params = scenarios.params_batch(keys.shape[0], **columns)
    params["key"] = keys
    result = simulator.run(scenario, params)
    out = {m.name: np.asarray(result.metrics[m.name]) for m in METRICS if m.name in result.metrics}
    out["t_diverged"] = result.t_diverged
    out["final_phase"] = np.asarray(result.records["phase"])[:, -1].astype(np.int64)
    diverged = result.diverged
    tipped = np.asarray(out["tipped"], bool) | diverged
    code = np.array([_SCENARIO_STATUS.get(s, 2) for s in result.status])
    code = np.where(diverged, 2, np.where(tipped, 3, code))
    out["tipped"] = tipped
    out["success"] = np.asarray(out["success"], bool) & ~diverged
    out["status"] = code
    return out


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
            rows.append((
                name, f"{float(v):g}", str(int(sel.sum())), f"{100 * np.mean(cols['success'][sel]):.0f}%",
                _fmt(_median(cols["climb_time"][ok]), 1.0, 1),
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
        columns=("param", "value", "runs", "success", "climb s", "margin mm", "pitch deg", "tipped", "div."),
        rows=tuple(rows),
        notes=(("climb s: median climb time of the successful runs; margin mm, pitch deg: medians of the min "
                "margin and the max nose-up pitch; tipped / div.: runs with that status"),
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
