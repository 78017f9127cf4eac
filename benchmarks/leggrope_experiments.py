"""The paper's three walking experiments in simulation (Ambe & Matsuno 2016, Figs. 11-14),
each as several perturbed trials: one cycle on the pi/12 slope, on an irregular pi/12
slope, and with L1's (the paper's case) or L2's foothold collapsing during its grope
(the walk then stops, as the paper's robot: regrope = 0). Every trial draws friction
0.45 +- 0.05 and the slope pi/12 +- 0.02 rad from its seed (values ours), as `jaxloco
sweep leggrope_collapse` does. Prints the README's table for the default walk (the
mirrored numbering's forward crawl) and, beside it, for the literal numbering's sideways
walk (its own safe_blend 0.25): mean and worst over the trials, the paper's figure beside
each.

    python benchmarks/leggrope_experiments.py [trials]     # default 5
"""

from __future__ import annotations

import sys
import time

import numpy as np

EXPERIMENTS = (  # name, facet_spread [rad], weak_leg (0..3 = L1..L4, -1 none), regrope, paper
    ("simple slope", 0.0, -1, 1, "cycle done; N < R_ref outside D (Fig. 11)"),
    ("irregular slope (spread 0.3 rad)", 0.3, -1, 1, "cycle done; N < R_ref outside D (Fig. 12)"),
    ("L1 foothold collapses", 0.0, 0, 0, "~2 deg, no fall; stops (Figs. 13-14)"),
    ("L2 foothold collapses", 0.0, 1, 0, "(not in the paper)"),
)
JITTER = {"mu_jitter": 0.05, "theta_jitter": 0.02}
WALKS = (("mirrored", 0.4), ("literal", 0.25))  # numbering, safe_blend


def main(trials: int = 5) -> None:
    import jax

    from jaxloco import runtime

    runtime.configure(x64=True, cache_dir=True)
    from jaxloco.analysis import mean_worst
    from jaxloco.robots.leggrope import sim_analysis

    for numbering, safe_blend in WALKS:
        fixed = {p.name: p.default for p in sim_analysis.PARAMS}
        fixed.update(JITTER, theta=float(np.pi / 12), r_break_lo=0.25, r_break_hi=0.45, numbering=numbering,
                     safe_blend=safe_blend)
        _table(sim_analysis, mean_worst, jax, fixed, trials)


def _table(sim_analysis, mean_worst, jax, fixed: dict, trials: int) -> None:
    batch = sim_analysis.FRAGILE_WALK.batch_fn(fixed)
    n = len(EXPERIMENTS) * trials
    swept = {name: np.repeat([e[col] for e in EXPERIMENTS], trials)
             for col, name in ((1, "facet_spread"), (2, "weak_leg"), (3, "regrope"))}
    keys = np.stack([np.asarray(jax.random.PRNGKey(s)) for s in np.tile(np.arange(trials), len(EXPERIMENTS))])
    t0 = time.perf_counter()
    m = batch(swept, keys)
    wall = time.perf_counter() - t0
    print(f"\n{fixed['numbering']} numbering: {n} simulated cycles of 30 s in {wall:.1f} s ({n / wall:.2f} "
          f"cycles/s), {trials} trials per experiment; mean (worst) over the trials")
    head = ("experiment", "paper", "status", "fell", "done in [s]", "tilt change [deg]", "collapse tilt [deg]",
            "N/R_ref outside D'", "grope end / R_ref", "load / probe")
    print(" | ".join(head))
    for i, (name, _, _, _, paper) in enumerate(EXPERIMENTS):
        sel = slice(i * trials, (i + 1) * trials)
        ok = np.asarray(m["success"][sel], bool)
        print(" | ".join((
            name, paper, f"{ok.sum()}/{trials} ok" + _failures(m["status"][sel], sim_analysis.STATUSES),
            f"{int(np.sum(m['fell'][sel]))}/{trials}",
            mean_worst(m["cycle_time"][sel], "max", 1),
            mean_worst(np.degrees(m["max_attitude_change"][sel]), "max", 1),
            mean_worst(np.degrees(m["collapse_tilt"][sel]), "max", 1),
            mean_worst(m["max_normal_ratio"][sel]),
            mean_worst(m["grope_ratio_min"][sel][ok], "min"),
            mean_worst(m["max_load_over_probe"][sel][ok]),
        )))


def _failures(codes: np.ndarray, names: tuple[str, ...]) -> str:
    """' (fell 1, failed: timeout 1)': the non-ok statuses of the trials ('' if none)."""
    codes = np.asarray(codes)
    parts = [f"{names[c]} {int((codes == c).sum())}" for c in sorted(set(codes.tolist())) if c != 0]
    return f" ({', '.join(parts)})" if parts else ""


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 5)
