"""What the T² Snake-3 MuJoCo experiment analyses (`table3`, `contact`, `sim_analysis`)
share: the perturbed-trial parameters (floor friction and heading jitter from each row's
seed), the run parameters (settling, threads) and the status of a batch.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from jaxloco.analysis import Metric, Param
from jaxloco.robots.snake import sim_control
from jaxloco.sim.scenario import seed_jitter

STATUSES = ("ok", "fell", "diverged")
MU_MIN = 0.05  # [-] the jittered friction never goes below this


def trial_params(mu: float) -> tuple[Param, ...]:
    """mu (default `mu`, ours) and the two jitters of a perturbed trial (defaults ours)."""
    return (
        Param("mu", mu, "floor friction coefficient (default (ours))", "", lo=MU_MIN, hi=3.0),
        Param("mu_jitter", 0.1, "mu + U(-1, 1) x this, from the row's seed (default (ours))", "", lo=0.0, hi=1.0),
        Param("heading_jitter", 0.05, "initial heading U(-1, 1) x this, from the row's seed (default (ours))", "rad",
              lo=0.0, hi=3.2),
    )


RUN_PARAMS = (
    Param("settle", sim_control.SETTLE, "settling on the servos before the paper's clock starts", "s", lo=0.0, hi=20.0,
          sweepable=False),
    Param("nthread", 0, "physics threads (0: all cores)", "", kind="int", lo=0, hi=1024, sweepable=False),
)
T_DIVERGED = Metric("t_diverged", "time the simulation diverged (nan: it did not)", "s")


def perturbed(values: Mapping[str, np.ndarray], keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(friction (n,), heading [rad] (n,)) of n trials from their rows' values (mu,
    mu_jitter, heading_jitter) and PRNG keys (n, 2)."""
    u = seed_jitter(keys, 2)
    mu = np.maximum(np.asarray(values["mu"], float) + u[:, 0] * np.asarray(values["mu_jitter"], float), MU_MIN)
    return mu, u[:, 1] * np.asarray(values["heading_jitter"], float)


def status(diverged: Any, fell: Any) -> np.ndarray:
    """STATUSES index per simulation: 2 diverged, 1 fell, 0 ok."""
    return np.where(np.asarray(diverged, bool), 2, np.where(np.asarray(fell, bool), 1, 0))
