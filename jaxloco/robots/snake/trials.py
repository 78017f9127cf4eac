"""What the T² Snake-3 MuJoCo experiment analyses (`table3`, `contact`, `sim_analysis`)
share: the perturbed trials (floor friction and heading jitter from each row's seed; the
parameters are in `params.PARAMETERS`) and the status of a batch.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from jaxloco.analysis import Metric
from jaxloco.robots.snake import params as snake_params
from jaxloco.sim.scenario import seed_jitter

STATUSES = ("ok", "fell", "diverged")
MU_MIN = snake_params.PARAMETERS["mu"].lo  # [-] the jittered friction never goes below this (mu's bound)


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
