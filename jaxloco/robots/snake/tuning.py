"""`snake.kv` tuning objective: gradient descent (optax, `jaxloco tune`) on the K_V
weights and the null-space gain k_eta of T² Snake-3's joint-limit avoidance, through
the differentiable kinematic rollout (`kinsim`, reverse mode through `lax.scan`).

The loss is `analysis.limit_loss`: the gripper tip's mean squared position / attitude
error (scaled by the paper's 30 mm / 0.1 rad) plus `w_limit` times a smooth count of
base joints above `recover_ratio` of their limits, averaged over the run. Raising
k_eta or the base weights straightens the base sooner, until the joints' speed limit
(4.7 rad/s) clips the null-space motion and the head starts to move: the trade-off the
tuning finds. The mode schedule (a discrete choice) and the joint-limit stops are
piecewise constant, so the gradient sees them only through their effect on the
continuous state; tune in log scale (every weight > 0).

Settings: every other parameter of the `snake.kv` analysis (horizon, dt, Delta T, mode
order, K, Eq. 20 weight a2, zigzag amplitude, ...), the same defaults. Reference: the
paper's K_V (15, 0.015, 9.6, ratio 0.5) with k_eta = 0.1 (the paper gives no k_eta).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import jax.numpy as jnp

from jaxloco.robots.snake import analysis, params
from jaxloco.tune.objective import Objective

# unbounded in log scale (the optimiser's steps are not clipped to the sweep ranges)
TUNABLES = tuple(
    params.PARAMETERS.tunable(name, lo=None, hi=None, scale="log")
    for name in ("kv_head_yaw", "kv_head_pitch", "kv_base", "kv_ratio", "k_eta")
)
_TUNED = {t.name for t in TUNABLES}
SETTINGS = tuple(p for p in analysis.PARAMS if p.name not in _TUNED)
AUX = ("recovery_time", "max_pos_error", "max_att_error", "final_V", "min_margin", "time_near_limit")
PAPER = {t.name: t.default for t in TUNABLES}  # the paper's K_V, k_eta = 0.1 (ours: the paper gives none)


def make_loss(settings: Mapping[str, Any]):
    """`Objective.make_loss`: loss_fn(values) -> (limit_loss, metrics) of one rollout."""
    config = analysis.rollout_config(settings["horizon"], settings["dt"], settings["feedback"])
    fixed = {p.name: settings[p.name] for p in SETTINGS if p.sweepable}

    def loss_fn(values):
        dtype = jnp.result_type(*values.values())
        row = {k: jnp.asarray(v, jnp.int32 if k == "mode_order" else dtype) for k, v in fixed.items()}
        row.update(values)
        m, _ = analysis.run_one(row, config)
        return m["loss"], {k: m[k] for k in AUX}

    return loss_fn


KV_TUNE = Objective(
    name="snake.kv",
    doc="T² Snake-3 joint-limit avoidance: K_V weights and k_eta minimising the gripper-tip error plus the "
    "time the base joints spend near their limits (kinematic rollout from the zigzag posture)",
    tunables=TUNABLES,
    settings=SETTINGS,
    make_loss=make_loss,
    references={"paper": PAPER},
    x64=True,
)
