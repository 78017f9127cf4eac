"""The OCTOPUS paper's step experiments ("Results and discussion") reproduced in simulation:
CCM (crawlers and flippers only) and CLM (`jaxloco.robots.octopus.clm`) over N perturbed
runs each, printed beside the paper's numbers, plus the rollout throughput.

    python benchmarks/octopus_experiments.py [N]      (N runs per row, default 8)

Rows: one-terrace step 400 mm (CCM and CLM), two-terrace step 400 mm from the front
(CLM), two-terrace step from the side, 400 mm under the left crawler and half that under
the right one (CLM); rough ground with a 500 mm block 10 mm beside the robot's right side
(CLM; the paper reports no numbers for it: the arms "collide with this obstacle and
automatically adapt"; we print in how many runs an arm roller rested on the block top);
then CLM on 300 and 200 mm one-terrace steps (not in the paper). Perturbations (seeded): initial distance to the first riser
U(0.6, 0.8) m, initial yaw U(-0.05, 0.05) rad, terrain friction U(0.6, 1.0). Metrics
(`scenarios` docstring): success rate, max nose-up pitch, max |roll|, min static
stability margin, climb time (mean over the successful runs); pitch / roll / margin are
the mean over the runs and the worst run.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from jaxloco import runtime

runtime.configure(x64=True, cache_dir=True)

from jaxloco.robots.octopus import ccm, clm, scenarios
from jaxloco.sim.rollout import rollout

HEIGHT = 0.4
HORIZON_CLM = 150.0  # [s] (two-terrace climbs take about 75 s)
HORIZON_CCM = 60.0
# the paper's numbers ("Results and discussion"; blank: not reported)
PAPER = {
    ("step1", "ccm"): {"success": 0.0},
    ("step1", "clm"): {"success": 1.0, "max_pitch": 0.6, "max_abs_roll": 0.03, "min_margin": 0.15},
    ("step2_front", "clm"): {"success": 1.0, "max_pitch": 0.59, "min_margin": 0.17},
    ("step2_side", "clm"): {"success": 1.0, "max_abs_roll": 0.25, "min_margin": 0.07},
}
# (terrain, mode, total height [m]); the last rows (not in the paper) show where CLM stands
ROWS = (("step1", "ccm", HEIGHT), ("step1", "clm", HEIGHT), ("step2_front", "clm", HEIGHT),
        ("step2_side", "clm", HEIGHT), ("block", "clm", 0.5), ("step1", "clm", 0.3), ("step1", "clm", 0.2))


def perturbations(n: int, seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {"distance": rng.uniform(0.6, 0.8, n), "yaw": rng.uniform(-0.05, 0.05, n), "mu": rng.uniform(0.6, 1.0, n)}


def run_row(kind: str, mode: str, n: int, height: float = HEIGHT, nthread: int = 0):
    controller = clm.make_controller() if mode == "clm" else ccm.make_controller()
    horizon = HORIZON_CLM if mode == "clm" else HORIZON_CCM
    sc = scenarios.make_scenario(kind, controller, horizon_s=horizon, record_every=25)
    params = scenarios.params_batch(n, height=height, side_ratio=0.5, **perturbations(n))
    t0 = time.perf_counter()
    r = rollout(sc, params, nthread=nthread)
    return sc, r, time.perf_counter() - t0


def summary(r) -> dict[str, float]:
    m = r.metrics
    ok = np.asarray(m["success"], bool)
    return {
        "success": float(ok.mean()),
        "max_pitch": float(np.nanmean(m["max_pitch"])),
        "max_pitch_worst": float(np.nanmax(m["max_pitch"])),
        "max_abs_roll": float(np.nanmean(m["max_abs_roll"])),
        "max_abs_roll_worst": float(np.nanmax(m["max_abs_roll"])),
        "min_margin": float(np.nanmean(m["min_margin"])),
        "min_margin_worst": float(np.nanmin(m["min_margin"])),
        "climb_time": float(np.nanmean(np.where(ok, m["climb_time"], np.nan))) if ok.any() else float("nan"),
        "diverged": int(np.sum(r.status == "diverged")),
    }


def fmt(x: float | None, digits: int = 2) -> str:
    return "-" if x is None or (isinstance(x, float) and np.isnan(x)) else f"{x:.{digits}f}"


def pct(x: float | None) -> str:
    return "-" if x is None else f"{x * 100:.0f}%"


def main(argv: list[str]) -> None:
    n = int(argv[1]) if len(argv) > 1 else 8
    print(f"OCTOPUS step experiments, {n} perturbed runs per row "
          f"(step2_side: h left, h / 2 right)")
    head = (f"{'terrain':<12} {'h [m]':>5} {'mode':<4} {'success':>8} {'paper':>6} | {'max pitch':>14} {'paper':>6} | "
            f"{'max |roll|':>14} {'paper':>6} | {'min margin':>15} {'paper':>6} | {'time [s]':>8} {'div':>3}")
    print(head)
    print("-" * len(head))
    timing = None
    for kind, mode, height in ROWS:
        sc, r, wall = run_row(kind, mode, n, height)
        s = summary(r)
        paper = PAPER.get((kind, mode), {}) if height == HEIGHT else {}
        print(f"{kind:<12} {height:5.2f} {mode:<4} {s['success'] * 100:7.0f}% {pct(paper.get('success')):>6} | "
              f"{fmt(s['max_pitch'])} ({fmt(s['max_pitch_worst'])}) {fmt(paper.get('max_pitch')):>6} | "
              f"{fmt(s['max_abs_roll'])} ({fmt(s['max_abs_roll_worst'])}) {fmt(paper.get('max_abs_roll')):>6} | "
              f"{fmt(s['min_margin'], 3)} ({fmt(s['min_margin_worst'], 3)}) {fmt(paper.get('min_margin')):>6} | "
              f"{fmt(s['climb_time'], 1):>8} {s['diverged']:>3}")
        if kind == "block":
            tips = slice(len(scenarios.CONTACT_SITES) - scenarios.N_ARM_SITES, len(scenarios.CONTACT_SITES))
            z = np.asarray(r.records["contact_points"])[:, :, tips, 2]
            on = np.asarray(r.records["contact"])[:, :, tips] & (z > height)
            print(f"{'':<12} an arm roller rested on the block top in {int(on.any(axis=(1, 2)).sum())}/{n} runs")
        if (kind, mode, height) == ("step1", "clm", HEIGHT):
            timing = (sc, wall)
    print("(pitch / roll / margin: mean over the runs, worst run in brackets; time: mean climb time of the "
          "successful runs; div: diverged runs)")
    if timing is not None:
        sc, first = timing
        _, r, wall = run_row("step1", "clm", n)  # compiled now
        sim_s = n * sc.horizon * sc.control_dt
        print(f"throughput, step1 400 mm CLM, {n} x {sc.horizon * sc.control_dt:.0f} s: {n / wall:.2f} rollouts/s "
              f"({sim_s / wall:.0f} simulated s per wall s; first call with compilation {first:.1f} s, "
              f"again {wall:.1f} s)")


if __name__ == "__main__":
    main(sys.argv)
