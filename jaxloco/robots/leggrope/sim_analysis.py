"""`leggrope.fragile_walk`: one leg-grope walk cycle of the simulated robot over fragile
footholds on a slope (`scenarios.make_scenario`), as a sweep analysis on the native
MuJoCo backend (executor "host": the batch runs in `mujoco.batch` on every core) or on
MJX (fixed parameter `backend`; "auto": MJX on a GPU or TPU). MJX runs the scenario's
MJX variant (`make_scenario(mjx_contacts=True)`: pyramidal cone, no no-slip solver), whose
toes creep more; the same controller, terrain and metrics (docs/simulation.md: how far
the two agree).

The question it answers: for a grope reaction R_ref, a distribution of foothold
strengths R_break, a slope and a friction coefficient, does the robot finish its cycle,
how much does its attitude change when a foothold collapses, and do the normal forces
stay below R_ref outside the leg-grope step (so that probed footholds hold)?
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from jaxloco.analysis import Analysis, Metric, Simulation, Summary, mean_worst
from jaxloco.robots.leggrope import scenarios
from jaxloco.robots.leggrope.params import PARAMETERS
from jaxloco.sim.rollout import RolloutResult
from jaxloco.sim.scenario import seed_jitter

# the simulated robot and terrain: narrower ranges than the force-distribution model's
# (`params.PARAMETERS`), the scenario's default slope, and its footstep designs
PARAMS = PARAMETERS.select(
    "theta", "psi", "mu", "r_ref_factor", "stride", "swing_height", "facet_spread", "fallback_distance", "safe_blend",
    "swing_margin", "twist_relief", "shear_relief", "grope_blend", "regrope", "p_weak", "r_break_lo", "r_break_hi",
    "weak_leg", "mu_jitter", "theta_jitter", "numbering", "horizon", "nthread", "backend",
    theta={"default": scenarios.PARAM_DEFAULTS["theta"], "doc": "slope inclination (walking direction psi = 0 climbs)",
           "lo": -0.45, "hi": 0.45, "lo_open": False, "hi_open": False},
    psi={"doc": "walking direction relative to the gradient"},
    mu={"doc": "friction coefficient of the terrain", "lo": 0.05, "lo_open": False},
    r_ref_factor={"doc": "grope reaction R_ref / (M g cos theta)", "lo": 0.2, "lo_open": False},
    stride={"lo": 0.01, "hi": 0.09, "lo_open": False},
    swing_height={"lo": 0.005, "hi": 0.08},
    facet_spread={"hi": 1.0},
    numbering={"doc": "leg numbering and footstep design (gait.DESIGNS): 'mirrored' walks along x_R (paper's forward "
               "direction), 'literal' along y_R"},
)

METRICS = (
    Metric("success", "the cycle finished, the robot did not fall and no simulation diverged", kind="bool"),
    Metric("completed_gropes", "gropes finished (4 = a full cycle)", kind="int"),
    Metric("max_attitude_change", "largest change of the body's tilt from the start", "rad"),
    Metric("max_abs_roll", "largest |roll| of the body (IMU)", "rad"),
    Metric("max_abs_pitch", "largest |pitch| of the body (IMU)", "rad"),
    Metric("max_normal_ratio", "largest toe normal force / R_ref outside the leg-grope step D'"),
    Metric("grope_ratio_min", "smallest normal force / R_ref reached at the end of a grope (0 if not groped)"),
    Metric("max_load_over_probe", "largest normal force on a groped foothold after its grope / the force the "
           "grope probed it with, the larger of the filtered peak and the raw load recorded in the grope (> 1: "
           "loaded beyond what was verified; nan before the first grope ends)"),
    Metric("max_load_over_probe_steady", "max_load_over_probe without the 0.2 s after each foothold collapse (the "
           "paper's Fig. 14: normal forces below R_ref 'except for the impulse' of a collapse)"),
    Metric("min_margin", "smallest static stability margin over the actual toe contacts (>= 3 loaded)", "m"),
    Metric("collapses_met", "footholds that collapsed under the groping leg", kind="int"),
    Metric("collapses_survived", "collapses met without falling", kind="int"),
    Metric("unexpected_collapses", "collapses of footholds that were not being groped", kind="int"),
    Metric("fell", "the body tilted more than 0.35 rad from the start, or the simulation diverged", kind="bool"),
    Metric("cycle_time", "time to finish the cycle (nan if not finished)", "s"),
    Metric("plan_margin", "smallest geometric margin of the plan (primary footholds) that its COG rule maximizes "
           "(gait.CyclePlan.rule_margin)", "m"),
    Metric("collapsed_leg", "the leg (0..3 = L1..L4) groping when a foothold first collapsed (-1: none)",
           kind="int"),
    Metric("collapse_tilt", "attitude change over the 0.2 s after the first collapse (paper Fig. 13: ~2 deg; nan: "
           "no collapse)", "rad"),
    Metric("max_foothold_offset", "largest distance of a loaded toe's contact point from the centre of the "
           "foothold it stands on, in the foothold's plane (not the groping leg from C* to the end of D'-2, "
           "while it retries a fallback, or after the walk stopped)", "m"),
    Metric("off_foothold", "a loaded toe slid off its foothold (max_foothold_offset > the pad half side, "
           "scenarios.PAD_HALF: outside the circle inscribed in the square pad): the walk fails", kind="bool"),
    Metric("late_collapses", "groped footholds that collapsed once their grope had accepted them, under a load it "
           "did not verify (weak or not; the premise's violations are late_weak_collapses)", kind="int"),
    Metric("late_weak_collapses", "late_collapses of footholds weaker than R_ref, which their grope should have "
           "broken (the others are stronger footholds broken later, e.g. by a neighbour's collapse)", kind="int"),
    Metric("weak_accepted", "groped footholds weaker than R_ref that their grope accepted and that still stand",
           kind="int"),
    Metric("tilt_change", "largest change of the body's tilt from the start, in degrees (max_attitude_change)",
           "deg"),
    Metric("t_diverged", "time the simulation diverged (nan: it did not)", "s"),
)

STATUSES = ("ok", "failed: no foothold", "failed: timeout", "diverged", "fell", "stopped: foothold collapsed",
            "failed: slid off a foothold")
# the jitters draw from the row's key with its low bits flipped, so that they do not
# repeat the draws the same key makes for the terrain and the weak footholds
JITTER_SALT = 0x5EED
_SCENARIO_STATUS = {"ok": 0, "no_foothold": 1, "timeout": 2, "stopped_on_collapse": 5}


def scenario(plain: Mapping[str, Any]):
    """The fragile-slope scenario of a sweep (horizon, numbering, and the backend that
    runs it: "mjx" gets the MJX variant)."""
    return scenarios.make_scenario(horizon_s=float(plain["horizon"]), record_every=5, numbering=str(plain["numbering"]),
                                   mjx_contacts=str(plain["backend"]) == "mjx")


def params(values: Mapping[str, Any], keys: np.ndarray) -> dict[str, Any]:
    """One simulation per row: its parameters, mu and theta jittered from the row's key."""
    columns = {p.name: np.asarray(values[p.name]) for p in PARAMS if p.sweepable}
    u = seed_jitter(keys ^ np.uint32(JITTER_SALT), 2)  # mu, theta
    columns["mu"] = np.maximum(columns["mu"] + u[:, 0] * columns.pop("mu_jitter"), 0.05)
    columns["theta"] = columns["theta"] + u[:, 1] * columns.pop("theta_jitter")
    return scenarios.params_batch(keys.shape[0], **columns)


def metrics(values: Mapping[str, Any], result: RolloutResult) -> dict[str, np.ndarray]:
    """The metrics and status of each row's simulated cycle."""
    out = {m.name: np.asarray(result.metrics[m.name]) for m in METRICS if m.name in result.metrics}
    out["t_diverged"] = result.t_diverged
    out["tilt_change"] = np.degrees(out["max_attitude_change"])
    fell = np.asarray(result.metrics["fell"], bool)
    code = np.array([_SCENARIO_STATUS.get(s, 3) for s in result.status])
    off = np.asarray(result.metrics["off_foothold"], bool) & (code == 0)
    code = np.where(result.diverged, 3, np.where(fell & ~result.diverged, 4, np.where(off, 6, code)))
    out["success"] = np.asarray(out["success"], bool) & ~result.diverged
    out["status"] = code
    return out


def summarize(table) -> Summary:
    """Success rate and the worst cases, grouped by R_ref factor, p_weak and the weak leg
    (`weak_leg`: the collapse experiments)."""
    cols = {n: table.column(n).to_numpy(zero_copy_only=False) for n in table.column_names}
    n_rows = len(cols["r_ref_factor"])
    weak = cols.get("weak_leg", np.full(n_rows, -1))
    keys = sorted({(float(a), float(b), int(c)) for a, b, c in zip(cols["r_ref_factor"], cols["p_weak"], weak)})
    rows = []
    for r_ref, p_weak, leg in keys:
        sel = (cols["r_ref_factor"] == r_ref) & (cols["p_weak"] == p_weak) & (weak == leg)
        rows.append((
            f"{r_ref:.2f}", f"{p_weak:.2f}", "-" if leg < 0 else f"L{leg + 1}", str(int(sel.sum())),
            f"{100 * np.mean(cols['success'][sel]):.0f}%",
            f"{np.degrees(np.nanmax(cols['max_attitude_change'][sel])):.1f}",
            _mean_worst(cols, "collapse_tilt", sel, np.degrees(1.0), 1),
            f"{np.nanmax(cols['max_normal_ratio'][sel]):.2f}",
            f"{int(np.sum(cols['collapses_met'][sel]))}/{int(np.sum(cols['collapses_survived'][sel]))}",
            f"{np.nanmin(cols['min_margin'][sel]) * 1000:.0f}",
            _load_over_probe(cols, sel),
            _load_over_probe(cols, sel, "max_load_over_probe_steady"),
            _late_and_weak(cols, sel),
        ))
    backend = cols.get("backend")
    simulator = "MJX, toes creep more" if backend is not None and len(backend) and str(backend[0]) == "mjx" \
        else "native MuJoCo"
    return Summary(
        title=f"leg-grope walk over fragile footholds ({simulator})",
        columns=("R_ref/Mg cos", "p_weak", "weak leg", "runs", "success", "max tilt change [deg]",
                 "collapse tilt [deg]", "max N/R_ref outside D'", "collapses met/survived", "min margin [mm]",
                 "load / probe", "load / probe, no impulse", "late (weak) / weak accepted"),
        rows=tuple(rows),
        notes=("other swept parameters are pooled; paper: attitude change ~2 deg when L1's foothold collapses",
               "collapse tilt: the attitude change over the 0.2 s after the first collapse, mean (worst) over the "
               "runs with a collapse",
               "load / probe: a groped foothold's largest later normal force / the force its grope probed it with, "
               "mean (worst) over the successful runs; > 1: loaded beyond what the grope verified; 'no impulse': "
               "without the 0.2 s after each collapse (paper Fig. 14: below R_ref 'except for the impulse')",
               "late (weak) / weak accepted: groped footholds that collapsed after their grope accepted them (of "
               "them weaker than R_ref) / weaker than R_ref and accepted, summed over the runs (the method's premise: "
               "(0) / 0)"),
    )


def _late_and_weak(cols: dict, sel: np.ndarray) -> str:
    """'late (late weak) / weak accepted', each summed over `sel` ('-' for an older table
    without the columns; the '(late weak)' part only where the table has it)."""
    if "late_collapses" not in cols or "weak_accepted" not in cols:
        return "-"
    late = f"{int(np.sum(cols['late_collapses'][sel]))}"
    if "late_weak_collapses" in cols:
        late += f" ({int(np.sum(cols['late_weak_collapses'][sel]))})"
    return f"{late} / {int(np.sum(cols['weak_accepted'][sel]))}"


def _mean_worst(cols: dict, name: str, sel: np.ndarray, scale: float = 1.0, digits: int = 2) -> str:
    """`mean_worst` of column `name` (times `scale`) over `sel`, worst = largest ('-' for an
    older table without the column)."""
    return mean_worst(cols[name][sel].astype(float) * scale, "max", digits) if name in cols else "-"


def _load_over_probe(cols: dict, sel: np.ndarray, name: str = "max_load_over_probe") -> str:
    """'mean (worst)' of column `name` (a load / probe metric) over the successful rows of
    `sel` ('-' for an older table without the column)."""
    return _mean_worst(cols, name, sel & cols["success"].astype(bool))


FRAGILE_WALK = Analysis(
    name="leggrope.fragile_walk",
    doc="The simulated leg-grope walk (position control, toe force sensors) over fragile footholds on a slope.",
    params=PARAMS,
    metrics=METRICS,
    simulate=Simulation(scenario, params, metrics),
    statuses=STATUSES,
    summarize=summarize,
    x64=True,
)
