"""Plots of TITAN XI's grid step over intermittent crawl gait (Hodoshima et al., JRM 2007):
the `titan.stride` sweep and planned walks.

    terrain_cases(table)              the terrain cases of a sweep table (frame size, interval, slope)
    plot_stride_maps(table, paper)    ok fraction and distance per cycle over (L_std, W_std), per terrain
    plot_plan(plan, gmap)             a planned walk from above: frames, footholds, COG path (Figs. 19-20)
    plot_nesm_steps(plans, s_ne_c)    NE stability margin of every planned step against S_NE^c
    field_label(cols, i)              the field of a sweep row in words (mixed fields included)
    plot_directions(table, s_ne_c)    min NESM and distance per cycle against heading (polar), per field

`plan` is a `gait.GaitPlan` and `gmap` a `maps.GridMap` (JAX or NumPy arrays; map frame:
on a slope x runs up the fall line, SI units, radians). Every function returns the
matplotlib Figure; nothing here imports JAX. The workbench plots (`heatmap`,
`plot_tuning`, `plot_validation`) are in `jaxloco.plots`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from jaxloco.plots import column, heatmap

__all__ = ["LEG_NAMES", "case_label", "field_label", "plot_directions", "plot_nesm_steps", "plot_plan",
           "plot_stride_maps", "terrain_cases"]

LEG_NAMES = ("LF", "RF", "LR", "RR")  # params.LEG_NAMES
CASE = ("frame_size", "frame_interval", "slope")


def case_label(frame_size: float, interval: float, slope: float) -> str:
    """A terrain case in words: flat ground, or frames of `frame_size` every `interval` [m]
    (on a slope of `slope` [rad])."""
    text = "flat ground" if frame_size <= 0 else f"{frame_size:g} m frames / {interval:g} m"
    if slope > 0:
        text += f", {math.degrees(slope):.0f}° slope"
    return text


def terrain_cases(table: Any) -> list[tuple[float, float, float]]:
    """Distinct (frame_size, frame_interval, slope) of a titan.stride table, first-seen order."""
    cols = np.column_stack([np.asarray(column(table, c), float) for c in CASE])
    return [tuple(float(v) for v in row) for row in dict.fromkeys(map(tuple, cols))]


def plot_stride_maps(table: Any, paper: Mapping[str, float] | None = None, *, where: np.ndarray | None = None,
                     panel=(3.3, 3.0)):
    """Per terrain case (columns): the ok fraction (every step NESM >= S_NE^c and no
    failed foothold search) and the mean distance per cycle [m] over the stride (L_std,
    W_std) [m], each cell pooled over the other swept parameters (S_NE^c, direction).
    Outlined: `paper`'s l_std, w_std (e.g. `tuning.DEFAULT_STRIDE`)."""
    import matplotlib.pyplot as plt

    cases = terrain_cases(table)
    cols = np.column_stack([np.asarray(column(table, c), float) for c in CASE])
    fig, axes = plt.subplots(2, len(cases), figsize=(panel[0] * len(cases), 2 * panel[1]), layout="constrained",
                             squeeze=False)
    mark = (paper["w_std"], paper["l_std"]) if paper else None  # (x, y) = (W_std, L_std)
    labels = {"l_std": "L_std [m]", "w_std": "W_std [m]"}
    sel0 = np.ones(len(cols), bool) if where is None else np.asarray(where, bool)
    dmax = float(np.nanmax(np.asarray(column(table, "distance_per_cycle"), float)[sel0])) if sel0.any() else 1.0
    for k, case in enumerate(cases):
        sel = sel0 & np.all(np.isclose(cols, np.asarray(case)[None]), axis=1)
        name = case_label(*case)
        heatmap(table, "w_std", "l_std", "ok", where=sel, ax=axes[0][k], mark=mark, labels=labels,
                colorbar=False, title=f"{name}\nok fraction")
        heatmap(table, "w_std", "l_std", "distance_per_cycle", where=sel, ax=axes[1][k], mark=mark, labels=labels,
                colorbar=False, vmin=0.0, vmax=dmax, title="distance per cycle [m]")
    return fig


def _np(x: Any) -> np.ndarray:
    return np.asarray(x)


def plot_plan(plan: Any, gmap: Any, *, title: str = "", ax=None, pad: float = 1.0, figsize=(7.5, 4.6)):
    """A planned walk seen from above (map frame, x [m] along the map, y [m] across): the
    forbidden-foothold cells (frames widened by the foot pad, grey), the COG after every
    step (black line, start ringed), and the footholds after every step, one colour per
    leg (LF, RF, LR, RR; a step that moves no foot adds no new foothold). Steps of failed
    (held) cycles are not drawn differently; see `plan.failed`."""
    import matplotlib.pyplot as plt

    feet = _np(plan.feet)
    cog = _np(plan.cog)
    forb = _np(gmap.forbidden)
    origin, cell = _np(gmap.origin), float(_np(gmap.cell))
    if ax is None:
        fig, ax = plt.subplots(figsize=figsize, layout="constrained")
    else:
        fig = ax.figure
    nx, ny = forb.shape
    extent = (origin[0], origin[0] + nx * cell, origin[1], origin[1] + ny * cell)
    ax.imshow(forb.T, origin="lower", extent=extent, cmap="Greys", vmin=0, vmax=2.5, interpolation="nearest")
    for leg in range(feet.shape[1]):
        xy = np.unique(np.round(feet[:, leg, :2], 6), axis=0)
        ax.scatter(xy[:, 0], xy[:, 1], s=22, color=f"C{leg}", label=LEG_NAMES[leg], zorder=3)
    ax.plot(cog[:, 0], cog[:, 1], "k.-", lw=1.2, ms=4, label="COG after each step", zorder=4)
    ax.plot(cog[0, 0], cog[0, 1], "o", mfc="none", mec="k", ms=9, zorder=4)
    pts = np.concatenate([feet[..., :2].reshape(-1, 2), cog[:, :2]])
    lo, hi = pts.min(axis=0) - pad, pts.max(axis=0) + pad
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(title or "planned footholds and COG (grey: forbidden cells)", fontsize="medium")
    ax.legend(fontsize="x-small", loc="upper left", bbox_to_anchor=(1.0, 1.0))
    return fig


def plot_nesm_steps(plans: Mapping[str, Any], s_ne_c: float, *, figsize=(10.0, 3.4)):
    """The NE stability margin [m] of every planned step (the smallest over the step: a
    swing on three legs, or a COG shift on four), one line per labelled plan, against
    S_NE^c (dashed). Filled markers: swings; open: COG shifts."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=figsize, layout="constrained")
    for k, (label, plan) in enumerate(plans.items()):
        nesm = _np(plan.nesm)
        swing = _np(plan.swing_leg) >= 0
        steps = np.arange(1, len(nesm) + 1)
        color = f"C{k}"
        ax.plot(steps, nesm, color=color, lw=1.0, label=f"{label}: min {nesm.min():.3f} m")
        ax.plot(steps[swing], nesm[swing], "o", color=color, ms=4)
        ax.plot(steps[~swing], nesm[~swing], "o", mfc="white", mec=color, ms=4)
    ax.axhline(s_ne_c, color="k", ls="--", lw=1, label=f"S_NE^c = {s_ne_c:g} m")
    ax.set_xlabel("step (six per cycle: swing r, swing f, shift, swing r̄, swing f̄, shift)")
    from matplotlib.ticker import FuncFormatter

    ax.set_yscale("log")  # swings on three legs sit near S_NE^c, COG shifts on four legs far above
    ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.yaxis.set_minor_formatter(FuncFormatter(  # label 2 x and 5 x a power of ten only
        lambda v, _: f"{v:g}" if v > 0 and round(v / 10 ** math.floor(math.log10(v) + 1e-9)) in (2, 5) else ""))
    ax.set_ylabel("NESM [m] (log scale)")
    ax.set_title("NE stability margin of every planned step (filled: swing, open: COG shift)", fontsize="medium")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="x-small", loc="upper left", bbox_to_anchor=(1.0, 1.0))
    return fig


def field_label(cols: Mapping[str, Any], i: int) -> str:
    """The terrain of row i of a `titan.stride` table (columns as arrays): 'flat',
    '0.2 m / 2 m' or a mixed field, with the slope if any."""
    def one(size, interval):
        return f"{size:g} m / {interval:g} m" if size > 0 else "flat"

    label = one(float(cols["frame_size"][i]), float(cols["frame_interval"][i]))
    if float(cols["mix_block"][i]) > 0:
        label = (f"mixed {label} + {one(float(cols['frame_size_b'][i]), float(cols['frame_interval_b'][i]))}, "
                 f"{float(cols['mix_block'][i]):g} m blocks")
    slope = float(cols["slope"][i])
    return label + (f", {math.degrees(slope):.0f} deg slope" if slope > 0 else "")


def plot_directions(table: Any, s_ne_c: float, *, figsize=(10.0, 4.4)):
    """A direction study (`titan_directions`): min NESM and distance per cycle against the
    heading (map frame; the body axes at 0, 90, 180, 270 deg) on polar axes, one line per
    field, S_NE^c dashed; walks that failed a cycle or went below S_NE^c are crossed."""
    import matplotlib.pyplot as plt

    cols = {n: np.asarray(column(table, n)) for n in ("direction", "min_nesm", "distance_per_cycle", "nesm_ok",
                                                       "frame_size", "frame_interval", "mix_block", "frame_size_b",
                                                       "frame_interval_b", "slope")}
    labels = np.asarray([field_label(cols, i) for i in range(len(cols["direction"]))])
    heading = np.mod(cols["direction"].astype(float), 2 * math.pi)
    fig, axes = plt.subplots(1, 2, figsize=figsize, subplot_kw={"projection": "polar"}, layout="constrained")
    ring = np.linspace(0.0, 2 * math.pi, 181)
    for ax, key, title in ((axes[0], "min_nesm", "min NESM [m]"), (axes[1], "distance_per_cycle",
                                                                    "distance per cycle [m]")):
        for label in dict.fromkeys(labels.tolist()):
            sel = labels == label
            order = np.argsort(heading[sel])
            th = np.append(heading[sel][order], heading[sel][order][0] + 2 * math.pi)
            r = np.append(cols[key][sel][order].astype(float), cols[key][sel][order][0])
            line, = ax.plot(th, r, marker="o", ms=3, lw=1.2, label=label)
            bad = sel & ~cols["nesm_ok"].astype(bool)
            if bad.any():
                ax.plot(heading[bad], cols[key][bad], "x", color=line.get_color(), ms=9, mew=2)
        if key == "min_nesm":
            ax.plot(ring, np.full_like(ring, s_ne_c), "k--", lw=1, label="S_NE^c")
            ax.set_rlim(0.0, max(2.0 * s_ne_c, float(np.nanmax(cols[key])) * 1.1))
        else:
            ax.set_rlim(0.0, float(np.nanmax(cols[key])) * 1.1)
        ax.set_title(title)
        ax.set_rlabel_position(100)
        ax.tick_params(axis="y", labelsize=7)
    axes[0].legend(loc="upper center", bbox_to_anchor=(1.1, -0.06), ncol=2, fontsize=8, frameon=False)
    return fig
