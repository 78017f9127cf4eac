"""Plots of T² Snake-3's joint-limit avoidance (Tanaka et al., IEEE T-RO 2019, Sec. V-B):
the `snake.kv` sweep and recorded kinematic runs.

    plot_kv_maps(table)               ok fraction and recovery time over (K_V base weight, k_eta)
    plot_limit_runs(runs)             gripper-tip errors, mode sigma and cost V over time (Fig. 9)
    plot_base_joints(runs)            base yaw joints theta_4..theta_9 over time with their limits (Fig. 10)
    plot_accuracy(errors, paper)      Table III: error of the changed component per target [%]
    plot_contact_forces(table)        Tables IV-V: f_x, f_y, f_z per posture, ours beside the paper's
    plot_operations(table)            Sec. V-D: each operation's goal and tip error per operator gain
    plot_door_run(records, t)         Fig. 14 as traces: door, tip error, switching, psi_2, link 7's heading

`runs` maps a label to the records of one `kinsim.rollout` (arrays over time, e.g. a
slice of the vmapped `analysis.run_one` records): t [s], phi (12 joints), error (7: tip
position [m], roll-pitch-yaw [rad], psi_3), sigma (mode), V. Every function returns the
matplotlib Figure; JAX is imported only inside the functions (for the paper's constants in
`params` / `experiments`). The workbench plots (`heatmap`,
`plot_tuning`, `plot_validation`) are in `jaxloco.plots`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from jaxloco.plots import column, heatmap, spans

__all__ = ["plot_accuracy", "plot_base_joints", "plot_contact_forces", "plot_door_run", "plot_kv_maps",
           "plot_limit_runs", "plot_operations", "rows_where"]


def plot_kv_maps(table: Any, *, where: np.ndarray | None = None, paper: Mapping[str, float] | None = None,
                 figsize=(10.0, 3.8)):
    """Two heatmaps over the base weight K_V,4 (`kv_base`, x) and the null-space gain k_eta
    (y), each cell the mean over the other swept parameters: the ok fraction (base joints
    below 70 % of their limits within the horizon and the tip within 30 mm / 0.1 rad) and
    the mean recovery time [s] (horizon + dt when never). Outlined: `paper`'s kv_base and
    k_eta (e.g. `tuning.PAPER`: the paper's K_V, k_eta = 0.1, which the paper does not give)."""
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(1, 2, figsize=figsize, layout="constrained")
    mark = (paper["kv_base"], paper["k_eta"]) if paper else None
    labels = {"kv_base": "K_V base weight (θ4) [-]", "k_eta": "k_η [-]", "recovery_time": "recovery time [s]"}
    heatmap(table, "kv_base", "k_eta", "ok", where=where, ax=a1, mark=mark, labels=labels,
            title="success (ok fraction)")
    heatmap(table, "kv_base", "k_eta", "recovery_time", where=where, ax=a2, mark=mark, labels=labels,
            cmap="viridis_r", fmt="{:.1f}", title="mean recovery time [s]")
    return fig


def _err(rec: Mapping[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    e = np.asarray(rec["error"], float)
    return np.linalg.norm(e[:, :3], axis=1), np.linalg.norm(e[:, 3:6], axis=1)


def plot_limit_runs(runs: Mapping[str, Mapping[str, Any]], *, paper_error: tuple[float, float] | None = None,
                    figsize=(9.0, 5.6)):
    """The paper's Fig. 9 for each labelled run: gripper-tip position error [mm] and
    attitude error [rad] (norm of roll, pitch, yaw errors) with the paper's "about 30 mm
    and 0.1 rad" (dashed; `experiments.PAPER_HEAD_ERROR` unless given), the mode sigma (1: fixing state;
    2..6: the lifted wheel pair) and the cost V = phi^T K_V phi (Eq. 19; log scale)."""
    import matplotlib.pyplot as plt

    if paper_error is None:
        from jaxloco.robots.snake.experiments import PAPER_HEAD_ERROR as paper_error
    fig, axes = plt.subplots(2, 2, figsize=figsize, layout="constrained", sharex=True)
    (a_pos, a_att), (a_sig, a_v) = axes
    for k, (label, rec) in enumerate(runs.items()):
        t = np.asarray(rec["t"], float)
        pos, att = _err(rec)
        color = f"C{k}"
        a_pos.plot(t, 1e3 * pos, color=color, lw=1.2, label=label)
        a_att.plot(t, att, color=color, lw=1.2, label=label)
        a_sig.step(t, np.asarray(rec["sigma"]) + 0.06 * k, where="post", color=color, lw=1.0, label=label)
        a_v.plot(t, np.asarray(rec["V"], float), color=color, lw=1.2, label=label)
    a_pos.axhline(1e3 * paper_error[0], color="k", ls="--", lw=1, label=f"paper: about {1e3 * paper_error[0]:g} mm")
    a_att.axhline(paper_error[1], color="k", ls="--", lw=1, label=f"paper: about {paper_error[1]:g} rad")
    a_pos.set_ylabel("tip position error [mm]")
    a_att.set_ylabel("tip attitude error [rad]")
    a_sig.set_ylabel("mode σ")
    a_sig.set_yticks(range(1, 7))
    a_v.set_ylabel("V = φᵀ K_V φ")
    a_v.set_yscale("log")
    for ax in axes.ravel():
        ax.grid(alpha=0.3)
    for ax in axes[1]:
        ax.set_xlabel("time [s]")
    a_pos.legend(fontsize="x-small")
    a_att.legend(fontsize="x-small")
    fig.suptitle("gripper tip held while the base leaves its joint limits (Fig. 9)", fontsize="medium")
    return fig


def plot_base_joints(runs: Mapping[str, Mapping[str, Any]], *, recover_ratio: float = 0.7, figsize=None):
    """The paper's Fig. 10: the base yaw joints theta_4..theta_9 [rad] over time, one panel
    per labelled run, with the joint limit +-65 deg (dash-dot) and `recover_ratio` of it
    (dotted: below it every joint counts as recovered)."""
    import matplotlib.pyplot as plt

    from jaxloco.robots.snake.params import N_H, YAW_LIMIT

    n = len(runs)
    fig, axes = plt.subplots(1, n, figsize=figsize or (4.6 * n, 3.4), layout="constrained", sharey=True,
                             squeeze=False)
    for ax, (label, rec) in zip(axes[0], runs.items()):
        t = np.asarray(rec["t"], float)
        phi = np.asarray(rec["phi"], float)[:, N_H:]
        for j in range(phi.shape[1]):
            ax.plot(t, phi[:, j], lw=1.1, color=f"C{j}", label=f"θ{4 + j}")
        for sign in (1, -1):
            ax.axhline(sign * YAW_LIMIT, color="k", ls="-.", lw=1, label="limit" if sign > 0 else None)
            ax.axhline(sign * recover_ratio * YAW_LIMIT, color="0.4", ls=":", lw=1,
                       label=f"{recover_ratio:.0%} of the limit" if sign > 0 else None)
        ax.set_title(label, fontsize="medium")
        ax.set_xlabel("time [s]")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("base yaw joint angle [rad]")
    axes[0][-1].legend(fontsize="x-small", loc="upper left", bbox_to_anchor=(1.0, 1.0))
    return fig


def plot_accuracy(errors: Mapping[str, Sequence[float]], names: Sequence[str], *, figsize=(7.0, 3.2)):
    """Table III as bars: the error of the changed component [%] per target (names), one
    bar per source (e.g. "paper", "kinematic"); log scale."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=figsize, layout="constrained")
    width = 0.8 / max(len(errors), 1)
    x = np.arange(len(names))
    for k, (label, vals) in enumerate(errors.items()):
        vals = np.maximum(np.asarray(vals, float), 1e-4)
        ax.bar(
            x + (k - (len(errors) - 1) / 2) * width,
            vals,
            width,
            label=label,
            color="C3" if label == "paper" else f"C{k}",
        )
    ax.set_yscale("log")
    ax.set_xticks(x, list(names))
    ax.set_ylabel("error of the changed component [%]")
    ax.set_title("relative position accuracy (Table III)", fontsize="medium")
    ax.grid(alpha=0.3, axis="y")
    ax.legend(fontsize="small")
    return fig


def plot_contact_forces(table: Any, *, figsize=(10.0, 3.2)):
    """Tables IV-V as bars: f_x, f_y, f_z [N] per posture, ours (mean ± SD over the `ok`
    trials of a `snake.contact` table) beside the paper's (mean ± SD), one panel per
    force."""
    import matplotlib.pyplot as plt

    from jaxloco.robots.snake import contact

    postures = np.asarray(column(table, "posture")).astype(str)
    ok = np.asarray(column(table, "status")).astype(str) == "ok"
    names = [k for k in contact.POSTURE_NAMES if np.any(postures == k)]
    x = np.arange(len(names))
    fig, axes = plt.subplots(1, 3, figsize=figsize, layout="constrained", sharey=True)
    for j, (ax, force) in enumerate(zip(axes, ("fx", "fy", "fz"), strict=True)):
        vals = np.asarray(column(table, force), float)
        ours = [vals[(postures == k) & ok] for k in names]
        mean = [v.mean() if v.size else np.nan for v in ours]
        sd = [v.std(ddof=1) if v.size > 1 else 0.0 for v in ours]
        ax.bar(x - 0.2, mean, 0.4, yerr=sd, label="ours", color="C0", capsize=2)
        ax.bar(
            x + 0.2,
            [contact.PAPER_FORCES[k][j][0] for k in names],
            0.4,
            yerr=[contact.PAPER_FORCES[k][j][1] for k in names],
            label="paper",
            color="C3",
            capsize=2,
        )
        ax.set_xticks(x, [f"({k})" for k in names], fontsize="small")
        ax.set_title(f"f_{force[1]} [N]", fontsize="medium")
        ax.grid(alpha=0.3, axis="y")
    axes[0].legend(fontsize="small")
    fig.suptitle("contact forces of the head (Tables IV-V): ours on a MuJoCo force plate, paper", fontsize="medium")
    return fig


def plot_contact_height_law(table: Any, *, figsize=(10.0, 3.2)):
    """Table IV on log-log axes: f_x, f_y, f_z [N] against the head height z_h [m] for the
    straight base ((i)-(iii)) and the L ((iv)-(vi)), ours (the `ok` trials' means of a
    `snake.contact` table, filled) and the paper's (open), each series labelled with its
    exponent n of f ~ z_h^n (`contact.height_exponents`)."""
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FuncFormatter, NullFormatter

    from jaxloco.robots.snake import contact

    ours, paper = contact.posture_means(table), contact.PAPER_MEANS
    fits = {"ours": contact.height_exponents(ours), "paper": contact.height_exponents(paper)}
    heights = sorted({contact.POSTURES[k][0] for names in contact.HEIGHT_SERIES.values() for k in names})
    fig, axes = plt.subplots(1, 3, figsize=figsize, layout="constrained", sharey=True)
    for j, (ax, force) in enumerate(zip(axes, ("x", "y", "z"), strict=True)):
        for c, (base, names) in enumerate(contact.HEIGHT_SERIES.items()):
            z = [contact.POSTURES[k][0] for k in names]
            for who, means, style in (("ours", ours, "o-"), ("paper", paper, "s--")):
                if base not in fits[who]:
                    continue
                ax.plot(z, [means[k][j] for k in names], style, color=f"C{c}", mfc="none" if who == "paper" else None,
                        label=f"{who}, {base}: n = {fits[who][base][j]:+.1f}")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xticks(heights, [f"{h:.2f}" for h in heights])
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        ax.yaxis.set_minor_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        ax.set_xlabel("z_h [m]")
        ax.set_title(f"f_{force} [N]", fontsize="medium")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize="x-small")
    fig.suptitle("contact forces against the head's height (Table IV), f ~ z_h^n: ours (filled), paper (open)",
                 fontsize="medium")
    return fig


def plot_operations(table: Any, *, figsize=(10.0, 3.2)):
    """The `snake.operations` table: per operation and operator gain, the goal reached
    (the measure over its success threshold: pipe lift / 0.05 m, valve turn / 75 % of 90
    deg, door opening / 1.0 rad; 1 = just reached) and the largest tip error [mm] against
    the 30 mm bound; bars the mean over the trials, dots each trial."""
    import matplotlib.pyplot as plt

    from jaxloco.robots.snake import operations_analysis

    ops = column(table, "operation").astype(str)
    gains = column(table, "operator_gain").astype(float)
    goal = {
        "pick": ("pipe_lift", operations_analysis.PICK_LIFT_MIN),
        "valve": ("valve_turn", operations_analysis.VALVE_TURN_MIN),
        "door": ("door_max", operations_analysis.DOOR_OPEN_MIN),
    }
    fig, (a1, a2) = plt.subplots(1, 2, figsize=figsize, layout="constrained")
    names = [n for n in operations_analysis.NAMES if np.any(ops == n)]
    levels = np.unique(gains)
    width = 0.8 / max(len(levels), 1)
    for j, g in enumerate(levels):
        for i, name in enumerate(names):
            sel = (ops == name) & (gains == g)
            if not sel.any():
                continue
            key, threshold = goal[name]
            x = i + (j - (len(levels) - 1) / 2) * width
            reached = column(table, key)[sel].astype(float) / threshold
            error = 1e3 * column(table, "max_tip_error")[sel].astype(float)
            color = f"C{j}"
            for ax, v in ((a1, reached), (a2, error)):
                ax.bar(x, np.nanmean(v), width * 0.9, color=color, alpha=0.6,
                       label=f"operator gain {g:g} /s" if i == 0 else None)
                ax.plot(np.full(v.size, x), v, ".", color="k", ms=3)
    a1.axhline(1.0, color="k", lw=0.8, ls="--")
    a2.axhline(1e3 * operations_analysis.TIP_BOUND, color="k", lw=0.8, ls="--")
    for ax, title in (
        (a1, "goal reached (measure / success threshold)"),
        (a2, "largest tip error [mm] (30 mm dashed)"),
    ):
        ax.set_xticks(range(len(names)), names)
        ax.set_title(title, fontsize=9)
    a1.legend(fontsize=8)
    return fig


def plot_door_run(records: Mapping[str, Any], t: np.ndarray, *, label: str = "", figsize=(10.0, 5.0)):
    """One door run (`operations.run_door` / the door rows of `snake.operations`; records
    of one run, time first, t [s]) as the paper's Fig. 14 in traces: the door's angle
    [rad], the gripper tip's distance from the operator's intended position [mm] against
    the 30 mm bound, psi_2 [rad] (0: links 2 and 3 in line, the head part's singular
    pose) and link 7's heading [rad], the switching state shaded (Fig. 14 e, g)."""
    import matplotlib.pyplot as plt

    from jaxloco.robots.snake import operations, operations_analysis

    t = np.asarray(t, float)
    door = np.asarray(records["fixture"])[:, 0]
    err = 1e3 * operations.tip_distance(records)
    switching = operations.switching(records)
    phi, base = np.asarray(records["phi"]), np.asarray(records["base"])
    fig, axes = plt.subplots(2, 2, figsize=figsize, sharex=True, layout="constrained")
    traces = (
        (door, "door angle [rad]", operations_analysis.DOOR_OPEN_MIN),
        (err, "tip error [mm]", 1e3 * operations_analysis.TIP_BOUND),
        (phi[:, 3], "psi_2 [rad] (0: singular)", 0.0),
        (base[:, 5], "link 7 heading [rad]", None),
    )
    shaded = [(a, b) for a, b, on in spans(t, switching.astype(int)) if on]
    for ax, (y, name, line) in zip(axes.flat, traces):
        for a, b in shaded:
            ax.axvspan(a, b, color="C1", alpha=0.2, lw=0)
        ax.plot(t, y, lw=1.2)
        if line is not None:
            ax.axhline(line, color="k", lw=0.8, ls="--")
        ax.set_ylabel(name, fontsize=9)
    for ax in axes[1]:
        ax.set_xlabel("t [s]")
    fig.suptitle(f"{label + ': ' if label else ''}opening the door, {len(shaded)} switching state(s) shaded; "
                 f"largest tip error {np.max(err):.0f} mm", fontsize=10)
    return fig


def rows_where(table: Any, **values: float) -> np.ndarray:
    """Rows whose columns equal the given values (e.g. delta_t=1.0, mode_order=0)."""
    sel = np.ones(len(column(table, "status")), bool)
    for name, v in values.items():
        sel &= np.isclose(np.asarray(column(table, name), float), v)
    return sel
