"""`octopus.paper`: the OCTOPUS paper's experiments ("Tasks setting", "Results and
discussion") as one sweep analysis, one row per perturbed run.

Tasks (`TASKS`; the swept string parameter `task`):
  * "step1_clm": the 400 mm one-terrace step, CLM (paper: 100 %, max pitch 0.60 rad, max
    roll 0.03 rad, min margin 0.15 m);
  * "step1_ccm": the same step, CCM, crawlers and flippers only, arms up (paper: 0 %, the
    robot turned over, roll -0.14 rad); ours is an automatic flipper policy (`ccm`), the
    paper's was two operators;
  * "step2_front": two terraces of 200 mm from the front, CLM with the arms down (paper:
    100 %, max pitch 0.59 rad, min margin 0.17 m);
  * "step2_side": two terraces from the side, 400 mm under the left crawler, 200 mm under
    the right one (the paper gives the total height only), CLM (paper: 100 %, roll
    -0.25 rad, min margin 0.07 m);
  * "block": a 500 mm block 10 mm beside the robot's right side, CLM: an arm collides,
    stops, rides the top and returns to the ground (paper, Figs. 19-20; no numbers).
Every task runs the paper's method by default: the CLM climbs by Eqs. 28-29
(`climb_paper` = 1) and never in CRAWL (`crawl_max_h` = 0); both of our options can be
set in a spec (`climb_paper` = 0: the level lift; `crawl_max_h` = 0.25) to compare.

Perturbations (the paper's runs differ by how the operator placed the robot; ours are
seeded): the start distance to the first riser distance + U(-1, 1) distance_jitter, the
heading yaw + U(-1, 1) yaw_jitter, the terrain friction mu + U(-1, 1) mu_jitter, from the
row's seed (`sim_analysis`). 20 seeds make the paper's 20 runs.

The summary prints, per task, the success rate and the mean and worst of max pitch, max
|roll| and min margin over the runs, the paper's number beside each.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from jaxloco.analysis import Analysis, Param, Summary, mean_worst
from jaxloco.robots.octopus import sim_analysis
from jaxloco.robots.octopus.params import PARAMETERS


@dataclass(frozen=True)
class Task:
    """One experiment of the paper: terrain kind, controller, total height [m] and the
    scenario parameters it fixes."""

    kind: str
    controller: str
    height: float
    doc: str
    fixed: tuple[tuple[str, float], ...] = ()


TASKS: dict[str, Task] = {
    "step1_clm": Task("step1", "clm", 0.4, "400 mm one-terrace step, CLM"),
    "step1_ccm": Task("step1", "ccm", 0.4, "400 mm one-terrace step, CCM (crawlers and flippers, arms up)"),
    "step2_front": Task("step2_front", "clm", 0.4, "two 200 mm terraces from the front, CLM with the arms down"),
    "step2_side": Task("step2_side", "clm", 0.4, "two terraces from the side, 400 mm left / 200 mm right, CLM",
                       (("side_ratio", 0.5),)),
    "block": Task("block", "clm", 0.5, "500 mm block 10 mm beside the right side, CLM"),
}
TASK_NAMES = tuple(TASKS)
# the tasks in which the CLM climbs a step (the block is passed, not climbed)
CLIMB_TASKS = tuple(name for name, t in TASKS.items() if t.controller == "clm" and t.kind.startswith("step"))

# the paper's numbers ("Results and discussion"; absent: not reported)
PAPER: dict[str, dict[str, float]] = {
    "step1_clm": {"success": 1.0, "max_pitch": 0.60, "max_abs_roll": 0.03, "min_margin": 0.15},
    "step1_ccm": {"success": 0.0, "max_abs_roll": 0.14},
    "step2_front": {"success": 1.0, "max_pitch": 0.59, "min_margin": 0.17},
    "step2_side": {"success": 1.0, "max_abs_roll": 0.25, "min_margin": 0.07},
    "block": {"success": 1.0},
}

_TASK_OWNED = {"kind", "controller", "height", "side_ratio"}
# the paper's method by default, and the paper's perturbations (benchmarks/octopus_experiments.py)
_DEFAULTS = {"climb_paper": 1.0, "crawl_max_h": 0.0, "horizon": 150.0, "distance_jitter": 0.1,
             "yaw_jitter": 0.05, "mu_jitter": 0.2}


def _with_default(p: Param) -> Param:
    return replace(p, default=_DEFAULTS[p.name]) if p.name in _DEFAULTS else p


PARAMS = (
    *PARAMETERS.select("task", task={
        "doc": PARAMETERS["task"].doc + ": " + "; ".join(f"{k}: {t.doc}" for k, t in TASKS.items()),
        "choices": TASK_NAMES}),
    *(_with_default(p) for p in sim_analysis.PARAMS if p.name not in _TASK_OWNED),
)
METRICS = sim_analysis.METRICS
STATUSES = sim_analysis.STATUSES


def task_values(task: str) -> dict[str, Any]:
    """The step_climb fixed values (kind, controller) and parameters (height, ...) of a task."""
    t = TASKS[task]
    return {"kind": t.kind, "controller": t.controller, "height": t.height, **dict(t.fixed)}


def simulate(values: Mapping[str, Any], keys: np.ndarray, simulator: Any) -> dict[str, np.ndarray]:
    """`Analysis.simulate`: the rows are split by task, and each group runs as
    `octopus.step_climb` rows of its terrain and controller (the task's height and side
    ratio as columns, the other step_climb parameters at their defaults or this sweep's
    values)."""
    tasks = np.asarray(values["task"]).astype(str)
    out: dict[str, np.ndarray] = {}
    for task in dict.fromkeys(tasks.tolist()):
        rows = np.flatnonzero(tasks == task)
        own = {**sim_analysis.PARAM_DEFAULTS, **task_values(task)}
        step = {}
        for p in sim_analysis.PARAMS:
            value = values[p.name] if p.name in values else own[p.name]
            if p.sweepable:
                value = np.asarray(value)[rows] if np.ndim(value) else np.full(rows.size, value)
            step[p.name] = value
        res = sim_analysis.simulate(step, keys[rows], simulator)
        for k, v in res.items():
            v = np.asarray(v)
            if k not in out:
                out[k] = np.zeros((tasks.size, *v.shape[1:]), v.dtype)
            out[k][rows] = v
    return out


def _failures(status: np.ndarray, shortfall: np.ndarray | None = None) -> str:
    """'2 tipped, 1 stuck; 0.29 (0.21) m short' from the runs' statuses ("failed" = never
    on the top) and, for the runs that did not succeed, their shortfall [m] (how near the
    COG came to the success line) as mean (nearest)."""
    names = {"tipped": "tipped", "failed": "stuck", "diverged": "diverged"}
    parts = [f"{int(np.sum(status == k))} {v}" for k, v in names.items() if np.any(status == k)]
    text = ", ".join(parts) or "-"
    short = np.asarray(shortfall, float)[status != "ok"] if shortfall is not None else np.zeros(0)
    if parts and np.isfinite(short).any():
        text += f"; {mean_worst(short, 'min')} m short"
    return text


def _paper(task: str, key: str, digits: int = 2) -> str:
    v = PAPER.get(task, {}).get(key)
    if v is None:
        return "-"
    return f"{v * 100:.0f}%" if key == "success" else f"{v:.{digits}f}"


def summarize(table) -> Summary:
    """Per task: runs, success (paper), max pitch, max |roll| [rad], min margin [m] as mean
    (worst) over the runs with the paper's value beside, and the mean climb time."""
    cols = {n: table.column(n).to_numpy(zero_copy_only=False) for n in table.column_names}
    tasks = cols["task"].astype(str)
    status = cols["status"].astype(str)
    rows = []
    for task in [t for t in TASK_NAMES if t in set(tasks)]:
        sel = tasks == task
        ok = cols["success"][sel].astype(bool)
        t_ok = cols["climb_time"][sel][ok]
        rows.append((
            task,
            f"{int(ok.sum())}/{int(sel.sum())} / {_paper(task, 'success')}",
            f"{mean_worst(cols['max_pitch'][sel], 'max')} / {_paper(task, 'max_pitch')}",
            f"{mean_worst(np.abs(cols['max_abs_roll'][sel]), 'max')} / {_paper(task, 'max_abs_roll')}",
            f"{mean_worst(cols['min_margin'][sel], 'min', 3)} / {_paper(task, 'min_margin')}",
            f"{np.nanmean(t_ok):.0f}" if t_ok.size else "-",
            _failures(status[sel], cols["shortfall"][sel] if "shortfall" in cols else None),
        ))
    def first(name: str) -> str:
        column = cols.get(name)
        return f"{float(column[0]):g}" if column is not None and len(column) else "-"

    notes = []
    if "block" in set(tasks) and "arm_over_obstacle" in cols:
        seq = cols["arm_over_obstacle"][tasks == "block"].astype(bool)
        notes.append(f"block: an arm rode the block top and came back to the floor (Figs. 19-20) in "
                     f"{int(seq.sum())}/{seq.size} runs")
    climbing = np.isin(tasks, CLIMB_TASKS)
    if first("climb_paper") == "1" and climbing.any() and not cols["success"][climbing].astype(bool).any():
        notes.append("the paper's climb got over no step here; in our model it does not get over even the "
                     "150-250 mm steps that the crawlers alone climb (python benchmarks/octopus_low_steps.py); "
                     "why, as far as we measured: docs/octopus.md, 'It does not climb yet'")
    climb = {"1": "the paper's Eqs. 28-29", "0": "our level lift (not the paper's)"}.get(first("climb_paper"), "?")
    return Summary(
        title=f"OCTOPUS paper experiments (climb: {climb}; CRAWL up to {first('crawl_max_h')} m)",
        columns=("task", "success / paper", "max pitch / paper", "max |roll| / paper", "min margin / paper",
                 "time s", "failures"),
        rows=tuple(rows),
        notes=(("pitch, roll [rad], margin [m]: mean over the runs (worst run) / the paper's value; time: mean "
                "climb time of the successful runs; failures: tipped (|roll| or pitch past its limit: turned over), "
                "stuck (never on the top), diverged, and how far short of the success line (pass_distance beyond "
                "the last riser) their COG stayed at its nearest, mean (nearest) [m]; paper: Chen et al. 2018, '-' "
                "not reported"), *notes),
    )


PAPER_EXPERIMENTS = Analysis(
    name="octopus.paper",
    doc="The OCTOPUS paper's experiments (400 mm step CLM and CCM, two terraces from the front and the side, "
        "the block beside the robot), one row per perturbed run, the paper's numbers beside.",
    params=PARAMS,
    metrics=METRICS,
    simulate=simulate,
    statuses=STATUSES,
    summarize=summarize,
    x64=True,
)


def perturbations(n: int, seed: int = 0) -> dict[str, np.ndarray]:
    """n perturbed starts like the sweep's jitters, for scripts that call
    `scenarios.params_batch` directly: distance U(0.6, 0.8) m, yaw U(-0.05, 0.05) rad,
    friction U(0.6, 1.0) (NumPy's generator with `seed`; not the sweep's per-row keys)."""
    rng = np.random.default_rng(seed)
    return {"distance": rng.uniform(0.6, 0.8, n), "yaw": rng.uniform(-0.05, 0.05, n), "mu": rng.uniform(0.6, 1.0, n)}


def run_summary(metrics: Mapping[str, Any]) -> dict[str, float]:
    """Success rate and mean / worst of max pitch, max |roll|, min margin [rad, m] and the
    mean climb time of the successful runs, from a rollout's metrics."""
    ok = np.asarray(metrics["success"], bool)
    pitch, roll, margin = (np.asarray(metrics[k], float) for k in ("max_pitch", "max_abs_roll", "min_margin"))
    t = np.asarray(metrics["climb_time"], float)[ok]
    return {
        "success": float(ok.mean()),
        "max_pitch": float(np.nanmean(pitch)),
        "max_pitch_worst": float(np.nanmax(pitch)),
        "max_abs_roll": float(np.nanmean(roll)),
        "max_abs_roll_worst": float(np.nanmax(roll)),
        "min_margin": float(np.nanmean(margin)),
        "min_margin_worst": float(np.nanmin(margin)),
        "climb_time": float(np.nanmean(t)) if t.size else float("nan"),
    }
