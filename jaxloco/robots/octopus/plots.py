"""Plots of the OCTOPUS sweeps (Chen et al., ROBOMECH J. 2018); the workbench plots that
read any table (heatmap, plot_tuning, plot_validation) are in `jaxloco.plots`.

    plot_accuracy_map(table, sigma)              terrain-classification accuracy over terrain
                                                 type x height for one (sigma_1, sigma_2, sigma_3)
    climb_trace(records, i, times)               pitch, roll, stability margin, phase, arm joints
                                                 and torques over time of one recorded rollout
    plot_climb_traces(traces, paper)             pitch and margin over time, one line per run
                                                 (Figs. 12-13)
    plot_attitude_traces(traces, paper)          pitch and roll over time (Figs. 16, 18)
    plot_arm_joints(trace, arms)                 swing, boom, elbow of two arms over time with the
                                                 robot phases shaded (Fig. 14, phases A-F)
    plot_arm_on_obstacle(trace, arm)             one arm's joints and elbow torque over time, with
                                                 the time its roller rode an obstacle (Fig. 20)
    plot_climb_geometry(step_height)             what pitch puts the front main wheel on a step top
                                                 with the robot on its rear flipper tips, and where
                                                 it turns over backwards (closed form, `kinematics`)
    plot_cog_lead(step_height)                   how far ahead of a step edge the COG gets on the
                                                 rear flipper tips and the edge alone, against the
                                                 COG's place and height (`kinematics`)

A table is a `pyarrow.Table` or a mapping of column name to array. Every plot function
returns the matplotlib Figure; matplotlib is imported inside the functions. Nothing here
imports JAX at import time (`climb_trace` computes margins with `jaxloco.sim.metrics`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from jaxloco.plots import column, heatmap, spans

__all__ = ["TERRAIN_NAMES", "climb_trace", "plot_accuracy_map", "plot_arm_joints", "plot_arm_on_obstacle",
           "plot_attitude_traces", "plot_climb_geometry", "plot_climb_traces", "plot_cog_lead"]

TERRAIN_NAMES = ("flat", "step up", "step down", "slope up", "slope down", "rough")  # analysis.TERRAINS order
ARM_LABELS = ("LF", "RF", "LR", "RR")  # params.ARM_LABELS (arms 1..4)
# the CLM robot phases (clm.PHASE_NAMES, in order) and the phases of the paper's Fig. 14
# they correspond to: A initialisation and B walking with arm transfers are our WALK (C,
# the stop at the step, is WALK's approach after the step is confirmed), D the posture
# adjustment (PREPARE), E the climb, F the release; DONE and CRAWL come after or beside it
CLM_PHASES = ("walk", "prepare", "climb", "release", "done", "crawl")
PAPER_PHASE = {"walk": "A-C", "prepare": "D", "climb": "E", "release": "F", "done": "after F", "crawl": "CRAWL (ours)"}
OBSTACLE_MIN = 0.1  # [m] scenarios.OBSTACLE_MIN: a roller contact this high is on an obstacle top

# ------------------------------------------------------------------------- OCTOPUS
def plot_accuracy_map(table: Any, sigma: Sequence[float] | None = None, *, ax=None, value: str = "accuracy",
                      figsize=(5.6, 3.6)):
    """Terrain-classification accuracy (`octopus.terrain_classification`) over terrain type
    (rows) and height [m] (columns) for the rows with (sigma_1, sigma_2, sigma_3) = `sigma`
    [m] (default: the first sigma setting of the table)."""
    s = np.column_stack([np.asarray(column(table, n), float) for n in ("sigma1", "sigma2", "sigma3")])
    target = s[0] if sigma is None else np.asarray(sigma, float)
    where = np.all(np.isclose(s, target[None]), axis=1)
    if not where.any():
        raise ValueError(f"no rows with sigma = {tuple(target)}")
    terrains = np.unique(np.asarray(column(table, "terrain"), int)[where])
    title = f"{value}, σ = ({', '.join(f'{v:g}' for v in target)}) m"
    return heatmap(table, "height", "terrain", value, where=where, ax=ax, cmap="RdYlGn", vmin=0.0, vmax=1.0,
                   title=title, yticklabels=[TERRAIN_NAMES[t] for t in terrains], labels={"terrain": "terrain"},
                   figsize=figsize)


def climb_trace(records: Mapping[str, Any], i: int, times: Any) -> dict[str, np.ndarray]:
    """Signals over time of run `i` of a recorded OCTOPUS rollout (`scenarios.make_scenario`
    records at `times` [s], `RolloutResult.times`): t [s], pitch (nose up > 0)
    and roll [rad] from the IMU, the static stability margin [m] of the COG over the
    sites in contact (NaN with fewer than three contacts) and the controller phase."""
    import jax.numpy as jnp

    from jaxloco.sim import metrics as sm

    rpy = np.asarray(records["rpy"][i])
    contact = np.asarray(records["contact"][i], bool)
    margin = np.asarray(sm.support_margins(jnp.asarray(records["cog"][i]), jnp.asarray(records["contact_points"][i]),
                                           jnp.asarray(contact)))
    margin = np.where(contact.sum(axis=1) >= 3, margin, np.nan)
    n = len(rpy)
    return {
        "t": np.asarray(times, float)[:n],
        "pitch": -rpy[:, 1],
        "roll": rpy[:, 0],
        "margin": margin,
        "phase": np.asarray(records["phase"][i]),
        "arm_q": np.asarray(records["arm_q"][i]).reshape(n, 4, 3),
        "arm_tau": np.asarray(records["arm_tau"][i]).reshape(n, 4, 3),
        # the arm rollers are the last four sites of the support set (scenarios.SUPPORT_BODIES)
        "roller_on": contact[:, 8:12],
        "roller_z": np.asarray(records["contact_points"][i])[:, 8:12, 2],
    }


def _pitch_and(traces: Mapping[str, Mapping[str, np.ndarray]], key: str, ylabel: str, titles: tuple[str, str],
               paper: Mapping[str, Mapping[str, float]] | None, ref_lines, figsize):
    """Nose-up pitch (left, with the paper's max pitch dashed) and signal `key` (right)
    over time, one line per labelled run; `ref_lines(ax, ref, color)` draws the paper's
    lines of the right panel."""
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(1, 2, figsize=figsize, layout="constrained")
    for k, (label, tr) in enumerate(traces.items()):
        color = f"C{k}"
        a1.plot(tr["t"], tr["pitch"], color=color, lw=1.2, label=label)
        a2.plot(tr["t"], tr[key], color=color, lw=1.2, label=label)
        ref = (paper or {}).get(label, {})
        if "max_pitch" in ref:
            a1.axhline(ref["max_pitch"], color=color, ls="--", lw=1, label=f"paper max {ref['max_pitch']:g}")
        ref_lines(a2, ref, color)
    a1.set_ylabel("pitch, nose up [rad]")
    a2.set_ylabel(ylabel)
    for ax, t in zip((a1, a2), titles):
        ax.set_xlabel("time [s]")
        ax.set_title(t, fontsize="medium")
        ax.grid(alpha=0.3)
        ax.legend(fontsize="x-small")
    return fig


def plot_climb_traces(traces: Mapping[str, Mapping[str, np.ndarray]],
                      paper: Mapping[str, Mapping[str, float]] | None = None, *, figsize=(9.0, 3.4)):
    """Nose-up pitch [rad] and stability margin [m] over time, one line per labelled run
    (the paper's Figs. 12-13 compare CCM and CLM on the 400 mm step). paper: per label,
    {"max_pitch": ..., "min_margin": ...} drawn as dashed lines of the run's colour."""

    def margin_line(ax, ref, color):
        if "min_margin" in ref:
            ax.axhline(ref["min_margin"], color=color, ls="--", lw=1, label=f"paper min {ref['min_margin']:g}")

    return _pitch_and(traces, "margin", "stability margin [m]",
                      ("pitch angle (Fig. 12)", "static stability margin (Fig. 13)"), paper, margin_line, figsize)


def plot_attitude_traces(traces: Mapping[str, Mapping[str, np.ndarray]],
                         paper: Mapping[str, Mapping[str, float]] | None = None, *, figsize=(9.0, 3.4)):
    """Nose-up pitch and roll [rad] over time, one line per labelled run (the paper's Figs.
    16 and 18, two terraces from the front and from the side). paper: per label,
    {"max_pitch": ..., "max_abs_roll": ...} drawn as dashed lines (roll at +-)."""

    def roll_lines(ax, ref, color):
        if "max_abs_roll" in ref:
            for sign in (1.0, -1.0):
                ax.axhline(sign * ref["max_abs_roll"], color=color, ls="--", lw=1,
                           label=f"paper max |roll| {ref['max_abs_roll']:g}" if sign > 0 else None)

    return _pitch_and(traces, "roll", "roll [rad]", ("pitch angle", "roll angle"), paper, roll_lines, figsize)


def plot_arm_joints(trace: Mapping[str, np.ndarray], arms: Sequence[int] = (1, 3), *,
                    phase_names: Sequence[str] = CLM_PHASES, title: str = "", figsize=(9.0, 5.6)):
    """Swing, boom and elbow angles [rad] over time of two arms (indices 0..3 = LF, RF, LR,
    RR; default RF and RR, as the paper's Fig. 14), one column per arm, with the CLM robot
    phases shaded and labelled with the paper's phases A-F (`PAPER_PHASE`)."""
    import matplotlib.pyplot as plt

    t, q = trace["t"], trace["arm_q"]
    phase_spans = spans(t, np.asarray(trace["phase"]))
    fig, axes = plt.subplots(3, len(arms), figsize=figsize, layout="constrained", sharex=True, squeeze=False)
    for col, arm in enumerate(arms):
        for row, joint in enumerate(("swing", "boom", "elbow")):
            ax = axes[row, col]
            for a, b, ph in phase_spans:
                ax.axvspan(a, b, color=f"C{ph}", alpha=0.12, lw=0)
                if row == 0 and b - a > 0.04 * (t[-1] - t[0] + 1e-9):
                    name = phase_names[ph] if ph < len(phase_names) else str(ph)
                    ax.text(0.5 * (a + b), 1.02, PAPER_PHASE.get(name, name), transform=ax.get_xaxis_transform(),
                            ha="center", va="bottom", fontsize="x-small")
            ax.plot(t, q[:, arm, row], color="k", lw=1.1)
            ax.set_ylabel(f"{ARM_LABELS[arm]} {joint} [rad]")
            ax.grid(alpha=0.3)
        axes[-1, col].set_xlabel("time [s]")
    handles = [plt.Rectangle((0, 0), 1, 1, color=f"C{k}", alpha=0.3) for k in range(len(phase_names))]
    fig.legend(handles, [f"{n} ({PAPER_PHASE.get(n, n)})" for n in phase_names], loc="outside lower center",
               ncol=len(phase_names), fontsize="x-small")
    if title:
        fig.suptitle(title, fontsize="medium")
    return fig


def plot_arm_on_obstacle(trace: Mapping[str, np.ndarray], arm: int = 1, *, title: str = "", figsize=(9.0, 4.2)):
    """One arm's swing, boom and elbow angles [rad] and its elbow torque [N m] over time
    (the paper's Fig. 20: RF meets the block at t1, rides its top, is back on the ground
    at t2), with the time its roller carried load on an obstacle top (>= OBSTACLE_MIN
    above the floor) shaded."""
    import matplotlib.pyplot as plt

    t, q, tau = trace["t"], trace["arm_q"], trace["arm_tau"]
    up = np.asarray(trace["roller_on"], bool)[:, arm] & (np.asarray(trace["roller_z"])[:, arm] > OBSTACLE_MIN)
    fig, (a1, a2) = plt.subplots(1, 2, figsize=figsize, layout="constrained", sharex=True)
    for a, b, on in spans(t, up.astype(int)):
        if on:
            for ax in (a1, a2):
                ax.axvspan(a, b, color="C3", alpha=0.15, lw=0)
    for j, joint in enumerate(("swing", "boom", "elbow")):
        a1.plot(t, q[:, arm, j], lw=1.1, label=joint)
    a2.plot(t, tau[:, arm, 2], color="k", lw=1.0, label="elbow torque")
    a1.set_ylabel(f"{ARM_LABELS[arm]} joint angles [rad]")
    a2.set_ylabel(f"{ARM_LABELS[arm]} elbow torque [N m]")
    for ax in (a1, a2):
        ax.set_xlabel("time [s]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize="x-small", title="shaded: roller on the obstacle top" if ax is a1 else None,
                  title_fontsize="x-small")
    if title:
        fig.suptitle(title, fontsize="medium")
    return fig


def plot_climb_geometry(step_height: float = 0.4, rear_flippers: Sequence[float] = (0.0, -0.3, -0.83), *,
                        mu: float = 0.8, paper_pitch: float = 0.60, stall: tuple[float, float] | None = None,
                        figsize=(10.0, 4.0)):
    """What the crawlers' side profile asks of a climb (closed form, `kinematics`): left,
    the front main axle's height [m] against the nose-up pitch [rad] with the robot on its
    rear flipper tips, one line per rear flipper angle [rad] (0 in line, < 0 turned down),
    and the height that puts the front wheel on a `step_height` top; right, the least
    such pitch and the pitch at which the robot turns over backwards on its rear flipper
    tips (`tipping_pitch_on_rear_tips`) against the rear flipper angle, the window between
    them and atan(mu) shaded. Both mark the paper's pitch, atan(mu) (a
    track driving up the edge slips above it, by friction alone) and, if given, the
    pitches at which our simulated climbs stall with their tracks loaded (the common-axis
    and rear-flipper readings, docs/octopus.md)."""
    import matplotlib.pyplot as plt

    from jaxloco.robots.octopus import kinematics, params

    need = step_height + params.MAIN_WHEEL_RADIUS
    slip = float(np.arctan(mu))
    fig, (a1, a2) = plt.subplots(1, 2, figsize=figsize, layout="constrained")
    pitch = np.linspace(0.0, 1.2, 241)
    for k, rear in enumerate(rear_flippers):
        h = np.asarray(kinematics.front_axle_height_on_rear_tips(pitch, rear))
        valid = pitch >= rear
        a1.plot(pitch[valid], h[valid], color=f"C{k}", lw=1.3, label=f"rear flippers {rear:+.2f} rad")
        p0 = float(kinematics.mount_pitch_on_rear_tips(step_height, rear))
        if np.isfinite(p0):
            a1.plot([p0], [need], "o", color=f"C{k}", ms=5)
    a1.axhline(need, color="k", lw=0.9, ls="--", label=f"front wheel on a {step_height:g} m top")
    a1.set_ylabel("front main axle height [m]")
    rear = np.linspace(-params.FLIPPER_LIMIT, 0.3, 241)
    mount = np.asarray(kinematics.mount_pitch_on_rear_tips(step_height, rear))
    tip = np.asarray(kinematics.tipping_pitch_on_rear_tips(rear))
    a2.plot(rear, mount, color="k", lw=1.3, label="least pitch, front wheel on the top")
    a2.plot(rear, tip, color="C1", lw=1.3, label="turns over backwards beyond")
    window = np.isfinite(mount) & (mount < np.minimum(tip, slip))
    a2.fill_between(rear, mount, np.minimum(tip, slip), where=window, color="C2", alpha=0.25, lw=0,
                    label="mounts without slipping or tipping")
    a2.set_xlabel("rear flipper angle [rad] (< 0: turned down)")
    a2.set_ylabel("pitch [rad]")
    for ax, horizontal in ((a1, False), (a2, True)):
        line = ax.axhline if horizontal else ax.axvline
        span = ax.axhspan if horizontal else ax.axvspan
        line(paper_pitch, color="C2", lw=1.0, ls=":", label=f"paper's max pitch {paper_pitch:g} rad")
        line(slip, color="C3", lw=1.0, ls="-.", label=f"atan(mu), mu {mu:g}: tracks slip beyond")
        if stall is not None:
            span(*stall, color="C3", alpha=0.12, lw=0, label="our climbs stall (tracks loaded)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize="x-small")
    a1.set_xlabel("nose-up pitch [rad]")
    fig.suptitle(f"Crawler side profile on a {step_height:g} m step, robot on its rear flipper tips", fontsize="medium")
    return fig


def plot_cog_lead(step_height: float = 0.4, cog_heights: Sequence[float] | None = None, *,
                  cog_x: Sequence[float] | None = None, figsize=(6.0, 4.0)):
    """Whether the robot can tip forward onto a `step_height` [m] top on its rear flipper
    tips and the edge alone (`kinematics.cog_lead_over_edge_on_rear_tips`): the most the
    COG gets ahead of the edge [m] against how far ahead of the rear main axle it sits
    (`cog_x` [m], default 0-0.6 m), one line per COG height above the axles
    (`cog_heights` [m], default ours, 0.1 and 0); above 0 it passes the edge. Marks our
    COG (`CrawlerProfile`) and the main crawler's front end."""
    import jax
    import matplotlib.pyplot as plt

    from jaxloco.robots.octopus import kinematics

    base = kinematics.CrawlerProfile()
    heights = (base.cog_z, 0.1, 0.0) if cog_heights is None else tuple(cog_heights)
    xs = np.linspace(0.0, 0.6, 61) if cog_x is None else np.asarray(cog_x, float)
    fig, ax = plt.subplots(figsize=figsize, layout="constrained")
    for k, cz in enumerate(heights):
        lead = jax.vmap(lambda x, cz=cz: kinematics.cog_lead_over_edge_on_rear_tips(
            step_height, base._replace(cog_x=x, cog_z=cz))[0])(xs)
        ax.plot(xs, np.asarray(lead), color=f"C{k}", lw=1.3, label=f"COG {cz:.3f} m above the axles")
    ax.axhline(0.0, color="k", lw=0.9, ls="--", label="COG over the edge")
    ax.axvline(base.cog_x, color="0.4", lw=1.0, ls=":", label=f"our COG ({base.cog_x:.3f} m, {base.cog_z:.3f} m up)")
    front = base.axle_spacing + base.wheel_radius
    ax.axvline(front, color="C3", lw=1.0, ls="-.", label=f"main crawler's front end ({front:.2f} m)")
    ax.set_xlabel("COG ahead of the rear main axle [m]")
    ax.set_ylabel("COG ahead of the edge, at best [m]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="x-small")
    ax.set_title(f"On the rear flipper tips and a {step_height:g} m edge alone (flippers "
                 f"{base.flipper_length:g} m)", fontsize="medium")
    return fig
