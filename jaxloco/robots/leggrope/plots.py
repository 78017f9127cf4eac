"""Plots of the leg-grope slope sweep (`leggrope.slope_cycle`) and of one recorded cycle.

Table plots take the sweep table (a `pyarrow.Table`, or any mapping of column name to
array, e.g. a dict or a pandas DataFrame) with at least the columns theta [rad], psi
[rad] and status, plus mu and the metric plotted where used:

    plot_feasibility_map(table)           status over the (theta, psi) grid
    plot_critical_theta(table)            critical +theta / -theta per psi
    plot_metric_vs_theta(table, metric)   one metric vs theta, a line per psi

Cycle plots take the `trace` dict of `forces.simulate_cycle(..., record=True)`
(NumPy or JAX arrays, one entry per 15 ms step):

    plot_cycle_forces(trace)    ground reactions per leg (the paper's Fig. 7)
    plot_cycle_margin(trace)    friction safety margin s (Fig. 8)
    plot_cycle_torques(trace)   joint torques per leg (Fig. 9)

Every function returns the matplotlib Figure. matplotlib is an optional dependency: it
is imported inside the functions, so importing this module (or jaxloco) never needs it.
Nothing here imports JAX.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from jaxloco.plots import new_axes
from jaxloco.robots.leggrope.results import (  # critical_theta, status_category: public here too
    PAPER_CRITICAL_THETA,
    _categories,
    _field_meta,
    _floats,
    _mus,
    critical_theta,
    status_category,
)

__all__ = [
    "critical_theta",
    "status_category",
    "plot_feasibility_map",
    "plot_critical_theta",
    "plot_metric_vs_theta",
    "plot_cycle_forces",
    "plot_cycle_margin",
    "plot_cycle_torques",
]

LEGS = ("L1", "L2", "L3", "L4")
GROPE_ORDER = (1, 0, 2, 3)  # L2, L1, L3, L4: `gait.WalkConfig.order`; used only when a trace has no `free`
PHASES = ("A move", "B unload", "C swing", "D load")
PHASE_COLORS = ("#ececec", "#fbd9b5", "#c9def2", "#cdeac4")
CATEGORIES = ("ok", "slip", "other failure")
CATEGORY_COLORS = ("#4c9a4c", "#d9822b", "#b03a3a")


def _edges(values: np.ndarray) -> np.ndarray:
    """Cell edges around sorted grid values (midpoints; half a spacing beyond the ends)."""
    if len(values) == 1:
        return np.array([values[0] - 0.5, values[0] + 0.5])
    mid = 0.5 * (values[1:] + values[:-1])
    return np.concatenate([[2 * values[0] - mid[0]], mid, [2 * values[-1] - mid[-1]]])


def _psi_label(p: float) -> str:
    return f"{p:+.3f} ({math.degrees(p):+.0f}°)"


def _theta_references(ax, mus: Sequence[float], *, vertical: bool, both_signs: bool, alpha: float = 1.0):
    """The paper's critical 0.40 (dashed) and atan(mu) of each mu (dotted)."""
    line = ax.axvline if vertical else ax.axhline
    signs = (1.0, -1.0) if both_signs else (1.0,)
    for k, sign in enumerate(signs):
        line(sign * PAPER_CRITICAL_THETA, color="k", ls="--", lw=1.2, alpha=alpha,
             label=f"paper critical |θ| = {PAPER_CRITICAL_THETA:.2f}" if k == 0 else None)
    for j, mu in enumerate(mus):
        for k, sign in enumerate(signs):
            line(sign * math.atan(mu), color="0.35" if j == 0 else f"C{j + 5}", ls=":", lw=1.5, alpha=alpha,
                 label=f"atan(μ = {mu:g}) = {math.atan(mu):.3f}" if k == 0 else None)


# --------------------------------------------------------------------------- table plots


def plot_feasibility_map(table: Any, *, ax=None, figsize=(8.0, 3.6)):
    """Status of every cycle over the grid: inclination theta [rad] (x) vs walking
    direction psi [rad] (y), colored ok / slip / other failure.

    A cell with several rows (seeds or pooled parameters) shows its worst category; a
    missing cell stays blank. Marked: the paper's critical |theta| = 0.40 rad (dashed)
    and atan(mu) (dotted; 0.423 rad at mu = 0.45), the rigid-block sliding limit.
    """
    from matplotlib.colors import BoundaryNorm, ListedColormap
    from matplotlib.patches import Patch

    theta, psi, cat = _floats(table, "theta"), _floats(table, "psi"), _categories(table)
    thetas, psis = np.unique(theta), np.unique(psi)
    grid = np.full((len(psis), len(thetas)), -1)
    np.maximum.at(grid, (np.searchsorted(psis, psi), np.searchsorted(thetas, theta)), cat)
    fig, ax = new_axes(ax, figsize)
    cmap = ListedColormap(CATEGORY_COLORS)
    norm = BoundaryNorm([-0.5, 0.5, 1.5, 2.5], cmap.N)
    ax.pcolormesh(_edges(thetas), _edges(psis), np.ma.masked_less(grid, 0), cmap=cmap, norm=norm)
    ax.hlines(_edges(psis)[1:-1], _edges(thetas)[0], _edges(thetas)[-1], color="white", lw=1.5)  # row separators
    _theta_references(ax, _mus(table), vertical=True, both_signs=True)
    ax.set_yticks(psis, [_psi_label(p) for p in psis])
    ax.set_xlabel("inclination θ [rad]  (θ > 0: ψ = 0 climbs)")
    ax.set_ylabel("walking direction ψ [rad]")
    ax.set_title("leg-grope walk on a slope: status per cycle")
    handles = [Patch(color=c, label=f"{n} ({int(np.sum(cat == i))})") for i, (n, c) in
               enumerate(zip(CATEGORIES, CATEGORY_COLORS))]
    handles += ax.get_legend_handles_labels()[0]
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=3, fontsize="small",
              frameon=False)
    return fig


def plot_critical_theta(table: Any, *, ax=None, figsize=(6.4, 4.0)):
    """Critical inclination [rad] per walking direction psi [rad] (see `critical_theta`):
    the +theta side (circles; psi = 0 climbs) and the -theta side as |theta| (squares),
    with a thin bar up to the first failing |theta| (the grid resolution), against the
    paper's 0.40 rad (dashed) and atan(mu) (dotted). A side that fails already at
    theta = 0 has no marker.
    """
    crit = critical_theta(table)
    fig, ax = new_axes(ax, figsize)
    dx = 0.01 * (float(np.ptp(crit.psi)) or 1.0)  # the two sides' bars side by side
    for values, fails, marker, color, label, offset in (
        (crit.plus, crit.first_fail_plus, "o", "C0", "+θ side", -dx),
        (crit.minus, crit.first_fail_minus, "s", "C3", "−θ side (|θ|)", dx),
    ):
        ax.plot(crit.psi, values, marker=marker, color=color, label=label)
        has = np.isfinite(values) & np.isfinite(fails)
        ax.vlines(crit.psi[has] + offset, values[has], fails[has], color=color, lw=3, alpha=0.35)
    _theta_references(ax, _mus(table), vertical=False, both_signs=False)
    ax.set_xticks(crit.psi, [f"{p:+.2f}\n({math.degrees(p):+.0f}°)" for p in crit.psi])
    ax.set_xlabel("walking direction ψ [rad]")
    ax.set_ylabel("critical |θ| [rad]")
    ax.set_title("largest |θ| with every smaller |θ| slip-free\n(bars: up to the first failing |θ|)",
                 fontsize="medium")
    finite = np.concatenate([crit.plus, crit.minus, crit.first_fail_plus, crit.first_fail_minus])
    finite = finite[np.isfinite(finite)]
    lo = min([PAPER_CRITICAL_THETA, *finite]) if len(finite) else PAPER_CRITICAL_THETA
    hi = max([math.atan(m) for m in _mus(table)] + [*finite, PAPER_CRITICAL_THETA])
    pad = 0.15 * max(hi - lo, 0.05)
    ax.set_ylim(lo - pad, hi + pad)
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.0, 1.0))
    return fig


def plot_metric_vs_theta(table: Any, metric: str, *, ax=None, mark_failed: bool = True, paper: bool = True,
                         hline: float | None = None, figsize=(7.0, 4.0)):
    """A metric column vs inclination theta [rad], one line per walking direction psi.

    The y unit comes from the column's metadata (e.g. min_ne_margin [m], max_torque
    [N m]; max_friction_use and max_relaxation are ratios). Non-finite values are left
    out. mark_failed: an x on every row whose status is not ok. paper: the paper's
    critical theta = +-0.40 rad as gray dashed lines. hline: a horizontal reference
    line (e.g. 1.0 for max_friction_use, where a leg slips).
    """
    theta, psi = _floats(table, "theta"), _floats(table, "psi")
    values = _floats(table, metric)
    values = np.where(np.isfinite(values), values, np.nan)
    failed = _categories(table) != 0
    fig, ax = new_axes(ax, figsize)
    for i, p in enumerate(np.unique(psi)):
        sel = np.nonzero(psi == p)[0]
        sel = sel[np.argsort(theta[sel], kind="stable")]
        ax.plot(theta[sel], values[sel], color=f"C{i}", lw=1.5, label=f"ψ = {_psi_label(p)}")
        bad = sel[failed[sel]]
        if mark_failed and len(bad):
            ax.scatter(theta[bad], values[bad], marker="x", s=14, color=f"C{i}", lw=0.8)
    if paper:
        for k, sign in enumerate((1.0, -1.0)):
            ax.axvline(sign * PAPER_CRITICAL_THETA, color="0.4", ls="--", lw=1,
                       label=f"paper |θ| = {PAPER_CRITICAL_THETA:.2f}" if k == 0 else None)
    if hline is not None:
        ax.axhline(hline, color="k", lw=0.8)
    meta = _field_meta(table, metric)
    unit = meta.get("unit", "")
    ax.set_xlabel("inclination θ [rad]")
    ax.set_ylabel(f"{metric} [{unit}]" if unit else metric)
    doc = meta.get("doc", "")
    ax.set_title(f"{metric}: {doc}" if doc else metric, fontsize="small")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="x-small", title="× : status not ok" if mark_failed else None, title_fontsize="x-small")
    return fig


# --------------------------------------------------------------------------- cycle plots


def _trace(trace: Mapping[str, Any], *names: str) -> list[np.ndarray]:
    missing = [n for n in names if n not in trace]
    if missing:
        raise KeyError(f"the trace has no {', '.join(missing)}")
    return [np.asarray(trace[n]) for n in names]


def _segments(time: np.ndarray, grope: np.ndarray, phase: np.ndarray):
    """(t_start, t_end, grope, phase) of each run of equal (grope, phase); a step covers
    [time - dt, time] (the trace's time is the end of its step)."""
    dt = float(np.median(np.diff(time))) if len(time) > 1 else float(time[0])
    change = np.nonzero((np.diff(grope) != 0) | (np.diff(phase) != 0))[0] + 1
    starts = np.concatenate([[0], change])
    ends = np.concatenate([change, [len(time)]]) - 1
    return [(time[a] - dt, time[b], int(grope[a]), int(phase[a])) for a, b in zip(starts, ends)]


def _groping_legs(trace: Mapping[str, Any], order: Sequence[int]) -> dict[int, int]:
    """grope index -> leg index: the leg that is not free during phases B-D (from the
    trace's `free`), else `order`."""
    grope, phase = _trace(trace, "grope", "phase")
    legs = {}
    free = np.asarray(trace["free"]) if "free" in trace else None
    for g in np.unique(grope):
        leg = order[int(g)] if int(g) < len(order) else -1
        if free is not None:
            steps = (grope == g) & (phase > 0)
            held = np.nonzero(~free[steps].all(axis=0))[0] if np.any(steps) else []
            if len(held) == 1:
                leg = int(held[0])
        legs[int(g)] = leg
    return legs


def _shade_phases(ax, segments) -> None:
    for t0, t1, _, ph in segments:
        ax.axvspan(t0, t1, color=PHASE_COLORS[ph % 4], lw=0, zorder=0)


def _label_gropes(ax, segments, legs: Mapping[int, int], numbering: Sequence[int]) -> None:
    """The groping leg's name above each grope (x in data, y in axes coordinates);
    numbering[i] is the physical leg the paper calls L(i+1)."""
    trans = ax.get_xaxis_transform()
    for g in sorted({s[2] for s in segments}):
        t0 = min(s[0] for s in segments if s[2] == g)
        t1 = max(s[1] for s in segments if s[2] == g)
        name = LEGS[list(numbering).index(legs[g])] if 0 <= legs.get(g, -1) < 4 else f"#{g}"
        ax.text(0.5 * (t0 + t1), 1.01, f"grope {name}", transform=trans, ha="center", va="bottom",
                fontsize="x-small")


def _phase_legend(fig) -> None:
    from matplotlib.patches import Patch

    engine = fig.get_layout_engine()
    outside = engine is not None and type(engine).__name__ == "ConstrainedLayoutEngine"
    fig.legend(handles=[Patch(color=c, label=n) for n, c in zip(PHASES, PHASE_COLORS)],
               loc="outside lower center" if outside else "lower center", ncol=4, fontsize="small", frameon=False,
               title="phase", title_fontsize="small")


def _new_figure(fig, nrows: int, figsize):
    import matplotlib.pyplot as plt

    if fig is None:
        fig = plt.figure(figsize=figsize, layout="constrained")
    axes = fig.subplots(nrows, 1, sharex=True, squeeze=False)[:, 0]
    return fig, axes


def plot_cycle_forces(trace: Mapping[str, Any], *, fig=None, order: Sequence[int] = GROPE_ORDER,
                      numbering: Sequence[int] = (0, 1, 2, 3), figsize=(8.0, 9.0)):
    """Ground reactions on each leg over one cycle (the paper's Fig. 7): a panel per leg
    L1..L4 with F_x (along the slope gradient), F_y and F_z (normal) in the leg's contact
    frame [N] vs time [s], R_ref [N] dashed, phases A-D shaded and the leg's own grope
    (unload, swing, load) hatched and named above the panel.

    trace: `forces.simulate_cycle(..., record=True)`'s dict (time, grope, phase, forces
    (n, 4, 3), r_ref; free is used to find the groping leg, else `order`). numbering: the
    physical leg of the paper's L1..L4 (`gait.GaitDesign.legs`; the panels follow it).
    """
    time, grope, phase, f, r_ref = _trace(trace, "time", "grope", "phase", "forces", "r_ref")
    r_ref = np.broadcast_to(r_ref, time.shape)
    segments = _segments(time, grope, phase)
    legs = _groping_legs(trace, order)
    fig, axes = _new_figure(fig, 4, figsize)
    for label, (n, ax) in enumerate(zip(numbering, axes)):
        _shade_phases(ax, segments)
        for c, (name, color) in enumerate(zip(("F_x", "F_y", "F_z"), ("C0", "C1", "C2"))):
            ax.plot(time, f[:, n, c], color=color, lw=1.3, label=f"${name[0]}_{name[2]}$")
        ax.plot(time, r_ref, color="k", ls="--", lw=1, label="$R_{ref}$")
        own = [s for s in segments if legs.get(s[2]) == n and s[3] > 0]
        if own:
            t0, t1 = min(s[0] for s in own), max(s[1] for s in own)
            ax.axvspan(t0, t1, fill=False, hatch="///", edgecolor="0.6", lw=0, zorder=0.5)
            ax.text(0.5 * (t0 + t1), 1.01, f"{LEGS[label]} gropes", transform=ax.get_xaxis_transform(),
                    ha="center", va="bottom", fontsize="small", fontweight="bold")
        ax.set_ylabel(f"{LEGS[label]}  force [N]")
        ax.grid(alpha=0.3)
        ax.margins(x=0)
    axes[0].legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize="small")
    fig.suptitle("ground reactions in the contact frames (x: slope gradient, z: normal)", fontsize="medium")
    axes[-1].set_xlabel("time [s]")
    _phase_legend(fig)
    return fig


def plot_cycle_margin(trace: Mapping[str, Any], *, ax=None, order: Sequence[int] = GROPE_ORDER,
                      numbering: Sequence[int] = (0, 1, 2, 3), figsize=(8.0, 3.2)):
    """Friction safety margin s [N] of the force-distribution QP vs time [s] over one
    cycle (the paper's Fig. 8): s >= 0 means every stance leg stays inside its friction
    pyramid with margin s. Zero line in black, phases A-D shaded, the groping leg named
    above each grope, steps whose QP failed (trace `ok` False) marked with a red x.
    numbering: as `plot_cycle_forces`.
    """
    time, grope, phase, s = _trace(trace, "time", "grope", "phase", "s")
    segments = _segments(time, grope, phase)
    fig, ax = new_axes(ax, figsize)
    _shade_phases(ax, segments)
    ax.plot(time, s, color="C0", lw=1.5, label="s")
    ax.axhline(0.0, color="k", lw=1)
    if "ok" in trace:
        bad = ~np.asarray(trace["ok"], bool)
        if np.any(bad):
            ax.scatter(time[bad], s[bad], marker="x", color="red", s=16, zorder=3, label="QP failed")
    _label_gropes(ax, segments, _groping_legs(trace, order), numbering)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("safety margin s [N]")
    ax.grid(alpha=0.3)
    ax.margins(x=0)
    _phase_legend(fig)
    return fig


def plot_cycle_torques(trace: Mapping[str, Any], *, fig=None, order: Sequence[int] = GROPE_ORDER,
                       numbering: Sequence[int] = (0, 1, 2, 3), figsize=(8.0, 8.0)):
    """Joint torques [N m] vs time [s] over one cycle (the paper's Fig. 9): a panel per
    leg L1..L4 with its yaw joint tau_i1 and pitch joints tau_i2, tau_i3 (trace `tau`
    is (n, 12), leg-major), phases A-D shaded, the groping leg named above each grope.
    numbering: as `plot_cycle_forces`.
    """
    time, grope, phase, tau = _trace(trace, "time", "grope", "phase", "tau")
    segments = _segments(time, grope, phase)
    legs = _groping_legs(trace, order)
    fig, axes = _new_figure(fig, 4, figsize)
    for label, (n, ax) in enumerate(zip(numbering, axes)):
        _shade_phases(ax, segments)
        for j in range(3):
            ax.plot(time, tau[:, 3 * n + j], color=f"C{j}", lw=1.3, label=f"$\\tau_{{i{j + 1}}}$")
        ax.set_ylabel(f"{LEGS[label]}  torque [N m]")
        ax.grid(alpha=0.3)
        ax.margins(x=0)
    _label_gropes(axes[0], segments, legs, numbering)
    axes[0].legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize="small")
    fig.suptitle("joint torques (i1: yaw, i2, i3: pitch)", fontsize="medium")
    axes[-1].set_xlabel("time [s]")
    _phase_legend(fig)
    return fig
