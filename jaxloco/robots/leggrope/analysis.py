"""`leggrope.slope_cycle`: one leg-grope walk cycle on a (simple or irregular) slope with
the force-distribution QP at every step, as a sweep analysis.

The question it answers (paper, "Simulation"): for an inclination theta and walking
direction psi, does a force distribution with friction safety margin s >= 0 exist at
every 15 ms step of the cycle? The paper reports yes for |theta| < ~0.40 rad and every
psi, against atan(mu) = 0.42 rad for a rigid block.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco.analysis import Analysis, Metric, Summary
from jaxloco.robots.leggrope import forces, gait, results
from jaxloco.robots.leggrope.params import PARAMETERS, G, LegGropeParams, default_params

# a cycle is feasible with Eq. 19 hard when no step needed more relaxation than this
# (fraction of R_ref; the interior-point QP leaves r at ~1e-9 where none is needed)
HARD_RELAXATION = 1e-6
MU = PARAMETERS.default("mu")  # the paper's friction coefficient, for the summary's note

PARAMS = PARAMETERS.select(
    "theta", "psi", "mu", "r_ref_factor", "a_max", "v_max", "h_s", "h_tau", "h_c", "stride", "swing_height",
    "facet_spread", "normal_tol", "numbering", "dt", "n_move", "n_unload", "n_swing", "n_load", "qp_iterations",
    "capacity",
)

METRICS = (
    Metric("slip_free", "a distribution with s >= 0 exists at every step", kind="bool"),
    Metric("slip_steps", "steps without a slip-free distribution", kind="int"),
    Metric("min_s", "smallest friction safety margin s of the QP (Eqs. 17-18)", "N"),
    Metric("min_s_norm", "min_s / (M g)"),
    Metric("min_capacity", "smallest slip capacity max s (only with capacity = true, else inf)", "N"),
    Metric("max_normal_ratio", "largest free stance-leg normal force / R_ref"),
    Metric("max_relaxation", "largest normal-force relaxation r (R_ref excess or grope shortfall) / R_ref"),
    Metric("feasible", "ok with Eq. 19 hard: status ok and max_relaxation <= 1e-6 (no R_ref excess or grope "
           "shortfall at all)", kind="bool"),
    Metric("plan_margin", "smallest geometric margin of the plan (COG in pi_g, foothold in step-D region)", "m"),
    Metric("min_static_margin", "smallest static stability margin of the stance", "m"),
    Metric("min_ne_margin", "smallest normalized energy stability margin of the stance", "m"),
    Metric("min_leg_margin", "smallest pyramid margin of any loaded leg", "N"),
    Metric("max_friction_use", "largest (|f_x| + |f_y|) / (mu f_z) of a leg carrying >= 10% of M g (1 = slipping)"),
    Metric("max_torque", "largest joint torque magnitude", "N m"),
    Metric("min_reach", "smallest leg reach margin (negative: unreachable)", "m"),
    Metric("max_move_time", "longest phase-A body move", "s"),
    Metric("max_qp_residual", "largest scaled primal residual of the solved QPs"),
    Metric("cycle_time", "duration of the cycle", "s"),
)

STATUSES = (
    "ok",
    "failed: slip (no distribution with s >= 0 at some step)",
    "failed: normal force beyond R_ref tolerance",
    "failed: leg out of reach",
    "failed: body move longer than phase A",
    "failed: QP did not converge",
)


def cycle_design(fixed: Mapping[str, Any]) -> gait.GaitDesign:
    """The row's leg numbering and footsteps for the A-D cycle (`gait.CYCLE_DESIGNS`)."""
    return gait.gait_design(str(fixed["numbering"]), cycle=True)


def walk_config(fixed: Mapping[str, Any]) -> tuple[gait.WalkConfig, forces.QPSettings]:
    config = cycle_design(fixed).config(
        n_move=fixed["n_move"], n_unload=fixed["n_unload"], n_swing=fixed["n_swing"], n_load=fixed["n_load"]
    )
    settings = forces.QPSettings(iterations=fixed["qp_iterations"], capacity=fixed["capacity"])
    return config, settings


class RowSetup(NamedTuple):
    """What one row's cycle is computed from (`row_setup`)."""

    params: LegGropeParams
    walk: gait.WalkParams
    terrain: gait.SlopeTerrain
    config: gait.WalkConfig
    settings: forces.QPSettings


def row_setup(values: Mapping[str, Any], key: jax.Array) -> RowSetup:
    """The robot parameters, footstep design, terrain, step counts and QP settings of one
    row; values: every parameter (`Analysis.row`'s form). What the row's metrics and its
    replay (`jaxloco.render.kinematic`) are computed from."""
    config, settings = walk_config(values)
    params = default_params().with_(
        mu=values["mu"], r_ref_factor=values["r_ref_factor"], a_max=values["a_max"], v_max=values["v_max"],
        h_s=values["h_s"], h_tau=values["h_tau"], h_c=values["h_c"], dt=float(values["dt"]),
    )
    walk = cycle_design(values).walk(stride=values["stride"], swing_height=values["swing_height"])
    terrain = gait.irregular_slope(values["theta"], values["psi"], values["facet_spread"], key)
    return RowSetup(params, walk, terrain, config, settings)


def row(values: Mapping[str, Any], key: jax.Array) -> dict[str, jax.Array]:
    """`Analysis.row`: metrics and status of one cycle; values: every parameter of PARAMS
    (the sweepable ones scalar arrays, the step counts, QP settings and numbering plain)."""
    params, walk, terrain, config, settings = row_setup(values, key)
    dt = float(values["dt"])
    plan, sm, _ = forces.simulate_cycle(params, walk, terrain, config, settings)
    weight = params.total_mass * G
    r_ref = params.r_ref_factor * weight * jnp.cos(terrain.theta)
    move = jnp.max(gait.move_durations(params, plan))
    residual_tol = 1e-3
    # a failed QP whose last iterate is (nearly) feasible did not converge; otherwise it is
    # infeasible: no slip-free distribution
    n_bad = sm.n_qp_failed
    slip = (n_bad > 0) & (sm.max_primal_residual > residual_tol)
    status = jnp.select(
        [sm.min_reach < 0, move > config.n_move * dt, slip, n_bad > 0,
         sm.max_overshoot > values["normal_tol"] * r_ref],
        [3, 4, 1, 5, 2],
        0,
    )
    relaxation = sm.max_overshoot / r_ref
    return dict(
        feasible=(status == 0) & (relaxation <= HARD_RELAXATION),
        slip_free=n_bad == 0,
        slip_steps=n_bad,
        min_s=sm.min_s,
        min_s_norm=sm.min_s / weight,
        min_capacity=sm.min_capacity,
        max_normal_ratio=sm.max_normal_ratio,
        max_relaxation=relaxation,
        plan_margin=plan.margin,
        min_static_margin=sm.min_static_margin,
        min_ne_margin=sm.min_ne_margin,
        min_leg_margin=sm.min_leg_margin,
        max_friction_use=sm.max_friction_use,
        max_torque=sm.max_torque,
        min_reach=sm.min_reach,
        max_move_time=move,
        max_qp_residual=sm.max_primal_residual,
        cycle_time=jnp.asarray(config.n_steps * dt, weight.dtype),
        status=status,
    )


def summarize(table) -> Summary:
    """Critical inclination per walking direction (`results.critical_theta`): the largest
    |theta| such that every row of that psi with 0 <= theta' <= theta (or theta <=
    theta' <= 0) is ok, the first failing |theta| and why it failed. Tables with the
    `feasible` and `max_relaxation` columns add the critical |theta| with Eq. 19 hard
    ("hard crit", + / -) and the largest relaxation used within the critical range."""
    crit = results.critical_theta(table)
    theta = results._floats(table, "theta")
    psi = results._floats(table, "psi")
    status = results._column(table, "status")

    def reason(p, t, sign):
        """Why the first failing row (psi p, theta = sign * t) failed."""
        if not np.isfinite(t):
            return "-"
        bad = [x for x in status[(psi == p) & np.isclose(theta, sign * t)] if x != "ok"]
        return bad[0].replace("failed: ", "").split(" (")[0] if bad else "-"

    fmt = lambda v: f"{v:.3f}" if np.isfinite(v) else "none"  # noqa: E731
    hard = results.critical_theta(table, ok=results._column(table, "feasible").astype(bool)) \
        if "feasible" in results._names(table) else None
    relaxation = results._floats(table, "max_relaxation") if "max_relaxation" in results._names(table) else None
    rows = []
    for i, p in enumerate(crit.psi):
        row = [f"{p:+.3f}", f"{math.degrees(p):+.0f}"]
        for sign, c, first in ((1.0, crit.plus, crit.first_fail_plus), (-1.0, crit.minus, crit.first_fail_minus)):
            row += [fmt(c[i]), fmt(first[i]) if np.isfinite(first[i]) else "-", reason(p, first[i], sign)]
        if hard is not None:
            row.append(f"{fmt(hard.plus[i])} / {fmt(hard.minus[i])}")
        if relaxation is not None:
            row.append(_relaxation_within(relaxation, psi == p, theta, crit.plus[i], crit.minus[i]))
        rows.append(tuple(row))
    swept = [n for n in table.column_names if n not in ("row", "theta", "psi", "seed")
             and (table.schema.field(n).metadata or {}).get(b"role") == b"swept"] if hasattr(table, "schema") else []
    notes = [
        "critical = largest |theta| with every smaller |theta| of that psi ok (grid resolution applies)",
        "hard crit: the same with Eq. 19 hard (feasible: no relaxation of R_ref at all), +theta / -theta; "
        "relax: the largest max_relaxation [R_ref] the ok rows within the critical range needed",
        f"paper (Ambe & Matsuno 2016): critical |theta| ~ {results.PAPER_CRITICAL_THETA:.2f} rad for every psi; "
        f"rigid block atan(mu) = {math.atan(MU):.3f} rad at mu = {MU:g}",
    ]
    if swept:
        notes.append("other swept parameters are pooled: " + ", ".join(swept))
    return Summary(
        title="leg-grope walk on slopes: critical inclination per walking direction",
        columns=("psi [rad]", "psi [deg]", "crit +theta", "first fail +", "why +",
                 "crit -theta", "first fail -", "why -",
                 *(("hard crit",) if hard is not None else ()), *(("relax",) if relaxation is not None else ())),
        rows=tuple(rows),
        notes=tuple(notes),
    )


def _relaxation_within(relaxation: np.ndarray, rows: np.ndarray, theta: np.ndarray, plus: float,
                       minus: float) -> str:
    """The largest relaxation [R_ref] among `rows` with -minus <= theta <= plus (a nan
    critical value: no row on that side), formatted; '-' if there is none."""
    upper, lower = np.nan_to_num(plus, nan=-1.0) + 1e-12, np.nan_to_num(minus, nan=-1.0) + 1e-12
    inside = rows & (theta <= upper) & (-theta <= lower)
    return f"{np.max(relaxation[inside]):.3f}" if np.any(inside) else "-"


SLOPE_CYCLE = Analysis(
    name="leggrope.slope_cycle",
    doc="One leg-grope walk cycle on a slope: is a slip-free force distribution feasible at every step?",
    params=PARAMS,
    metrics=METRICS,
    row=row,
    statuses=STATUSES,
    summarize=summarize,
    x64=True,
)
