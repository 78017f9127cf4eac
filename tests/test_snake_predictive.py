"""Predictive mode selection (`predictive`): the chosen mode is the best look-ahead."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxloco.robots.snake import experiments, kinsim, predictive

DT = 0.05
PRED = predictive.Prediction(horizon_s=0.3, w_error=1.0)


@pytest.fixture(scope="module")
def setup():
    x0, target = experiments.limit_setup()
    cp = experiments.limit_params(switch_at=0.0, delta_t=0.5)  # switching from the start, a slot every 0.5 s
    return x0, target, cp


def test_scores_are_the_look_ahead_rollouts_one_by_one(setup):
    """vmap over the candidates == a loop of `kinsim.rollout`s in each fixed mode, scored
    by the module's formula."""
    x0, target, cp = setup
    scores = np.asarray(predictive.mode_scores(x0, jnp.asarray(0.0), target, cp, DT, "tip", PRED))
    config = kinsim.RolloutConfig(steps=round(PRED.horizon_s / DT), dt=DT, point="tip")
    one = jax.jit(lambda sg: kinsim.rollout(x0, target, cp.with_(fixed_mode=sg, switch_at=jnp.inf, enter_ratio=2.0),
                                       config))
    for i, sigma in enumerate(predictive.CANDIDATES):
        rec = one(jnp.asarray(sigma, jnp.int32))
        e = np.asarray(rec["error"])
        err = (e[:, :3] ** 2).sum(-1) / 0.03**2 + (e[:, 3:6] ** 2).sum(-1) / 0.1**2
        assert np.all(np.asarray(rec["sigma"]) == sigma)
        assert scores[i] == pytest.approx(float(rec["V"][-1] / rec["V"][0] + err.mean()), rel=1e-9)
    assert np.ptp(scores) > 1e-3  # the modes do differ


def test_predictive_rollout_holds_the_best_mode_for_each_slot(setup):
    x0, target, cp = setup
    config = kinsim.RolloutConfig(steps=round(1.5 / DT), dt=DT, point="tip")
    choose = predictive.chooser(target, cp, DT, "tip", PRED)
    rec = jax.jit(lambda: kinsim.rollout(x0, target, cp, config, choose=choose))()
    sigma, t = np.asarray(rec["sigma"]), np.asarray(rec["t"])
    assert set(np.unique(sigma)) <= set(predictive.CANDIDATES.tolist())
    for k in range(3):  # one mode per 0.5 s slot
        slot = (t >= 0.5 * k - 1e-9) & (t < 0.5 * (k + 1) - 1e-9)
        assert np.unique(sigma[slot]).size == 1
    first = predictive.CANDIDATES[
        int(np.argmin(predictive.mode_scores(x0, jnp.asarray(0.0), target, cp, DT, "tip", PRED)))
    ]
    assert sigma[0] == first
