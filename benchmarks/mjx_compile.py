"""What a first MJX sweep of each robot spends before it simulates: JAX's trace and XLA's
compile of the batched rollout, with empty caches (a fresh compilation cache and
program cache per robot, in a fresh process each), from JAX's own monitoring events.

    python benchmarks/mjx_compile.py                 # the four robots, users' settings
    python benchmarks/mjx_compile.py --fast-compile  # as the test suite compiles
    python benchmarks/mjx_compile.py --robots snake --repeat 2

Each sweep is tiny (one or two rows, a short horizon): the trace and the compile do
not depend on the horizon, and the run time printed beside them is the rest of the
sweep. To compare two versions of the code, run this script from each checkout in
turn on the same machine (the figures of docs/simulation.md, "One forward dynamics
per program", are such alternating runs).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

SPECS = {
    "snake": {"sweep": {"analysis": "snake.contact", "chunk_size": 1},
              "fixed": {"ramp": 1.5, "hold": 0.3, "settle": 0.1, "nthread": 1, "backend": "mjx"},
              "params": {"posture": ["ii"]}},
    "leggrope": {"sweep": {"analysis": "leggrope.fragile_walk", "chunk_size": 2},
                 "fixed": {"horizon": 1.0, "nthread": 1, "backend": "mjx", "theta": 0.2618},
                 "params": {"r_ref_factor": [0.4, 0.5]}},
    "titan": {"sweep": {"analysis": "titan.walk"},
              "fixed": {"n_cycles": 1, "nthread": 1, "backend": "mjx", "map": "exact"},
              "params": {"start_jitter": [0.0, 0.3]}},
    "octopus": {"sweep": {"analysis": "octopus.step_climb", "chunk_size": 2},
                "fixed": {"horizon": 1.0, "nthread": 1, "backend": "mjx"},
                "params": {"clm_speed": [0.03, 0.063]}},
}

CHILD = r"""
import collections, json, sys, time
import jax
from jaxloco import runtime
runtime.configure(x64=True, cache_dir=True)
totals = collections.defaultdict(float)

def listen(event, secs, **kw):
    if event.endswith(("jaxpr_trace_duration", "backend_compile_duration")):
        totals[event.rsplit("/", 1)[-1]] += secs

jax.monitoring.register_event_duration_secs_listener(listen)
from jaxloco.sweep import run
spec = json.loads(sys.argv[1])
t0 = time.perf_counter()
run(spec, progress=False)
wall = time.perf_counter() - t0
print(json.dumps({"trace": totals["jaxpr_trace_duration"], "compile": totals["backend_compile_duration"],
                  "wall": wall}))
"""


def measure(robot: str, fast_compile: bool) -> dict[str, float]:
    """One sweep of `robot` in a fresh process with empty caches: seconds traced,
    compiled and in all."""
    with tempfile.TemporaryDirectory() as tmp:
        spec = json.loads(json.dumps(SPECS[robot]))
        spec["sweep"].update({"name": robot, "output": os.path.join(tmp, "out"), "formats": ["parquet"]})
        env = {**os.environ, "JAXLOCO_CACHE_DIR": os.path.join(tmp, "cache"),
               "JAX_DISABLE_MOST_OPTIMIZATIONS": "1" if fast_compile else "0"}
        out = subprocess.run([sys.executable, "-c", CHILD, json.dumps(spec)], env=env, capture_output=True,
                             text=True, check=False)
        if out.returncode:
            raise SystemExit(f"{robot}: the sweep failed:\n{out.stderr[-2000:]}")
        return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", default=",".join(SPECS), help=f"comma-separated, of {', '.join(SPECS)}")
    ap.add_argument("--fast-compile", action="store_true",
                    help="JAX_DISABLE_MOST_OPTIMIZATIONS=1, as tests/conftest.py sets it for the suite")
    ap.add_argument("--repeat", type=int, default=1, help="runs per robot")
    args = ap.parse_args()
    robots = [r.strip() for r in args.robots.split(",") if r.strip()]
    unknown = sorted(set(robots) - set(SPECS))
    if unknown:
        raise SystemExit(f"unknown robots {unknown}; known: {', '.join(SPECS)}")
    print("fast compile (the suite's setting)" if args.fast_compile else "full optimisation (users' setting)")
    print("| robot | trace [s] | XLA compile [s] | whole sweep [s] |")
    print("| --- | ---: | ---: | ---: |")
    for robot in robots:
        for _ in range(args.repeat):
            r = measure(robot, args.fast_compile)
            print(f"| {robot} | {r['trace']:.1f} | {r['compile']:.1f} | {r['wall']:.1f} |", flush=True)


if __name__ == "__main__":
    main()
