"""Plots of the OCTOPUS sweeps (Chen et al., ROBOMECH J. 2018); the workbench plots that
read any table (heatmap, plot_tuning, plot_validation) are in `jaxloco.plots`.

    plot_accuracy_map(table, sigma)              terrain-classification accuracy over terrain
                                                 type x height for one (sigma_1, sigma_2, sigma_3)
    climb_trace(records, i, times)               pitch, roll, stability margin and phase over time
                                                 of one recorded step-climbing rollout
    plot_climb_traces(traces, paper)             those over time, one line per run (Figs. 12-13)

A table is a `pyarrow.Table` or a mapping of column name to array. Every plot function
returns the matplotlib Figure; matplotlib is imported inside the functions. Nothing here
imports JAX at import time (`climb_trace` computes margins with `jaxloco.sim.metrics`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

__all__ = ["TERRAIN_NAMES", "climb_trace", "plot_accuracy_map", "plot_climb_traces"]

TERRAIN_NAMES = ("flat", "step up", "step down", "slope up", "slope down", "rough")  # analysis.TERRAINS order
from jaxloco.plots import column, heatmap


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
    return {
        "t": np.asarray(times, float)[: len(rpy)],
        "pitch": -rpy[:, 1],
        "roll": rpy[:, 0],
        "margin": margin,
        "phase": np.asarray(records["phase"][i]),
    }


def plot_climb_traces(traces: Mapping[str, Mapping[str, np.ndarray]],
                      paper: Mapping[str, Mapping[str, float]] | None = None, *, figsize=(9.0, 3.4)):
    """Nose-up pitch [rad] and stability margin [m] over time, one line per labelled run
    (the paper's Figs. 12-13 compare CCM and CLM on the 400 mm step). paper: per label,
    {"max_pitch": ..., "min_margin": ...} drawn as dashed lines of the run's colour."""
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(1, 2, figsize=figsize, layout="constrained")
    for k, (label, tr) in enumerate(traces.items()):
        color = f"C{k}"
        a1.plot(tr["t"], tr["pitch"], color=color, lw=1.2, label=label)
        a2.plot(tr["t"], tr["margin"], color=color, lw=1.2, label=label)
        ref = (paper or {}).get(label, {})
        if "max_pitch" in ref:
            a1.axhline(ref["max_pitch"], color=color, ls="--", lw=1, label=f"paper max {ref['max_pitch']:g}")
        if "min_margin" in ref:
            a2.axhline(ref["min_margin"], color=color, ls="--", lw=1, label=f"paper min {ref['min_margin']:g}")
    a1.set_ylabel("pitch, nose up [rad]")
    a2.set_ylabel("stability margin [m]")
    for ax, t in ((a1, "pitch angle (Fig. 12)"), (a2, "static stability margin (Fig. 13)")):
        ax.set_xlabel("time [s]")
        ax.set_title(t, fontsize="medium")
        ax.grid(alpha=0.3)
        ax.legend(fontsize="x-small")
    return fig
