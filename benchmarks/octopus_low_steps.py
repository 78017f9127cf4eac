"""The OCTOPUS paper's climb against the crawlers alone on low steps: a check of our model
and readings against the rest of the paper. The paper says OCTOPUS "can climb the step
which height is lower than 250 mm (the length of flippers) without using arms" and that
its CLM "can greatly improve the climbing ability"; so the paper's climb (Eqs. 28-29)
should get over every step the crawlers alone get over.

    python benchmarks/octopus_low_steps.py [N] [--heights 0.15,0.2,0.25,0.3,0.4]

Three controllers on a one-terrace step (`octopus.step_climb`, 150 s, N perturbed runs per
height, default 5: start 0.7 +- 0.1 m, heading +- 0.05 rad, friction 0.8 +- 0.2, default
(ours)):
  * CCM: crawlers and flippers only, the arms stowed (the paper's CCM; our automatic
    flipper policy in place of its two operators);
  * CLM, the paper's climb: Eqs. 28-29 for every confirmed step (`climb_paper` = 1,
    `crawl_max_h` = 0: the defaults and every paper row);
  * CLM + CRAWL (ours): steps whose estimated height H_EST is at most 250 mm are climbed
    by the crawlers and flippers with the arms carried (`crawl_max_h` = 0.25), higher ones
    by the paper's climb. A named option, not the paper's method.
Cells: successes / runs, then the failed runs' shortfall (how far their COG stayed, at its
nearest, from the success line 0.3 m beyond the riser), mean (nearest) [m], and the max
nose-up pitch, mean (worst) [rad]. Prints the wall time of each set.
"""

from __future__ import annotations

import argparse
import tempfile
import time

from jaxloco import runtime

runtime.configure(x64=True, cache_dir=True)

import numpy as np  # noqa: E402

from jaxloco import sweep  # noqa: E402

JITTERS = {"distance_jitter": 0.1, "yaw_jitter": 0.05, "mu_jitter": 0.2}
SETS = (
    ("CCM (crawlers only)", "ccm", {}),
    ("CLM, the paper's climb", "clm", {"climb_paper": 1.0, "crawl_max_h": 0.0}),
    ("CLM + CRAWL <= 250 mm (ours)", "clm", {"climb_paper": 1.0, "crawl_max_h": 0.25}),
)


def run_set(controller: str, fixed: dict, heights: list[float], n: int, out: str):
    """One sweep of `heights` x n seeds on `controller`; returns its table and wall time [s]."""
    spec = {"sweep": {"analysis": "octopus.step_climb", "name": "low_steps", "chunk_size": len(heights) * n,
                      "seeds": list(range(n)), "formats": ["parquet"]},
            "fixed": {"kind": "step1", "controller": controller, "horizon": 150.0, **JITTERS, **fixed},
            "params": {"height": heights}}
    t0 = time.perf_counter()
    result = sweep.run(spec, output=out, progress=False, overwrite=True)
    return result.table, time.perf_counter() - t0


def cell(table, height: float) -> str:
    """successes / runs; failed runs' shortfall mean (nearest) [m]; max pitch mean (worst) [rad]."""
    rows = np.isclose(np.asarray(table.column("height").to_pylist()), height)
    ok = np.asarray(table.column("success").to_pylist(), bool)[rows]
    short = np.asarray(table.column("shortfall").to_pylist(), float)[rows][~ok]
    pitch = np.asarray(table.column("max_pitch").to_pylist(), float)[rows]
    text = f"{ok.sum()}/{ok.size}"
    if short.size:
        text += f", {short.mean():.2f} ({short.min():.2f}) m short"
    return text + f", pitch {pitch.mean():.2f} ({pitch.max():.2f})"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("n", type=int, nargs="?", default=5, help="perturbed runs per height (default 5)")
    ap.add_argument("--heights", default="0.15,0.2,0.25,0.3,0.4", help="step heights [m], comma-separated")
    args = ap.parse_args()
    heights = [float(h) for h in args.heights.split(",")]
    if args.n < 1 or not all(0.0 < h <= 0.6 for h in heights):
        ap.error("expected n >= 1 and heights in (0, 0.6] m")
    tables = []
    with tempfile.TemporaryDirectory() as tmp:
        for k, (name, controller, fixed) in enumerate(SETS):
            table, wall = run_set(controller, fixed, heights, args.n, f"{tmp}/{k}")
            tables.append(table)
            print(f"{name}: {len(heights) * args.n} climbs of 150 s in {wall:.0f} s", flush=True)
    print()
    print("| step [m] | " + " | ".join(name for name, _, _ in SETS) + " |")
    print("| --- |" + " --- |" * len(SETS))
    for h in heights:
        print(f"| {h:.2f} | " + " | ".join(cell(t, h) for t in tables) + " |")


if __name__ == "__main__":
    main()
