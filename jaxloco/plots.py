"""Workbench plots that read any sweep or tune table (every robot's notebook uses them).

    heatmap(table, x, y, value="ok")             a metric (or the ok fraction) over two swept
                                                 parameters, the mean over the other rows
    plot_tuning(curve, comparison, params)       loss per step and each tuned value per step,
                                                 with the initial / tuned / reference values
    plot_validation(comparison, metrics)         a validation table (`tune.handoff.validate`):
                                                 one bar per compared set and metric
    column(table, name), ok_fraction(table)      a column as numpy; the fraction of ok rows
    spans(t, values)                             (start, end, value) of each run of equal values
                                                 over time, to shade phases and states

A table is a `pyarrow.Table` or a mapping of column name to array. Every plot function
returns the matplotlib Figure; matplotlib is imported inside the functions, JAX never.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

__all__ = ["column", "grid_mean", "heatmap", "new_axes", "ok_fraction", "plot_tuning", "plot_validation", "spans"]

SET_COLORS = {"initial": "0.55", "tuned": "C0", "paper": "C3"}


# ------------------------------------------------------------------------- table access
def _names(table: Any) -> list[str]:
    return list(table.column_names) if hasattr(table, "column_names") else list(table)


def column(table: Any, name: str) -> np.ndarray:
    """A column as a NumPy array (pyarrow table or mapping)."""
    if name not in _names(table):
        raise KeyError(f"the table has no column {name!r} (has: {', '.join(_names(table))})")
    if hasattr(table, "column_names"):
        return np.asarray(table.column(name).to_numpy(zero_copy_only=False))
    return np.asarray(table[name])


def _unit(table: Any, name: str) -> str:
    try:
        meta = table.schema.field(name).metadata or {}
    except (AttributeError, KeyError):
        return ""
    return meta.get(b"unit", b"").decode()


def _label(table: Any, name: str, labels: Mapping[str, str] | None = None) -> str:
    if labels and name in labels:
        return labels[name]
    unit = _unit(table, name)
    return f"{name} [{unit}]" if unit else name


def ok_fraction(table: Any) -> np.ndarray:
    """1.0 where the row's status is "ok", else 0.0."""
    return np.asarray([s == "ok" for s in column(table, "status")], dtype=float)


def _values(table: Any, value: str) -> np.ndarray:
    if value == "ok":
        return ok_fraction(table)
    return np.asarray(column(table, value), dtype=float)


def _tick(v: float | str) -> str:
    return v if isinstance(v, str) else f"{v:.4g}"


def _axis_values(table: Any, name: str) -> np.ndarray:
    """A column as a grid axis: floats, or strings for a string column (e.g. a swept task)."""
    values = column(table, name)
    strings = values.dtype.kind in "US" or (values.dtype.kind == "O" and any(isinstance(v, str) for v in values.flat))
    return values.astype(str) if strings else values.astype(float)


def _axis_index(values: np.ndarray, v: Any) -> np.ndarray:
    """Positions of `v` on an axis (equal strings, or close numbers)."""
    return np.nonzero(values == v)[0] if values.dtype.kind == "U" else np.nonzero(np.isclose(values, v))[0]


def new_axes(ax, figsize):
    """(figure, axes): `ax`'s figure and `ax`, or a new constrained-layout figure of `figsize`."""
    import matplotlib.pyplot as plt

    if ax is None:
        fig, ax = plt.subplots(figsize=figsize, layout="constrained")
        return fig, ax
    return ax.figure, ax


def spans(t: np.ndarray, values: np.ndarray) -> list[tuple[float, float, int]]:
    """(start, end, value) of every run of equal (integer) values over the uniform times t
    [s], each run ending one sample after its last: the phases or states to shade in a
    time plot."""
    values = np.asarray(values)
    edges = np.flatnonzero(np.diff(values)) + 1
    starts, ends = np.r_[0, edges], np.r_[edges, len(values)]
    dt = t[1] - t[0] if len(t) > 1 else 0.0
    return [(float(t[a]), float(t[b - 1] + dt), int(values[a])) for a, b in zip(starts, ends)]


# ------------------------------------------------------------------------- workbench plots
def grid_mean(table: Any, x: str, y: str, value: str = "ok", where: np.ndarray | None = None):
    """(xs, ys, mean (len(ys), len(xs)), count) of `value` per (x, y) cell over the rows
    selected by `where` (default all); non-finite values are left out of the mean. A string
    column (a swept categorical parameter) gives an axis of its values in sorted order."""
    xv, yv = _axis_values(table, x), _axis_values(table, y)
    vals = _values(table, value)
    sel = np.ones(len(vals), bool) if where is None else np.asarray(where, bool)
    xs, ys = np.unique(xv[sel]), np.unique(yv[sel])
    total = np.zeros((len(ys), len(xs)))
    count = np.zeros((len(ys), len(xs)))
    good = sel & np.isfinite(vals)
    ix, iy = np.searchsorted(xs, xv[good]), np.searchsorted(ys, yv[good])
    np.add.at(total, (iy, ix), vals[good])
    np.add.at(count, (iy, ix), 1.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(count > 0, total / np.maximum(count, 1.0), np.nan)
    return xs, ys, mean, count


def heatmap(table: Any, x: str, y: str, value: str = "ok", *, where: np.ndarray | None = None, ax=None,
            cmap: str | None = None, vmin: float | None = None, vmax: float | None = None, fmt: str = "{:.2f}",
            title: str | None = None, labels: Mapping[str, str] | None = None,
            yticklabels: Sequence[str] | None = None, mark: tuple[float, float] | None = None,
            mark_label: str = "paper", colorbar: bool = True, figsize=(5.2, 3.8)):
    """`value` over the grid of two swept parameters x (columns) and y (rows): the mean
    over every other row of the cell (other swept parameters, seeds), written in the cell.

    value "ok" is the fraction of rows with status "ok" (success). Cells are evenly
    spaced, labelled with the swept values (log-spaced grids stay readable). labels: axis
    / colorbar labels by column name (default: name [unit] from the table's metadata).
    mark: an (x, y) to outline (e.g. the paper's setting), if it is on the grid.
    """
    xs, ys, mean, count = grid_mean(table, x, y, value, where)
    fig, ax = new_axes(ax, figsize)
    is_ok = value == "ok"
    cmap = cmap or ("RdYlGn" if is_ok else "viridis")
    if is_ok:
        vmin = 0.0 if vmin is None else vmin
        vmax = 1.0 if vmax is None else vmax
    im = ax.imshow(np.ma.masked_invalid(mean), origin="lower", aspect="auto", cmap=cmap, vmin=vmin, vmax=vmax)
    for (i, j), v in np.ndenumerate(mean):
        if np.isfinite(v):
            r, g, b, _ = im.cmap(im.norm(v))
            dark = 0.299 * r + 0.587 * g + 0.114 * b < 0.5  # the cell's luminance
            ax.text(j, i, fmt.format(v), ha="center", va="center", fontsize="small", color="white" if dark else "black")
    ax.set_xticks(range(len(xs)), [_tick(v) for v in xs])
    ax.set_yticks(range(len(ys)), list(yticklabels) if yticklabels is not None else [_tick(v) for v in ys])
    ax.set_xlabel(_label(table, x, labels))
    ax.set_ylabel(_label(table, y, labels))
    if mark is not None:
        jx, iy = _axis_index(xs, mark[0]), _axis_index(ys, mark[1])
        if len(jx) and len(iy):
            from matplotlib.patches import Rectangle

            ax.add_patch(Rectangle((jx[0] - 0.5, iy[0] - 0.5), 1, 1, fill=False, ec="k", lw=2.5, label=mark_label))
            ax.legend(loc="upper left", bbox_to_anchor=(0.0, -0.16), fontsize="x-small", frameon=False)
    n = int(np.nanmax(count)) if count.size else 0
    what = "ok fraction (success)" if is_ok else _label(table, value, labels)
    if colorbar:
        fig.colorbar(im, ax=ax, label=what, shrink=0.9)
    ax.set_title(title or f"{what}\nmean over {n} row{'s' if n != 1 else ''} per cell", fontsize="medium")
    return fig


def _curve_column(curve: Any, name: str) -> np.ndarray:
    return np.asarray(column(curve, name), dtype=float)


def _log_axis(ax) -> None:
    """A log y axis when the drawn values span more than a factor of 3 (else linear: a log
    axis within one decade would have no labelled ticks)."""
    lo, hi = ax.dataLim.y0, ax.dataLim.y1
    if lo > 0 and hi / lo > 3.0:
        from matplotlib.ticker import FuncFormatter

        def minor(v, _):  # label 2 x and 5 x a power of ten only
            return f"{v:.3g}" if v > 0 and round(v / 10 ** math.floor(math.log10(v) + 1e-9)) in (2, 5) else ""

        ax.set_yscale("log")
        ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:.3g}"))
        ax.yaxis.set_minor_formatter(FuncFormatter(minor))


def plot_tuning(curve: Any, comparison: Any, params: Sequence[str], *, units: Mapping[str, str] | None = None,
                log: Sequence[str] = (), loss_log: bool = False, title: str = "", ncols: int = 3,
                panel: tuple[float, float] = (3.3, 2.6)):
    """A gradient tuning: the loss per optimizer step (left; the best step marked, every
    compared set's loss as a horizontal line) and each tuned parameter per step, with the
    initial, tuned and reference values (e.g. "paper") of `comparison` (tuned.parquet:
    one row per set, column `label`). units: per parameter; log: parameters drawn on a
    log axis (the log-scale tunables)."""
    import matplotlib.pyplot as plt

    units = dict(units or {})
    n = 1 + len(params)
    cols = min(ncols, n)
    rows = math.ceil(n / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(panel[0] * cols, panel[1] * rows), layout="constrained",
                             squeeze=False)
    axes = axes.ravel()
    steps = _curve_column(curve, "step")
    loss = _curve_column(curve, "loss")
    sets = comparison.to_pylist() if hasattr(comparison, "to_pylist") else list(comparison)
    ax = axes[0]
    ax.plot(steps, loss, color="C0", lw=1.5, label="loss")
    if np.isfinite(loss).any():
        best = int(np.nanargmin(loss))
        ax.plot(steps[best], loss[best], "o", color="C0", ms=6, label=f"best, step {int(steps[best])}")
    for row in sets:
        if row["label"] == "tuned":
            continue
        color = SET_COLORS.get(row["label"], "C2")
        ax.axhline(row["loss"], color=color, ls="--", lw=1, label=f"{row['label']}: {row['loss']:.3g}")
    if loss_log:
        ax.set_yscale("log")
    ax.set_xlabel("optimizer step")
    ax.set_ylabel("loss")
    ax.set_title("loss", fontsize="medium")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="x-small")
    for ax, name in zip(axes[1:], params):
        ax.plot(steps, _curve_column(curve, name), color="C0", lw=1.5)
        for row in sets:
            if row.get(name) is None:
                continue
            color = SET_COLORS.get(row["label"], "C2")
            style = "-" if row["label"] == "tuned" else "--"
            ax.axhline(float(row[name]), color=color, ls=style, lw=1, alpha=0.9,
                       label=f"{row['label']}: {float(row[name]):.3g}")
        if name in log:
            _log_axis(ax)
        unit = units.get(name, "")
        ax.set_title(f"{name} [{unit}]" if unit else name, fontsize="medium")
        ax.set_xlabel("optimizer step")
        ax.grid(alpha=0.3)
        ax.legend(fontsize="x-small")
    for ax in axes[n:]:
        ax.set_visible(False)
    if title:
        fig.suptitle(title, fontsize="medium")
    return fig


def plot_validation(comparison: Any, metrics: Sequence[str], *, labels: Mapping[str, str] | None = None,
                    title: str = "", ranges: bool = False, panel: tuple[float, float] = (2.6, 2.8)):
    """A validation comparison (`jaxloco.tune.handoff.compare`): one panel per metric, one
    bar per compared set (initial, tuned, references; merged sets such as "initial=paper" once).
    A metric `m` is drawn from the column `m_mean` (ranges: with a line from `m_min` to
    `m_max` over the set's rows); "ok_fraction" and `*_fraction` columns as they are."""
    import matplotlib.pyplot as plt

    rows = comparison.to_pylist() if hasattr(comparison, "to_pylist") else list(comparison)
    names = [r["label"] for r in rows]
    fig, axes = plt.subplots(1, len(metrics), figsize=(panel[0] * len(metrics), panel[1]), layout="constrained",
                             squeeze=False)
    for ax, metric in zip(axes[0], metrics):
        direct = metric in rows[0]
        key = metric if direct else f"{metric}_mean"
        vals = np.array([float(r[key]) for r in rows])
        colors = [SET_COLORS.get(n.split("=")[-1] if "tuned" not in n else "tuned", "C2") for n in names]
        ax.bar(range(len(rows)), np.nan_to_num(vals), color=colors)
        if ranges and not direct and f"{metric}_min" in rows[0]:
            lo = np.array([float(r[f"{metric}_min"]) for r in rows])
            hi = np.array([float(r[f"{metric}_max"]) for r in rows])
            ax.vlines(range(len(rows)), lo, hi, color="k", lw=1.2)
        for i, v in enumerate(vals):
            ax.text(i, v if np.isfinite(v) else 0.0, f"{v:.3g}", ha="center", va="bottom", fontsize="x-small")
        ax.set_xticks(range(len(rows)), names, rotation=20, fontsize="small")
        ax.set_title((labels or {}).get(metric, metric), fontsize="medium")
        ax.grid(alpha=0.3, axis="y")
        if metric.endswith("fraction"):
            ax.set_ylim(0, 1.12)
    if title:
        fig.suptitle(title, fontsize="medium")
    return fig
