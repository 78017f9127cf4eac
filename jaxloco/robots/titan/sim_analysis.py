"""`titan.walk`: TITAN XI's planned walks executed in MuJoCo (Hodoshima et al. 2007, Secs.
7 and 8.2-8.4) as a sweep analysis (executor "host": plans are made row by row, each
group of rows with the same terrain structure simulates as one batch) on native MuJoCo or
MJX (`backend`, default "auto": native on CPUs; MJX runs the model's MJX variant,
`scenarios.mjx_variant`, with the same executor code).

The question it answers: planned on a map of the frames (exact, or made from a noisy
total-station survey, Sec. 8.2.1), does the walk hold up on the true terrain: does the
robot finish without falling, keep the NE margin S_NE^c, keep its feet off the frames
and land them where planned, and how far does it get?

One row:
  1. terrain: `field` "grid" (the Sec. 7 / 8.4 frame grids: beams `frame_size` wide and
     high every `frame_interval` m, centred on the origin, on a plane at `slope` with the
     tethers cancelling `tether` of the slope-parallel gravity) or "long" (the Sec. 8.3
     dummy-frame field `walk.LONG_FIELD`, 30.2 x 4.7 m of 0.2 m beams every 1.5 m, flat
     ground around it);
  2. map: `map` "survey" (the frame crossings and area centres measured with Gaussian
     noise of `survey_noise` per coordinate, drawn from the row's seed; `maps.map_from_
     survey`) or "exact" (`maps.frame_grid_map` of the true beams; grid field only);
  3. plan: `n_cycles` cycles (`gait.plan_cycles`) from the standard start, the COG
     moved by U(-1, 1) x `start_jitter` in x and y from the row's seed (and onto free
     cells, `walk.clear_start`); grid: along the map-frame `direction`, the walk centred
     on the origin; long: along +x from 5 m before the field;
  4. execution: the quasi-static footstep executor (`control.py`, integral gain
     `body_gain`) in MuJoCo (`scenarios.make_scenario`), friction `mu`.
Frames: the map frame of `maps` (on a slope: x up the fall line, z normal to it); SI, rad.

Success (`success`): every cycle planned, the plan completed in simulation, no fall, the
simulated min NESM >= S_NE^c - `nesm_tol`, no swing collision, no foot on a frame,
touchdown error < 0.1 m and path deviation < 0.1 m (`scenarios.summarize`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from functools import lru_cache
from typing import Any

import jax.numpy as jnp
import numpy as np

from jaxloco.analysis import Analysis, Metric, Summary, mean_worst
from jaxloco.errors import SpecError
from jaxloco.robots.titan import params as titan_params
from jaxloco.robots.titan import scenarios, walk
from jaxloco.sim.rollout import Simulator
from jaxloco.sim.scenario import seed_jitter

GRID_HALF = 12.0  # [m] the grid field's beams cover at least +-GRID_HALF
WALK_PER_CYCLE = 1.0  # [m] a generous distance per cycle: sizes the map and centres the walk
ROBOT_REACH = 3.0  # [m] the feet's farthest reach from the COG, with room to spare
JITTER_SALT = 0x717A  # the start jitter's draws differ from the survey noise's

# the simulated fields: the grid field's beams (frame_size, frame_interval) and slope within
# what the simulated terrain holds (`scenarios.MAX_SPACING`, `MAX_BEAM_HEIGHT`)
PARAMS = titan_params.PARAMETERS.select(
    "field", "map", "survey_noise", "frame_size", "frame_interval", "slope", "direction", "tether", "mu",
    "start_jitter", "nesm_tol", "body_gain", "n_cycles", "backend", "nthread",
    frame_size={"doc": "beam section (width = height); 0 = flat ground"},
    frame_interval={"doc": "grid field: beam spacing (long field: 1.5 m)", "hi": 3.0},
    slope={"doc": "slope of the terrain plane (Sec. 8.4: 30 deg, 0.2 m frames every 1.5 m)", "hi": 0.6},
    direction={"doc": "grid field: map-frame walking direction (0 = +x, up the fall line on a slope)"},
    n_cycles={"doc": "gait cycles per walk (6 steps, 18 s each); the long field needs ~52 to cross it", "hi": 80},
    body_gain={"doc": "the footstep executor's integral gain of the body position and attitude correction "
               "(control.executor_step; the titan.body_gain objective tunes it)"},
)

METRICS = (
    Metric("success", "every cycle planned and the walk executed: no fall, simulated min NESM >= S_NE^c - "
           "nesm_tol, no swing collision, no foot on a frame, touchdown and path errors < 0.1 m", kind="bool"),
    Metric("planned", "every cycle found a feasible foothold trial (no held cycle)", kind="bool"),
    Metric("plan_min_nesm", "smallest NE stability margin of the plan", "m"),
    Metric("plan_failures", "cycles with no feasible trial (the robot holds)", kind="int"),
    Metric("plan_modifications", "modifications the plan used (trial-index sum)", kind="int"),
    Metric("converged", "the last 2 cycles are the standard gait (|L| = L_std, |W| = W_std, no modification)",
           kind="bool"),
    Metric("sim_min_nesm", "smallest NE stability margin in simulation (whole-robot COG, measured feet)", "m"),
    Metric("nesm_ok", "sim_min_nesm >= S_NE^c - nesm_tol", kind="bool"),
    Metric("distance", "COG progress along the first cycle's direction in simulation", "m"),
    Metric("max_touchdown_error", "largest distance of a landed foot from its planned foothold", "m"),
    Metric("min_swing_clearance", "smallest clearance of a swinging leg to the frames (inf: no frames)", "m"),
    Metric("swing_collision", "a swinging leg touched a frame", kind="bool"),
    Metric("feet_on_frames", "a loaded foot pad overlapped a frame", kind="bool"),
    Metric("max_cycle_error", "largest in-plane COG error against the plan at the cycle ends", "m"),
    Metric("max_path_deviation", "largest COG distance from the cycle's path L_G at the cycle ends", "m"),
    Metric("foot_slip", "largest summed in-plane motion of a loaded foot", "m"),
    Metric("max_tilt", "largest body tilt from the start", "rad"),
    Metric("fell", "tilted > 0.3 rad, sank > the fall drop, or the simulation diverged", kind="bool"),
    Metric("t_diverged", "time the simulation diverged (nan: it did not)", "s"),
)

STATUSES = (
    "ok",
    "failed: a cycle unplanned (the robot holds)",
    "failed: fell",
    "failed: a foot on a frame or a swing collision",
    "failed: NESM below S_NE^c - nesm_tol",
    "failed: touchdown or path error",
    "diverged",
    "failed: no start pose clear of the frames",
)
_SIM_METRICS = {  # titan.walk metric -> scenarios.summarize metric
    "sim_min_nesm": "min_nesm", "nesm_ok": "nesm_ok", "distance": "final_progress",
    "max_touchdown_error": "max_touchdown_error", "min_swing_clearance": "min_swing_clearance",
    "swing_collision": "swing_collision", "feet_on_frames": "forbidden_landing",
    "max_cycle_error": "max_cycle_error", "max_path_deviation": "max_path_deviation", "foot_slip": "foot_slip",
    "max_tilt": "max_tilt", "fell": "fell",
}


def grid_field(spacing: float) -> scenarios.FrameField:
    """The grid field's beams: an even count each way (so that the beam centres are at
    +-spacing/2, +-3 spacing/2, ..., as `walk.sim_map`'s lines) covering +-GRID_HALF,
    their length the crossings' extent (the survey sees every beam)."""
    n = 2 * math.ceil(GRID_HALF / spacing + 0.5)
    half = 0.5 * (n - 1) * spacing + 3.0
    return scenarios.FrameField(n_along=n, n_across=n, max_spacing=float(spacing), half_length=half, half_width=half)


def grid_shape(n_cycles: int) -> tuple[int, int]:
    """Planning map cells for a grid-field walk of n_cycles centred on the origin."""
    half = 0.5 * n_cycles * WALK_PER_CYCLE + ROBOT_REACH + 1.0
    n = max(
        2 * math.ceil(half / float(titan_params.CELL)), walk.SIM_SHAPE[0]
    )  # short walks share walk.SIM_SHAPE's compile
    return n, n


@lru_cache(maxsize=8)
def walk_scenario(n_steps: int, beam_width: float, field: scenarios.FrameField, backend: str = "native"):
    """The executor scenario of a group of rows (one per terrain structure and backend;
    kept, so that its compiled rollout serves every chunk and replay)."""
    return scenarios.make_scenario(n_steps, beam_width=beam_width, field=field, record_every=5, backend=backend)


def row_terrain(v: Mapping[str, Any]) -> tuple[scenarios.FrameField, float, float]:
    """(field, spacing, beam width) of a row: what the simulated terrain is built from."""
    width = float(v["frame_size"]) if float(v["frame_size"]) > 0.0 else float(titan_params.FRAME_SMALL)
    if v["field"] == "long":
        return walk.LONG_FIELD, walk.LONG_SPACING, width
    return grid_field(float(v["frame_interval"])), float(v["frame_interval"]), width


def plan_row(v: Mapping[str, Any], key: np.ndarray, n_cycles: int):
    """The executor plan, planner output and executor scalars of one row (module
    docstring, steps 2-3); `walk.NoClearStart` when no start pose is clear of the frames."""
    field, spacing, _ = row_terrain(v)
    params = dataclasses.replace(titan_params.default_params(), tether=jnp.asarray(float(v["tether"])))
    size, slope = float(v["frame_size"]), float(v["slope"])
    long = v["field"] == "long"
    shape = walk.LONG_SHAPE if long else grid_shape(n_cycles)
    if v["map"] == "exact":
        gmap = walk.sim_map(size, spacing, slope, shape)
    else:
        gmap = walk.surveyed_map(field, spacing, size, float(v["survey_noise"]), jnp.asarray(key, jnp.uint32),
                              shape=shape, slope=slope)
    direction = 0.0 if long else float(v["direction"])
    jitter = seed_jitter(np.asarray(key, np.uint32)[None] ^ np.uint32(JITTER_SALT), 2)[0] * float(v["start_jitter"])
    if long:
        near = np.asarray(walk.LONG_START) + jitter
    else:
        near = -0.5 * n_cycles * WALK_PER_CYCLE * 0.9 * np.array([math.cos(direction), math.sin(direction)]) + jitter
    return walk.plan_on_map(params, gmap, near, n_cycles, direction, spacing, size, slope)


def _status(m: Mapping[str, Any], planned: bool, diverged: bool) -> int:
    if diverged:
        return 6
    if not planned:
        return 1
    if m["success"]:
        return 0
    if m["fell"] or not m["completed"]:
        return 2
    if m["forbidden_landing"] or m["swing_collision"]:
        return 3
    if not m["nesm_ok"]:
        return 4
    return 5


def simulate(values: Mapping[str, Any], keys: np.ndarray, simulator: Simulator) -> dict[str, np.ndarray]:
    """`Analysis.simulate`: a plan per row (module docstring), the rows grouped by terrain,
    one rollout per group (values: (B,) columns of the sweepable parameters; n_cycles
    plain). A row with no clear start gets status 7 and no simulation."""
    n_cycles = int(values["n_cycles"])
    names = [p.name for p in PARAMS if p.sweepable]
    n = keys.shape[0]
    rows = [{k: np.asarray(values[k])[i] for k in names} for i in range(n)]
    blank = {"bool": False, "int": -1}
    out = {m.name: np.full(n, blank.get(m.kind, np.nan)) for m in METRICS}
    out["status"] = np.full(n, 7)
    if any(v["field"] == "long" and v["map"] == "exact" for v in rows):
        raise SpecError("titan.walk: map = 'exact' is for the grid field; the long field is planned on a survey")
    if any(v["field"] == "long" and float(v["direction"]) != 0.0 for v in rows):
        raise SpecError("titan.walk: direction is for the grid field; the long field is walked along +x")
    groups: dict[tuple, list] = {}
    for i, v in enumerate(rows):
        try:
            planned = plan_row(v, keys[i], n_cycles)
        except walk.NoClearStart:
            continue  # status 7, metrics nan
        groups.setdefault(row_terrain(v), []).append((i, v, planned))
    for (field, _spacing, width), group in groups.items():
        sc = walk_scenario(6 * n_cycles, width, field, simulator.backend)
        plans = [g[2][0] for g in group]
        scal = [g[2][2] for g in group]
        over = {k: np.array([s[k] for s in scal]) for k in scal[0]}
        for k in ("mu", "nesm_tol", "body_gain"):
            over[k] = np.array([float(g[1][k]) for g in group])
        res = simulator.run(sc, scenarios.params_batch(plans, **over))
        for j, (i, _v, (_plan, gait, _s)) in enumerate(group):
            m = res.row(j)
            ok_plan = int(gait.n_failures) == 0
            for name, src in _SIM_METRICS.items():
                out[name][i] = float(m[src])
            out["plan_min_nesm"][i] = float(gait.min_nesm)
            out["plan_failures"][i] = int(gait.n_failures)
            out["plan_modifications"][i] = int(gait.n_modifications)
            out["planned"][i] = ok_plan
            out["converged"][i] = walk.converged(gait, titan_params.default_params())
            out["t_diverged"][i] = res.t_diverged[j]
            out["status"][i] = _status(m, ok_plan, bool(res.diverged[j]))
            out["success"][i] = out["status"][i] == 0
    return out


def summarize(table) -> Summary:
    """Mean (worst) over the seeds, one row per field, map, frames, slope and heading."""
    cols = {n: table.column(n).to_numpy(zero_copy_only=False) for n in table.column_names}
    keys = ("field", "map", "frame_size", "frame_interval", "slope", "direction")
    groups = sorted({tuple(cols[k][i] for k in keys) for i in range(len(cols["field"]))}, key=str)
    rows = []
    for g in groups:
        sel = np.all([cols[k] == val for k, val in zip(keys, g, strict=True)], axis=0)
        field, source, size, interval, slope, direction = g
        where = "long field (Sec. 8.3)" if field == "long" else f"{size:g} m / {interval:g} m"
        rows.append((
            where, str(source), f"{math.degrees(float(slope)):.0f}", f"{math.degrees(float(direction)):.0f}",
            str(int(sel.sum())), f"{100 * np.mean(cols['success'][sel]):.0f}%",
            mean_worst(cols["distance"][sel], "min", 1),
            mean_worst(cols["sim_min_nesm"][sel], "min", 4),
            mean_worst(cols["plan_min_nesm"][sel], "min", 4),
            str(int(np.nansum(cols["feet_on_frames"][sel]))),
            mean_worst(cols["max_touchdown_error"][sel], "max", 3),
            mean_worst(np.where(np.isfinite(cols["min_swing_clearance"][sel]), cols["min_swing_clearance"][sel],
                                np.nan), "min", 3),
            f"{int(np.nansum(cols['converged'][sel]))}/{int(sel.sum())}",
        ))
    return Summary(
        title="TITAN XI: planned walks executed in MuJoCo (titan.walk)",
        columns=("terrain", "map", "slope [deg]", "heading [deg]", "runs", "success", "distance [m]",
                 "sim min NESM [m]", "plan min NESM [m]", "walks with a foot on a frame", "touchdown error [m]",
                 "swing clearance [m]", "standard gait at the end"),
        rows=tuple(rows),
        notes=("mean (worst) over the seeds (survey noise and start jitter drawn from each row's seed)",
               "S_NE^c = 0.03 m, L_std = 0.5 m, W_std = 1.0 m: default (ours), the paper gives no values",
               "standard gait at the end: the last 2 cycles with |L| = L_std, |W| = W_std and no modification "
               "(Fig. 5; meaningful where the walk leaves the frames, the long field)"),
    )


WALK = Analysis(
    name="titan.walk",
    doc="TITAN XI's planned walks (exact or surveyed maps) executed in MuJoCo on frame grids, slopes and the "
        "Sec. 8.3 long field.",
    params=PARAMS,
    metrics=METRICS,
    simulate=simulate,
    statuses=STATUSES,
    summarize=summarize,
    x64=True,
)

