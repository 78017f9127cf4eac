"""Predictive mode selection for T² Snake-3 (beyond the paper, Sec. V-E): at each switch,
roll every candidate mode forward and take the best, instead of the fixed order.

The paper switches modes 2, 3, ..., 6, 2, ... in a fixed order "to reduce the
calculation cost", and says a predicted choice (its ref. [21]) would be better (Sec.
V-E, with Eq. 20). In JAX the prediction is one `vmap`: at the start of every Delta T
slot of the switching state, `chooser` runs the kinematic closed loop (`kinsim.rollout`,
no skid, the same controller, servo speed limits) from the state the controller sees,
holding each candidate mode (Table II's modes 2-6) for `horizon_s`, and picks the one
with the lowest score

    J(sigma) = V(T) / V(0) + w_error * mean_t( |e_p|^2 / e_p0^2 + |e_a|^2 / e_a0^2 )

V the controller's cost (Eq. 19 / 20) at the end of the horizon relative to its start,
e_p, e_a the controlled point's position and attitude errors over the horizon in units
of the paper's tolerances (e_p0 = 30 mm, e_a0 = 0.1 rad, Sec. V-B). Horizon and weight
are ours (`Prediction`). `mode_scores` gives the scores, for plots and tests.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco.robots.snake import control, experiments, kinsim
from jaxloco.robots.snake import params as snake_params

Array = jax.Array
CANDIDATES = np.arange(2, snake_params.N_MODES + 1)  # Table II's switching modes 2..6


@dataclass(frozen=True)
class Prediction:
    """Settings of the predictive choice (defaults ours): look-ahead horizon [s] and the
    weight of the tracking error against the drop of V."""

    horizon_s: float = 1.0
    w_error: float = 1.0


def mode_scores(
    state: kinsim.SnakeState,
    t: Array,
    target: kinsim.Target,
    cp: control.ControlParams,
    dt: float,
    point: str,
    prediction: Prediction = Prediction(),
    plant: kinsim.PlantParams | None = None,
    params: snake_params.SnakeParams | None = None,
) -> Array:
    """J(sigma) (5,) of the candidate modes 2..6 (module docstring) from `state` at time t
    [s] (the target's clock), each a `kinsim.rollout` of horizon_s in that fixed mode."""
    plant = kinsim.PlantParams() if plant is None else plant
    steps = max(1, round(prediction.horizon_s / dt))
    config = kinsim.RolloutConfig(steps=steps, dt=dt, point=point, feedback=False)
    ahead = kinsim.Target(target.w0, target.delta, target.t0 - t, target.duration)  # the target from time t on
    e_p0, e_a0 = experiments.PAPER_HEAD_ERROR

    def score(sigma: Array) -> Array:
        fixed = cp.with_(fixed_mode=sigma, switch_at=jnp.inf, enter_ratio=2.0)
        rec = kinsim.rollout(state, ahead, fixed, config, plant, params)
        e = rec["error"]
        err = jnp.sum(e[:, :3] ** 2, -1) / e_p0**2 + jnp.sum(e[:, 3:6] ** 2, -1) / e_a0**2
        return rec["V"][-1] / rec["V"][0] + prediction.w_error * jnp.mean(err)

    return jax.vmap(score)(jnp.asarray(CANDIDATES, jnp.int32))


def chooser(
    target: kinsim.Target,
    cp: control.ControlParams,
    dt: float,
    point: str,
    prediction: Prediction = Prediction(),
    plant: kinsim.PlantParams | None = None,
    params: snake_params.SnakeParams | None = None,
) -> Callable[[kinsim.SnakeState, Array], Array]:
    """choose(state, t) -> the candidate mode of lowest J (for `kinsim.rollout`'s
    `choose`)."""

    def choose(state: kinsim.SnakeState, t: Array) -> Array:
        scores = mode_scores(state, t, target, cp, dt, point, prediction, plant, params)
        return jnp.asarray(CANDIDATES, jnp.int32)[jnp.argmin(scores)]

    return choose
