"""The OCTOPUS paper's experiments ("Results and discussion") reproduced in simulation, N
perturbed runs each, printed beside the paper's numbers: the `octopus.paper` analysis
(`jaxloco/robots/octopus/paper_analysis.py`, the same runs as `jaxloco sweep
octopus_paper`), then the same tasks with our options (not the paper's method) and with
the operator layer, and the rollout throughput.

    python benchmarks/octopus_experiments.py [N] [--quick | --options | --common-axis]

Row sets:
  * paper: the five tasks on the paper's method (CLM climbing by Eqs. 28-29, never in
    CRAWL; CCM with the arms up; no operator);
  * ours, level lift: the CLM tasks with `climb_paper` = 0 (our level lift);
  * ours, level lift + CRAWL: two terraces from the front with `crawl_max_h` = 0.25 m
    (low terraces climbed by crawlers and flippers, arms carried);
  * operator: the CLM tasks on the paper's method with the operator steering
    (`operator_gain` = 0.2 m/s per rad: the CLM cannot measure the yaw, a person can);
  * paper, common axis: the climbing tasks on the paper's method with Eq. 28 read on the
    authors' common boom axis (`climb_common_axis` = 1: the rear booms turn up).
--quick runs the paper set only, --options every set but it, --common-axis that set only.
Perturbations (seeded, from the row's seed): start distance 0.7 +- 0.1 m, heading
+- 0.05 rad, friction 0.8 +- 0.2. Cells: mean over the runs (worst run) / the paper's value.
"""

from __future__ import annotations

import sys
import tempfile
import time

from jaxloco import runtime

runtime.configure(x64=True, cache_dir=True)

from jaxloco import sweep
from jaxloco.robots.octopus import paper_analysis

CLM_TASKS = ("step1_clm", "step2_front", "step2_side", "block")
ROW_SETS = (
    ("paper", paper_analysis.TASK_NAMES, {}),
    ("ours, level lift", CLM_TASKS, {"climb_paper": 0.0}),
    ("ours, level lift + CRAWL", ("step2_front",), {"climb_paper": 0.0, "crawl_max_h": 0.25}),
    ("operator", CLM_TASKS, {"operator_gain": 0.2}),
    ("paper, common axis", ("step1_clm", "step2_front", "step2_side"), {"climb_common_axis": 1.0}),
)


def run_set(tasks, fixed: dict, n: int, out: str):
    """One sweep of `tasks` x n seeds; returns the table and the wall time [s]."""
    spec = {"sweep": {"analysis": "octopus.paper", "name": "bench", "chunk_size": n, "seeds": list(range(n)),
                      "formats": ["parquet"]},
            "fixed": {"horizon": 150.0, **fixed}, "params": {"task": list(tasks)}}
    t0 = time.perf_counter()
    result = sweep.run(spec, output=out, progress=False, overwrite=True)
    return result.table, time.perf_counter() - t0


def main(argv: list[str]) -> None:
    args = [a for a in argv[1:] if not a.startswith("--")]
    n = int(args[0]) if args else 20
    by_flag = {"--quick": ("paper",), "--common-axis": ("paper, common axis",),
               "--options": tuple(label for label, _, _ in ROW_SETS if label != "paper")}
    labels = next((by_flag[f] for f in by_flag if f in argv), tuple(label for label, _, _ in ROW_SETS))
    sets = [s for s in ROW_SETS if s[0] in labels]
    print(f"OCTOPUS paper experiments, {n} perturbed runs per row; cells: mean (worst) / paper")
    head = (f"{'set':<26} {'task':<12} {'success':>14} | {'max pitch':>18} | {'max |roll|':>18} | "
            f"{'min margin':>21} | {'time s':>6} | failures")
    print(head)
    print("-" * len(head))
    throughput = []
    with tempfile.TemporaryDirectory() as tmp:
        for label, tasks, fixed in sets:
            table, wall = run_set(tasks, fixed, n, f"{tmp}/{len(throughput)}")
            throughput.append((label, len(tasks) * n, wall))
            summary = paper_analysis.summarize(table)
            for row in summary.rows:
                task, success, pitch, roll, margin, t, failures = row
                print(f"{label:<26} {task:<12} {success:>14} | {pitch:>18} | {roll:>18} | {margin:>21} | {t:>6} | "
                      f"{failures}")
            for note in summary.notes[1:]:
                print(f"{label:<26} {note}")
    print("(pitch / roll [rad], margin [m]: mean over the runs, worst run in brackets, then the paper's value;"
          " time: mean climb time of the successful runs; failures: tipped = turned over, stuck = never on the top; "
          "m short: how far the failed runs' COG stayed, at its nearest, from 0.3 m beyond the last riser)")
    for label, runs, wall in throughput:
        print(f"throughput, {label}: {runs} runs x 150 s in {wall:.0f} s = {runs / wall:.2f} rollouts/s "
              f"({runs * 150 / wall:.0f} simulated s per wall s, first set includes compilation)")


if __name__ == "__main__":
    main(sys.argv)
