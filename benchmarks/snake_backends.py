"""T² Snake-3 on both simulators: one snake analysis' metrics on the same rows on native
MuJoCo (the native model), on native MuJoCo with the model's MJX variant ("variant":
what the variant changes) and on MJX (the variant), side by side (docs/simulation.md's
table).

    python benchmarks/snake_backends.py snake.reach --fixed horizon=1 --rows gain_k=1,2.5
    python benchmarks/snake_backends.py snake.table3 --rows target=x,y,z,alpha,beta,gamma
    python benchmarks/snake_backends.py snake.contact --fixed ramp=1.5 hold=0.3 settle=0.1 --rows posture=ii,v,viii
    python benchmarks/snake_backends.py snake.operations --rows operation=door,door,door,door,door

Row i has the seed i (the perturbed trials); native runs on one thread. MJX compiles
each analysis' closed loop first (minutes on 2 cores, then from JAX's persistent cache).
Keep MJX batches small on CPU (the contact postures two at a time: 6 simulations):
jaxlib 0.10.2's batched LAPACK kernels can deadlock XLA's CPU thread pool when several
run at once, and 30 simulations hung on 2 cores.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass

import numpy as np

from jaxloco.sim.rollout import RolloutResult, Simulator, rollout


@dataclass(eq=False)
class VariantOnNative(Simulator):
    """A simulator whose analyses build their MJX variant (backend "mjx") and run it on
    native MuJoCo."""

    def run(self, scenario, params) -> RolloutResult:
        return rollout(scenario, params, backend="native", nthread=self.nthread)


def _value(param, text: str):
    if param.kind == "str":
        return text
    return {"float": float, "int": int, "bool": lambda x: x.lower() in ("1", "true")}[param.kind](text)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("analysis", help="snake.reach, snake.table3, snake.contact or snake.operations")
    ap.add_argument("--fixed", nargs="*", default=[], metavar="NAME=VALUE", help="fixed parameters")
    ap.add_argument("--rows", nargs="+", required=True, metavar="NAME=V1,V2,...", help="swept parameters")
    ap.add_argument("--runs", nargs="+", default=["native", "variant", "mjx"], choices=["native", "variant", "mjx"])
    args = ap.parse_args()

    from jaxloco import analysis, runtime

    runtime.configure(x64=True, cache_dir=True)
    a = analysis.get(args.analysis)
    fixed = a.defaults() | {"nthread": 1}
    for item in args.fixed:
        name, text = item.split("=", 1)
        fixed[name] = _value(a.param(name), text)
    swept = {}
    for item in args.rows:
        name, texts = item.split("=", 1)
        swept[name] = np.array([_value(a.param(name), t) for t in texts.split(",")])
    n = len(next(iter(swept.values())))
    keys = np.stack([np.array([0, i], np.uint32) for i in range(n)])
    simulators = {"native": ("native", Simulator("native", 1)), "variant": ("mjx", VariantOnNative("mjx", 1)),
                  "mjx": ("mjx", Simulator("mjx"))}
    out = {}
    for run in args.runs:
        backend, simulator = simulators[run]
        t = time.perf_counter()
        batch = a.batch_fn(fixed | {"backend": backend}, simulator)
        out[run] = {k: np.asarray(v) for k, v in batch(swept, keys).items()}
        print(f"{run}: {time.perf_counter() - t:.1f} s", flush=True)
    print(f"rows: {', '.join(f'{k} {v.tolist()}' for k, v in swept.items())}; columns: {' | '.join(args.runs)}")
    def cell(values: np.ndarray) -> str:
        return " ".join(f"{x:.5g}" if np.issubdtype(values.dtype, np.floating) else str(x) for x in values)

    for metric in out[args.runs[0]]:
        print(f"{metric:>16}  " + " | ".join(cell(out[r][metric]) for r in args.runs))


if __name__ == "__main__":
    main()
