"""`leggrope.shear_relief` tuning objective: the gain of the walk controller's shear relief
(`shear_relief`, m/s per M g of a toe's in-plane reaction beyond its share;
`control.shear_relief`), tuned by gradient descent through an MJX rollout of the
leg-grope walk's closed loop in forward mode (`Objective.grad_mode = "forward"`,
`jax.jvp`: MJX's constraint solver is a `while_loop`, which reverse mode cannot
differentiate, see `jaxloco.sim.mjx`).

The experiment is the start of `leggrope.fragile_walk` on its MJX variant
(`scenarios.make_scenario(mjx_contacts=True)`: pyramidal cone, no no-slip solver): the
robot placed on its initial footholds moves its body to the first grope's A' position on
four legs, the phase in which the shear relief acts. The loss is the stance's mean
squared friction use over the `horizon` after `t_settle` (the robot is placed unloaded):
u = |in-plane reaction| / (mu normal reaction) of each toe (a toe slips at u = 1), at the
control rate. Its aux metrics: the mean and largest u, and the largest in-plane
displacement of a toe from where it stood at t_settle (`toe_creep`, m).

Why this gain and this loss: the shear relief exists so that every stance toe uses the
same fraction of its friction cone (stiff servos share the slope's tangential load by
stiffness, and the most lightly loaded toe slips first); the loss measures exactly that,
and it depends smoothly on the gain (a feedback gain acting every control period, not a
threshold). Too small a gain leaves the light toes near the friction limit; too large a
one overshoots each period. On the 15 degree slope at mu = 0.45 (2 s, MuJoCo C on the MJX
variant's contacts) the mean of u^2 went 0.42 (gain 0), 0.344 (0.1, the default), 0.335
(0.4), 0.339 (0.8), 0.353 (1.6): a shallow optimum near 0.4.

Gradients through contact: the four toes stay in contact over the horizon (no contact
mode changes), so the loss is smooth in the gain between the tiny jumps of MJX's solver
iteration counts; the test checks the forward-mode derivative against central finite
differences of the same MJX loss. Forward mode costs one tangent per tuned tunable: tune
`shear_relief` alone (twist_relief then stays at its [init] value).

Settings: horizon, t_settle, theta, psi, mu, r_ref_factor. Reference "default (ours)": the
controller's defaults (shear_relief 0.1, twist_relief 0.02; ours, not the paper's).
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from typing import Any

import jax
import jax.numpy as jnp

from jaxloco import runtime
from jaxloco.analysis import Param
from jaxloco.robots.leggrope import scenarios, sim_analysis
from jaxloco.robots.leggrope.params import PARAMETERS
from jaxloco.sim.scenario import first_row
from jaxloco.tune.objective import Objective

_A = {p.name: p for p in sim_analysis.PARAMS}
# log scale, bounds for the optimiser inside the table's (0, 1] and [0, 0.5]
TUNABLES = (
    PARAMETERS.tunable("shear_relief", lo=1e-3, hi=1.0, scale="log"),
    PARAMETERS.tunable("twist_relief", lo=1e-4, hi=0.5, scale="log"),
)
SETTINGS = (
    Param("horizon", 1.5, "simulated time of the MJX rollout (the first A' ends at about 1.6 s)", "s", lo=0.1,
          hi=5.0),
    Param("t_settle", 0.2, "the loss starts here (the robot is placed unloaded at t = 0)", "s", lo=0.0, hi=5.0),
    _A["theta"],
    _A["psi"],
    _A["mu"],
    _A["r_ref_factor"],
)
AUX = ("mean_use", "max_use", "toe_creep")
DEFAULTS = {t.name: t.default for t in TUNABLES}  # shear_relief 0.1, twist_relief 0.02: default (ours)
MIN_NORMAL = scenarios.CONTACT_FORCE  # [N] friction use is taken over at least this normal force


@functools.lru_cache(maxsize=4)
def _rollout(horizon: float):
    """(scenario, MJX rollout of one simulation) of the walk's MJX variant, recorded every
    control period."""
    from jaxloco.sim import mjx as mjx_backend

    sc = scenarios.make_scenario(horizon_s=horizon, record_every=1, mjx_contacts=True)
    return sc, mjx_backend.rollout_fn(sc)


def friction_use(records: Mapping[str, Any], mu: Any, times: Any, t_settle: float) -> dict[str, Any]:
    """The stance's friction use from a walk's records (every control period): u = |in-plane
    reaction| / (mu normal reaction) per toe and record (the normal reaction taken as at
    least MIN_NORMAL [N]), from `t_settle` [s] on (`times`: the records' times [s]).
    Returns the loss (mean of u^2) and the aux metrics: mean and largest u, and the largest
    displacement [m] of a toe centre from where it was at t_settle (`toe_creep`)."""
    f, fn = records["foot_force"], records["normal_force"]  # (T, 4, 3) world, (T, 4) along the foothold normal [N]
    after = (times >= t_settle - 1e-9)[:, None]
    tangential2 = jnp.maximum(jnp.sum(f * f, axis=-1) - fn * fn, 0.0)
    u2 = tangential2 / (mu * jnp.maximum(fn, MIN_NORMAL)) ** 2
    n = jnp.sum(after) * u2.shape[1]
    u = jnp.sqrt(jnp.maximum(u2, 1e-18))
    toe = records["toe_pos"]  # (T, 4, 3) world [m]
    creep = jnp.linalg.norm(toe - toe[jnp.argmax(after[:, 0])][None], axis=-1)
    return {
        "loss": jnp.sum(jnp.where(after, u2, 0.0)) / n,
        "mean_use": jnp.sum(jnp.where(after, u, 0.0)) / n,
        "max_use": jnp.max(jnp.where(after, u, 0.0)),
        "toe_creep": jnp.max(jnp.where(after, creep, 0.0)),
    }


def make_loss(settings: Mapping[str, Any]):
    """`Objective.make_loss`: loss_fn(values) -> (loss, metrics) of one MJX rollout;
    the loss is nan when the simulation diverged (the runner then stops)."""
    horizon, t_settle = float(settings["horizon"]), float(settings["t_settle"])
    runtime.single_thread_lapack()
    sc, run = _rollout(horizon)
    times = jnp.arange(sc.n_records) * (sc.record_every * sc.control_dt)
    base = scenarios.params_batch(1, **{k: settings[k] for k in ("theta", "psi", "mu", "r_ref_factor")})
    key = jax.random.PRNGKey(0)

    def loss_fn(values):
        dtype = jnp.result_type(*values.values())
        p = first_row(base, dtype)
        p.update(shear_relief=values["shear_relief"], twist_relief=values["twist_relief"], key=key)
        records, _, final = run(p, key)
        m = friction_use(records, p["mu"], times, t_settle)
        loss = jnp.where(final.alive, m["loss"], jnp.nan)
        return loss, {k: m[k] for k in AUX}

    return loss_fn


SHEAR_RELIEF_TUNE = Objective(
    name="leggrope.shear_relief",
    doc="The leg-grope walk's shear-relief gain that keeps the stance toes furthest from slipping (mean squared "
    "friction use over the first body move, A'), by forward-mode gradients through an MJX rollout",
    tunables=TUNABLES,
    settings=SETTINGS,
    make_loss=make_loss,
    references={"default (ours)": DEFAULTS},
    x64=True,
    grad_mode="forward",
)
