"""`titan.stride`: the TITAN XI grid step over intermittent crawl gait (Hodoshima et al.
2007, Sec. 5-6; `gait.py`) on frame grid maps, against its stride (L_std, W_std) and the
critical NE stability margin S_NE^c, as a sweep analysis.

The question it answers: for the Sec. 7 frame fields (0.2 m frames on a 2.0 m grid,
0.3 m on 3.0 m) and the Sec. 8.4 test slope (30 deg, 0.2 m frames every 1.5 m), which
stride walks fastest (distance per cycle) while every step keeps NESM >= S_NE^c and the
foothold search never fails?

One row is `gait.sweep_plan`: a `maps.frame_grid_map` of `shape` cells of `cell` m
(origin (0, 0), frame centre lines at (k + 1/2) frame_interval in x and y; frame_size = 0
is flat ground; slope angle `slope` of the map frame), the standard start
(`gait.standard_start`) with the COG at map xy (3 m, shape[1] cell / 2), and `n_cycles`
planned cycles (`gait.plan_cycles`) along the map-frame `direction`; the metrics add the
smooth objective from the plan's per-step NESM to `gait.sweep_metrics`' (the tests check
the rows against it).
Frames: map frame of `maps` (on the slope: x up the fall line, y across, z normal to
the slope); SI units, radians.

Metrics (per row):
  * min_nesm, distance_per_cycle, n_failures, n_modifications, path_deviation: the plan's
    (`gait.GaitPlan`): smallest per-step NESM [m], mean COG progress along L_G per cycle
    [m] (0 for a held, failed cycle), cycles with no feasible trial, trial-index sum of
    modifications (a), (b), Sec. 5.5 and transitions, largest lateral offset of a
    cycle-end COG from L_G [m].
  * nesm_ok: min_nesm >= S_NE^c - 1e-9 m and n_failures == 0.
  * softmin_nesm = -tau log(sum_k exp(-nesm_k / tau)) over the S = 6 n_cycles per-step
    NESMs (tau = softmin_tau [m]): a smooth lower bound of min_nesm,
    min_nesm - tau log(S) <= softmin_nesm <= min_nesm.
  * objective = distance_per_cycle * sigmoid((softmin_nesm - S_NE^c) / tau): the speed
    (progress per cycle; every cycle is six steps) discounted smoothly by how far the
    soft-min margin is above the critical one (0.5 at softmin_nesm = S_NE^c, -> 1 well
    above it, -> 0 below it). Larger is better.

Differentiability: the objective is a smooth function of the plan's COG positions and
feet, which are piecewise smooth in l_std and w_std (the foothold search picks grid
candidates relative to the stride-dependent search start I_u; `lax.while_loop`s pick the
trial). `gait.plan_cycles` uses `lax.while_loop`, so only forward-mode derivatives exist
(`jax.jvp`, `jax.jacfwd`; `objective_fn` gives the scalar function); reverse mode
(`jax.grad`) raises. Across a change of the chosen foothold or trial the objective jumps,
so gradient tuning should use flat ground or average over frame offsets.

Directions: every heading plans (`gait.directional_stride` lengthens the stride off the
body axes; `titan_directions` sweeps 24 headings). The robot starts at map x = `start_x`
(default 3 m from the x = 0 edge) on the map's centre line with its feet about 2.1 m
from the COG; cells outside the map read forbidden, so `start_x` and the map size must
leave room for the walk (`titan_directions`: a 30 x 30 m map, start at its centre).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco.analysis import Analysis, Metric, Summary
from jaxloco.robots.titan import gait, plots
from jaxloco.robots.titan import params as titan_params

NESM_TOL = 1e-9  # [m] rounding allowance of nesm_ok's min_nesm >= S_NE^c
TITAN_PARAMS = ("l_std", "w_std", "s_ne_c", "tether")  # fields of `TitanParams` set per row

PARAMS = titan_params.PARAMETERS.select(
    "l_std", "w_std", "s_ne_c", "frame_size", "frame_interval", "frame_size_b", "frame_interval_b", "mix_block",
    "slope", "direction", "start_x", "tether", "softmin_tau", "n_cycles", "map_nx", "map_ny", "cell",
)

METRICS = (
    Metric("min_nesm", "smallest NE stability margin over every planned step", "m"),
    Metric("distance_per_cycle", "mean COG progress along the walking direction per cycle (0 for failed cycles)",
           "m"),
    Metric("n_failures", "cycles with no feasible foothold trial (the robot holds)", kind="int"),
    Metric("n_modifications", "modifications used: trial-index sum of (a), (b), Sec. 5.5 and transitions",
           kind="int"),
    Metric("path_deviation", "largest lateral offset of a cycle-end COG from its path L_G", "m"),
    Metric("nesm_ok", "min_nesm >= S_NE^c (1e-9 m allowance) and no failed cycle", kind="bool"),
    Metric("softmin_nesm", "soft-min of the per-step NESMs: -tau log sum exp(-nesm / tau)", "m"),
    Metric("objective", "distance_per_cycle * sigmoid((softmin_nesm - S_NE^c) / tau); smooth, larger is better",
           "m"),
)

STATUSES = (
    "ok",
    "failed: foothold search (a cycle with no feasible trial, robot held)",
    "failed: NESM below S_NE^c during a step",
)


def softmin(x: jax.Array, tau: jax.Array) -> jax.Array:
    """Soft minimum -tau log(sum exp(-x / tau)) of x (S,) [m] with temperature tau [m]."""
    return -tau * jax.nn.logsumexp(-x / tau)


def plan_metrics(plan: gait.GaitPlan, s_ne_c: jax.Array, tau: jax.Array) -> dict[str, jax.Array]:
    """The metrics of `METRICS` and the status code of one plan (module docstring)."""
    soft = softmin(plan.nesm, tau)
    objective = plan.distance_per_cycle * jax.nn.sigmoid((soft - s_ne_c) / tau)
    low = plan.min_nesm < s_ne_c - NESM_TOL
    failed = plan.n_failures > 0
    return {
        "min_nesm": plan.min_nesm,
        "distance_per_cycle": plan.distance_per_cycle,
        "n_failures": plan.n_failures,
        "n_modifications": plan.n_modifications,
        "path_deviation": plan.path_deviation,
        "nesm_ok": ~low & ~failed,
        "softmin_nesm": soft,
        "objective": objective,
        "status": jnp.where(failed, 1, jnp.where(low, 2, 0)).astype(jnp.int32),
    }


def row_params(values: Mapping[str, jax.Array], dtype) -> titan_params.TitanParams:
    """`TitanParams` (defaults in `dtype`) with the row's l_std, w_std, s_ne_c, tether."""
    return titan_params.default_params().astype(dtype).with_(**{n: jnp.asarray(values[n], dtype) for n in TITAN_PARAMS})


def row_plan(values: Mapping[str, Any]) -> tuple[titan_params.TitanParams, Any, gait.GaitState, gait.GaitPlan]:
    """(params, map, start, plan) of one row (`gait.sweep_setup`'s map and start,
    `gait.plan_cycles`' plan); values: every parameter (`Analysis.row`'s form). What the
    row's metrics and its replay (`jaxloco.render.kinematic`) are computed from."""
    n_cycles, shape, cell = _static(values)
    params = row_params(values, jnp.asarray(values["l_std"]).dtype)
    gmap, start = gait.sweep_setup(params, values["frame_size"], values["frame_interval"], values["slope"],
                                   values["direction"], shape, cell, **field_values(values))
    return params, gmap, start, gait.plan_cycles(params, gmap, start, n_cycles, values["direction"])


def row(values: Mapping[str, Any], key: jax.Array) -> dict[str, jax.Array]:
    """`Analysis.row`: metrics and status of one row; n_cycles and the map shape/cell are
    plain values (one compilation per sweep). No randomness: the key is unused."""
    params, _, _, plan = row_plan(values)
    return plan_metrics(plan, params.s_ne_c, values["softmin_tau"])


def field_values(values: Mapping[str, jax.Array]) -> dict[str, Any]:
    """`gait.sweep_setup`'s start_x, field_b and mix_block from a row's values."""
    return {"start_x": values["start_x"], "field_b": (values["frame_size_b"], values["frame_interval_b"]),
            "mix_block": values["mix_block"]}


def _static(fixed: Mapping[str, Any]) -> tuple[int, tuple[int, int], float]:
    return int(fixed["n_cycles"]), (int(fixed["map_nx"]), int(fixed["map_ny"])), float(fixed["cell"])


def objective_fn(fixed: Mapping[str, Any]):
    """`f(l_std, w_std) -> objective` [m] for the other parameters at `fixed` (every
    parameter of PARAMS but l_std and w_std, e.g. `STRIDE.defaults()`): the smooth tuning
    objective of one sweep point. Differentiate with forward mode (`jax.jacfwd`, `jax.jvp`);
    see the module docstring."""
    static = {p.name: fixed[p.name] for p in PARAMS if not p.sweepable}
    sweepable = [p.name for p in PARAMS if p.sweepable and p.name not in ("l_std", "w_std")]

    def f(l_std: jax.Array, w_std: jax.Array) -> jax.Array:
        dtype = jnp.result_type(l_std, w_std, float)
        values = {name: jnp.asarray(fixed[name], dtype) for name in sweepable}
        values.update(l_std=jnp.asarray(l_std, dtype), w_std=jnp.asarray(w_std, dtype))
        return row({**static, **values}, None)["objective"]

    return f


# ---------------------------------------------------------------------------- summary
GROUP = ("frame_size", "frame_interval", "slope", "direction", "tether")
STRIDE_COLS = ("l_std", "w_std", "s_ne_c")


def best_rows(cols: Mapping[str, np.ndarray]) -> list[tuple[tuple[float, ...], np.ndarray, int | None]]:
    """Per terrain case (distinct `GROUP` values, first-seen order): (key, row indices of the
    case, index of the best stride or None). The best stride is the nesm_ok row with the
    largest distance_per_cycle, ties (within 1 mm) to the larger min_nesm - S_NE^c."""
    keys = np.column_stack([np.asarray(cols[n], float) for n in GROUP])
    dist = np.asarray(cols["distance_per_cycle"], float)
    spare = np.asarray(cols["min_nesm"], float) - np.asarray(cols["s_ne_c"], float)
    ok = np.asarray(cols["nesm_ok"], bool)
    out = []
    for key in dict.fromkeys(map(tuple, keys)):
        idx = np.flatnonzero(np.all(keys == np.asarray(key), axis=1))
        good = idx[ok[idx]]
        best = None
        if good.size:
            top = good[dist[good] >= dist[good].max() - 1e-3]
            best = int(top[np.argmax(spare[top])])
        out.append((key, idx, best))
    return out


def is_direction_study(cols: Mapping[str, np.ndarray]) -> bool:
    """One stride, at least 4 headings: summarize per field over the headings."""
    one_stride = all(len(set(np.asarray(cols[n], float).tolist())) == 1 for n in STRIDE_COLS)
    return one_stride and len(set(np.asarray(cols["direction"], float).tolist())) >= 4


def summarize_directions(cols: Mapping[str, np.ndarray]) -> Summary:
    """Per field: walks, walks with min NESM >= S_NE^c and no failed cycle, failed cycles,
    the smallest min NESM (and its heading), distance per cycle mean (smallest)."""
    labels = [plots.field_label(cols, i) for i in range(len(cols["direction"]))]
    deg = np.degrees(np.asarray(cols["direction"], float)) % 360.0
    nesm = np.asarray(cols["min_nesm"], float)
    ok = np.asarray(cols["nesm_ok"], bool)
    fails = np.asarray(cols["n_failures"], int)
    dist = np.asarray(cols["distance_per_cycle"], float)
    rows, notes = [], []
    for label in dict.fromkeys(labels):
        idx = np.flatnonzero(np.asarray(labels) == label)
        worst = idx[np.argmin(nesm[idx])]
        rows.append((label, str(idx.size), f"{int(ok[idx].sum())}/{idx.size}", str(int(fails[idx].sum())),
                     f"{nesm[worst]:.3f} at {deg[worst]:.0f}", f"{dist[idx].mean():.2f} ({dist[idx].min():.2f})"))
        bad = idx[~ok[idx]]
        if bad.size:
            notes.append(f"{label}: not ok at " + ", ".join(f"{deg[i]:.0f}" for i in bad) + " deg")
    n_cycles = sorted(set(np.asarray(cols["n_cycles"], int).tolist()))
    notes += [
        f"{', '.join(map(str, n_cycles))} cycles per walk from the standard start; headings in deg (map frame, "
        f"body axes at 0, 90, 180, 270); S_NE^c = {float(cols['s_ne_c'][0]):g} m",
        f"stride L_std = {float(cols['l_std'][0]):g} m along a body axis, / max(|cos|, |sin|)^"
        f"{titan_params.STRIDE_EXPONENT:g} off it (gait.directional_stride; ours, the paper gives no stride)",
        "paper (Sec. 7): \"we confirmed that the robot walks in all directions without a problem\"",
    ]
    return Summary(
        title="TITAN XI crawl gait in every direction: planned walks per field",
        columns=("field", "walks", "ok", "failed cycles", "min NESM [m] at deg", "dist/cycle mean (min) [m]"),
        rows=tuple(rows),
        notes=tuple(notes),
    )


def summarize(table) -> Summary:
    """Per terrain case (frame size, interval, slope, direction, tether): how many strides
    kept NESM >= S_NE^c without failures, and the fastest of them (`best_rows`); for a
    direction study (one stride, many headings) `summarize_directions`."""
    cols = {k: np.asarray(v) for k, v in table.to_pydict().items()}
    if is_direction_study(cols):
        return summarize_directions(cols)
    tether_varies = len(set(np.asarray(cols["tether"], float).tolist())) > 1
    rows = []
    for key, idx, best in best_rows(cols):
        size, interval, slope, direction, tether = key
        ok = int(np.sum(np.asarray(cols["nesm_ok"], bool)[idx]))
        cells = [f"{size:g}" if size > 0 else "flat", f"{interval:g}" if size > 0 else "-",
                 f"{math.degrees(slope):.0f}", f"{direction:+.2f}"]
        if tether_varies:
            cells.append(f"{tether:g}")
        cells.append(f"{ok}/{idx.size}")
        if best is None:
            cells += ["-"] * 8
        else:
            cells += [f"{cols[n][best]:g}" for n in STRIDE_COLS]
            cells += [f"{cols['distance_per_cycle'][best]:.3f}", f"{cols['min_nesm'][best]:.3f}",
                      str(int(cols["n_modifications"][best])), f"{cols['path_deviation'][best]:.3f}",
                      f"{cols['objective'][best]:.3f}"]
        rows.append(tuple(cells))
    n_cycles = sorted(set(np.asarray(cols["n_cycles"], int).tolist()))
    notes = (
        (
            "ok = rows with min NESM >= S_NE^c and no failed cycle; best = the ok row with the largest "
            "distance per cycle (ties within 1 mm: largest min NESM - S_NE^c)"
        ),
        (
            f"{', '.join(map(str, n_cycles))} cycles per row from the standard start; slope in deg, direction in rad "
            "(map frame); objective = dist * sigmoid((softmin NESM - S_NE^c) / tau)"
        ),
        (
            f"default strides (ours; the paper gives no values): L_std = {titan_params.L_STD:g} m, "
            f"W_std = {titan_params.W_STD:g} m, "
            f"S_NE^c = {titan_params.S_NE_C:g} m (params.py; 1 m per cycle on flat ground)"
        ),
    )
    columns = ("frame [m]", "interval [m]", "slope", "dir", *(("tether",) if tether_varies else ()), "ok",
               "L_std", "W_std", "S_NE^c", "dist/cycle", "min NESM", "mods", "deviation", "objective")
    return Summary(
        title="TITAN XI crawl gait: fastest stride with NESM >= S_NE^c per terrain case",
        columns=columns,
        rows=tuple(rows),
        notes=notes,
    )


STRIDE = Analysis(
    name="titan.stride",
    doc="TITAN XI crawl gait on frame fields and slopes: min NESM, distance per cycle, search failures "
    "and modifications against the stride (L_std, W_std) and S_NE^c",
    params=PARAMS,
    metrics=METRICS,
    row=row,
    statuses=STATUSES,
    summarize=summarize,
    x64=True,
)
