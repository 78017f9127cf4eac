"""The MJX gain tuning's gradient beside finite differences: d(loss)/dK of the
`snake.reach_gain` objective (3 s MJX rollout of T² Snake-3's feedback controller) by
forward mode (what `jaxloco tune` uses) and by central differences of the same loss,
at a few gains K; plus the time of one evaluation.

    python benchmarks/snake_gain_gradient.py [--gains 0.7 0.9 1.0 1.3] [--h 1e-5]

Steps of ~1e-5 in K stay inside one smooth piece of the loss (MJX's contact points
change discretely every ~1e-4 of K, see jaxloco/robots/snake/mjx_tuning.py); the
column "one-sided spread" shows whether the stencil straddled a jump.
"""

from __future__ import annotations

import argparse
import time

import jax
import jax.numpy as jnp

from jaxloco import runtime


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--gains", type=float, nargs="+", default=[0.7, 0.9, 1.0, 1.3])
    ap.add_argument("--h", type=float, default=1e-5, help="finite-difference step in K [1/s]")
    args = ap.parse_args()
    runtime.configure(x64=True, cache_dir=True)

    from jaxloco.robots.snake import mjx_tuning
    from jaxloco.tune import runner

    settings = {p.name: p.default for p in mjx_tuning.SETTINGS}
    t0 = time.perf_counter()
    f = jax.jit(runner.value_and_grad(mjx_tuning.make_loss(settings), "forward", ["gain_k"]))
    loss = jax.jit(mjx_tuning.make_loss(settings))

    def value(k):
        return float(loss({"gain_k": jnp.float64(k), "k_eta": jnp.float64(0.1)})[0])

    f({"gain_k": jnp.float64(1.0), "k_eta": jnp.float64(0.1)})[0][0].block_until_ready()
    value(1.0)
    print(f"compile (forward mode + plain loss): {time.perf_counter() - t0:.0f} s")
    print(f"{'K [1/s]':>8} {'loss':>10} {'forward dL/dK':>15} {'central FD':>15} {'rel. diff':>10} "
          f"{'one-sided spread':>17} {'s/eval':>7}")
    for k in args.gains:
        t1 = time.perf_counter()
        (l0, _), g = f({"gain_k": jnp.float64(k), "k_eta": jnp.float64(0.1)})
        grad = float(g["gain_k"])
        dt = time.perf_counter() - t1
        lm, lp = value(k - args.h), value(k + args.h)
        central = (lp - lm) / (2 * args.h)
        spread = abs((lp - float(l0)) - (float(l0) - lm)) / args.h
        print(f"{k:8.3f} {float(l0):10.6f} {grad:15.9f} {central:15.9f} {abs(central - grad) / abs(grad):10.1e} "
              f"{spread:17.1e} {dt:7.2f}")
    print("rel. diff = |central - forward| / |forward|")


if __name__ == "__main__":
    main()
