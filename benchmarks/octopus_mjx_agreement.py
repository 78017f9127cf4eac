"""Native MuJoCo vs MJX on the same OCTOPUS rows: the `octopus.step_climb` metrics of the
CLM at the 400 mm step from the paper's perturbed starts (distance 0.7 +- 0.1 m, heading
+- 0.05 rad, friction 0.8 +- 0.2), one sweep per backend over the same seeds, and their
differences (the table of docs/simulation.md, "OCTOPUS").

    python benchmarks/octopus_mjx_agreement.py --horizon 2 --rows 4
    python benchmarks/octopus_mjx_agreement.py --horizon 30 --rows 4   # through PREPARE

MJX on CPU runs some 100-300 physics steps/s per simulation on 2 cores: 30 s of 4 rows
take a few minutes after a compile of 1-2 minutes.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

METRICS = ("final_x", "final_z", "max_pitch", "max_abs_roll", "min_margin", "climb_time", "t_diverged")
EXACT = ("success", "tipped", "final_phase", "status")


def sweep(backend: str, horizon: float, rows: int, out: Path, nthread: int):
    from jaxloco.sweep import run

    return run({"sweep": {"analysis": "octopus.step_climb", "name": backend, "chunk_size": rows,
                          "seeds": list(range(rows)), "output": str(out / backend), "formats": ["parquet"]},
                "fixed": {"horizon": horizon, "nthread": nthread, "backend": backend, "distance_jitter": 0.1,
                          "yaw_jitter": 0.05, "mu_jitter": 0.2}}, progress=False)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--horizon", type=float, default=2.0, help="simulated seconds per row")
    ap.add_argument("--rows", type=int, default=4, help="perturbed starts (seeds 0..rows-1)")
    ap.add_argument("--nthread", type=int, default=1, help="native threads")
    args = ap.parse_args()

    from jaxloco import runtime

    runtime.configure(x64=True, cache_dir=True)
    with tempfile.TemporaryDirectory() as tmp:
        tables = {b: sweep(b, args.horizon, args.rows, Path(tmp), args.nthread).table for b in ("native", "mjx")}
    cols = {b: {n: t.column(n).to_numpy(zero_copy_only=False) for n in t.column_names} for b, t in tables.items()}
    n, m = cols["native"], cols["mjx"]
    print(f"octopus.step_climb, CLM, 400 mm step, {args.rows} perturbed starts, {args.horizon:g} s")
    print(f"{'metric':>14} {'native mean':>12} {'mjx mean':>12} {'max |diff|':>11}")
    for name in METRICS:
        a, b = n[name].astype(float), m[name].astype(float)
        both_nan = np.isnan(a) & np.isnan(b)
        diff = np.where(both_nan, 0.0, np.abs(a - b))
        print(f"{name:>14} {np.nanmean(a) if (~np.isnan(a)).any() else np.nan:>12.6g} "
              f"{np.nanmean(b) if (~np.isnan(b)).any() else np.nan:>12.6g} {np.max(diff):>11.3g}")
    for name in EXACT:
        print(f"{name:>14} native {list(n[name])} mjx {list(m[name])}")


if __name__ == "__main__":
    main()
