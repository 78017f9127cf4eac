"""Wall time of the shipped slope sweep (`jaxloco sweep leggrope_slope`),
cold (empty JAX compilation cache) and warm (cache filled by the cold run).

    python benchmarks/bench_sweep.py [--spec jaxloco/specs/leggrope_slope.toml]

Each run writes to a temporary directory; the user's cache and results are untouched.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def timed_run(spec: Path, out: Path, cache: Path) -> tuple[float, str]:
    env = dict(os.environ, JAXLOCO_CACHE_DIR=str(cache))
    cmd = [sys.executable, "-m", "jaxloco.cli", "sweep", str(spec), "--out", str(out), "--overwrite", "--quiet"]
    start = time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
    elapsed = time.perf_counter() - start
    if proc.returncode != 0:
        sys.exit(f"sweep failed ({proc.returncode}):\n{proc.stderr}")
    return elapsed, proc.stdout


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spec", default="leggrope_slope", help="a spec file or a bundled spec's name")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        cache, out = Path(tmp) / "cache", Path(tmp) / "out"
        cold, _ = timed_run(args.spec, out, cache)
        warm, stdout = timed_run(args.spec, out, cache)
    rows = next((line for line in stdout.splitlines() if line.startswith("wrote") and "rows" in line), "")
    print(f"spec: {args.spec.name}  {rows.strip()}")
    print(f"cold (empty compilation cache): {cold:7.1f} s wall")
    print(f"warm (cache filled):            {warm:7.1f} s wall")
    print(f"cores: {os.cpu_count()}")


if __name__ == "__main__":
    main()
