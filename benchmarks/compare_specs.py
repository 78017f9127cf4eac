"""Does every ready sweep spec give the same table as at another revision?

    python benchmarks/compare_specs.py --base a234f69 [--keep 1] [--only leggrope_slope ...]
                                       [--rtol 0] [--full]

For each bundled sweep spec (`jaxloco/specs/*.toml`, the `*_tune` specs aside) it runs a
shrunk copy (`jaxloco.notebook.shrink`: `--keep` evenly spread values per swept factor,
the first seed; `--full` runs the spec as it is) twice: in this tree and in a git
worktree of `--base` (each in its own Python process, `PYTHONPATH` on that tree), on the
same machine. It then compares the two tables column by column, NaN-aware (NaN == NaN),
floats within `--rtol` (default 0: bit for bit), everything else exactly; the provenance
columns (versions, spec hash) are left out. Prints one line per spec and exits 1 when
any differs. A refactor that must not change results (e.g. of the analysis contract)
runs this before it lands."""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

REPO = Path(__file__).resolve().parents[1]
PROVENANCE = {"jaxloco_version", "jax_version", "mujoco_version", "spec_hash", "analysis"}

RUN_ONE = """
import sys
from jaxloco import notebook
from jaxloco.sweep import load_spec, run
spec = load_spec(sys.argv[1])
if sys.argv[3] != "full":
    spec = notebook.shrink(spec, keep=int(sys.argv[3]))
run(spec, output=sys.argv[2], progress=False, overwrite=True)
"""


def sweep_specs(only: list[str]) -> list[Path]:
    specs = sorted(p for p in (REPO / "jaxloco" / "specs").glob("*.toml") if not p.stem.endswith("_tune"))
    return [p for p in specs if not only or p.stem in only]


def run_spec(tree: Path, spec: Path, out: Path, keep: str) -> float:
    """Run `spec` (this tree's file) with the jaxloco of `tree`; the wall time [s]."""
    env = {**os.environ, "PYTHONPATH": str(tree)}
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", RUN_ONE, str(spec), str(out), keep], cwd=tree, env=env,
                          capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"{spec.stem} at {tree}: {proc.stderr.strip().splitlines()[-1] if proc.stderr else '?'}")
    return time.perf_counter() - t0


def compare(a_path: Path, b_path: Path, rtol: float) -> tuple[bool, str]:
    """(same, what differs) of two tables, NaN-aware."""
    a, b = pq.read_table(a_path), pq.read_table(b_path)
    if a.num_rows != b.num_rows:
        return False, f"rows {a.num_rows} vs {b.num_rows}"
    names_a, names_b = set(a.column_names) - PROVENANCE, set(b.column_names) - PROVENANCE
    if names_a != names_b:
        return False, f"columns differ: {sorted(names_a ^ names_b)}"
    worst, where = 0.0, ""
    for name in sorted(names_a):
        x = a.column(name).to_numpy(zero_copy_only=False)
        y = b.column(name).to_numpy(zero_copy_only=False)
        if x.dtype.kind == "f" or y.dtype.kind == "f":
            x, y = x.astype(float), y.astype(float)
            nan = np.isnan(x) & np.isnan(y)
            close = np.isclose(x, y, rtol=rtol, atol=0.0) if rtol else (x == y)
            if not (close | nan).all():
                with np.errstate(invalid="ignore"):  # inf - inf
                    diff = float(np.nanmax(np.abs(x - y)))
                if not np.isfinite(diff) or diff >= worst:
                    worst, where = diff, name
        elif not (x == y).all():
            return False, f"column {name} differs"
    if where:
        return False, f"max |diff| {worst:.3g} in {where}"
    return True, ""


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--base", required=True, help="git revision to compare with")
    ap.add_argument("--keep", type=int, default=1, help="values kept per swept factor (shrink)")
    ap.add_argument("--full", action="store_true", help="run the specs as they are")
    ap.add_argument("--rtol", type=float, default=0.0, help="relative tolerance on floats (0: exact)")
    ap.add_argument("--only", nargs="*", default=[], help="spec names")
    args = ap.parse_args(argv[1:])
    keep = "full" if args.full else str(args.keep)
    differ = 0
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp) / "base"
        subprocess.run(["git", "-C", str(REPO), "worktree", "add", "--detach", "-q", str(base), args.base], check=True)
        try:
            print(f"specs at {keep} values per factor: this tree vs {args.base}")
            for spec in sweep_specs(args.only):
                outs = (Path(tmp) / "new" / spec.stem, Path(tmp) / "old" / spec.stem)
                try:
                    t_new = run_spec(REPO, spec, outs[0], keep)
                    t_old = run_spec(base, spec, outs[1], keep)
                except RuntimeError as exc:
                    print(f"{spec.stem:24s} ERROR {exc}")
                    differ += 1
                    continue
                same, what = compare(outs[0] / "table.parquet", outs[1] / "table.parquet", args.rtol)
                rows = pq.read_metadata(outs[0] / "table.parquet").num_rows
                print(f"{spec.stem:24s} {'same' if same else 'DIFFERS'} ({rows} rows; {t_new:.0f} s / {t_old:.0f} s)"
                      f"{' ' + what if what else ''}", flush=True)
                differ += not same
        finally:
            subprocess.run(["git", "-C", str(REPO), "worktree", "remove", "--force", str(base)], check=False)
    print(json.dumps({"specs_differing": differ}))
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
