"""The MJX executor-gain tuning's gradient beside finite differences: d(loss)/d(body_gain)
of the `titan.body_gain` objective (TITAN XI's footstep executor in an MJX rollout, the
objective's default settings: 10 s on the 30 deg slope) by forward mode (what `jaxloco
tune` uses) and by central differences of the same loss, at a few gains; plus the time
of one evaluation.

    python benchmarks/titan_gain_gradient.py [--gains 1 3 10 16] [--h 1e-3] [--horizon 10]

"one-sided spread": the largest difference of the two one-sided slopes around the gain,
relative to the forward-mode derivative (a jump inside the stencil shows there).
"""

from __future__ import annotations

import argparse
import time


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--gains", type=float, nargs="+", default=[1.0, 3.0, 10.0, 16.0])
    ap.add_argument("--h", type=float, default=1e-3, help="finite-difference step in body_gain [1/s]")
    ap.add_argument("--horizon", type=float, default=None, help="simulated seconds (default: the objective's)")
    args = ap.parse_args()

    from jaxloco import runtime

    runtime.configure(x64=True, cache_dir=True)
    import jax
    import jax.numpy as jnp

    from jaxloco.robots.titan import mjx_tuning
    from jaxloco.tune import runner

    settings = {p.name: p.default for p in mjx_tuning.SETTINGS}
    if args.horizon is not None:
        settings["horizon"] = args.horizon
    f = jax.jit(runner.value_and_grad(mjx_tuning.make_loss(settings), "forward", ["body_gain"]))

    def evaluate(gain: float) -> tuple[float, float]:
        (loss, _), grad = f({"body_gain": jnp.float64(gain)})
        return float(loss), float(grad["body_gain"])

    t0 = time.perf_counter()
    evaluate(args.gains[0])
    print(f"horizon {settings['horizon']:g} s; first call (trace + compile + run) {time.perf_counter() - t0:.1f} s")
    print(f"{'gain':>6} {'loss [mm^2]':>12} {'forward':>13} {'central':>13} {'rel. diff':>10} "
          f"{'one-sided spread':>17} {'eval [s]':>9}")
    for gain in args.gains:
        t0 = time.perf_counter()
        loss, grad = evaluate(gain)
        dt = time.perf_counter() - t0
        lo, hi = evaluate(gain - args.h)[0], evaluate(gain + args.h)[0]
        central = (hi - lo) / (2 * args.h)
        spread = abs((hi - loss) - (loss - lo)) / args.h / abs(grad)
        print(f"{gain:>6.2f} {loss:>12.5f} {grad:>13.6e} {central:>13.6e} {abs(central - grad) / abs(grad):>10.1e} "
              f"{spread:>17.1e} {dt:>9.1f}")


if __name__ == "__main__":
    main()
