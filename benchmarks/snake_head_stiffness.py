"""T² Snake-3: the evidence behind the head servos' stiffness (`model.KP`, `model.KV`).

    python benchmarks/snake_head_stiffness.py [KP ...]

Runs Table III on the head (`snake.table3`, the paper's feedforward control, one trial
per target) for each head-part stiffness KP [N m/rad] (default 30 100 200 400 600), the
damping scaled as KV = 0.5 sqrt(KP / 30) (the same damping ratio as KP = 30, KV = 0.5),
and prints the error of every row [%] beside the paper's. The z and beta rows carry the
head part's sag (Sec. IV-C2); `model.py` explains the choice.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from jaxloco import runtime

runtime.configure(x64=True, cache_dir=True)

from jaxloco.robots.snake import experiments, table3

DEFAULT_KPS = (30.0, 100.0, 200.0, 400.0, 600.0)


def main(argv: list[str]) -> None:
    kps = np.array([float(a) for a in argv[1:]] or DEFAULT_KPS)
    fixed = {p.name: p.default for p in table3.PARAMS}
    fn = table3.TABLE3.batch_fn(fixed)
    n_t = len(table3.TARGETS)
    swept = {"target": np.tile(np.array(table3.TARGETS), len(kps)), "head_kp": np.repeat(kps, n_t),
             "head_kv": np.repeat(0.5 * np.sqrt(kps / 30.0), n_t), "mu_jitter": np.zeros(n_t * len(kps)),
             "heading_jitter": np.zeros(n_t * len(kps))}
    t = time.perf_counter()
    out = fn(swept, np.zeros((n_t * len(kps), 2), np.uint32))
    wall = time.perf_counter() - t
    print(f"Table III errors [%] on the head, feedforward, against the head servos' stiffness "
          f"({len(kps) * n_t} runs in {wall:.0f} s)")
    print("| KP [N m/rad] | KV | " + " | ".join(f"d{n}" for n in table3.TARGETS) + " | dz [m] | dbeta [rad] |")
    print("| --- " * (n_t + 4) + "|")
    for i, kp in enumerate(kps):
        sl = slice(i * n_t, (i + 1) * n_t)
        err = out["error"][sl]
        print(f"| {kp:g} | {0.5 * np.sqrt(kp / 30.0):.2f} | " + " | ".join(f"{e:.1f}" for e in err)
              + f" | {out['dz'][sl][2]:+.4f} | {out['dbeta'][sl][4]:+.4f} |")
    print("| paper | | " + " | ".join(f"{e:.1f}" for e in experiments.PAPER_ACCURACY_ERROR)
          + f" | {experiments.PAPER_ACCURACY_ROWS[2, 2]:+.4f} | {experiments.PAPER_ACCURACY_ROWS[4, 4]:+.4f} |")
    if np.any(out["status"] != 0):
        print("status not ok in rows", np.flatnonzero(out["status"] != 0).tolist())


if __name__ == "__main__":
    main(sys.argv)
