"""`titan.body_gain` tuning objective: the footstep executor's integral gain `body_gain`
[1/s] (`control.executor_step`: the correction that drives the whole-robot centre of mass
and the body attitude onto the plan), tuned by gradient descent through an MJX rollout
of the closed loop in forward mode (`Objective.grad_mode = "forward"`: MJX's constraint
solver is a `while_loop`, which reverse mode cannot differentiate, see `jaxloco.sim.mjx`).

The experiment: TITAN XI on a plane of `slope` (default the Sec. 8.4 test slope, 30 deg,
the tethers cancelling `tether` of the slope-parallel gravity, friction `mu`) starts the
standard intermittent crawl gait (Sec. 4.4; `scenarios.demo_crawl_plan`, one cycle up
the fall line: plain ground leaves the planner nothing to adapt) and the executor runs
it for `horizon` s on the model's MJX variant (`scenarios.mjx_variant`): the settling
(1 s), then the first steps of 3 s each (default 7 s: the two left-leg swings on three
legs, where the centre of mass must hold against the support's edges).

Loss: the mean over the plan's control periods (the settling excluded) of the squared
in-plane distance between the whole-robot centre of mass and the plan's body target
(`record`'s `cog` and `body_target`, world frame, in the plane of the slope) in cm^2.
Why a finite optimum: a small gain leaves the servos' sag and the feet's slip in the
COG for long; a large one rings against the servos' lag (gain x control period ~1 at
25 /s) and makes the feet slip. Measured on native MuJoCo (default settings, rms error
over the 6 s of plan): 4.5 mm at 0 /s, 3.8 mm at 3-5 /s (the default, 3 /s, sits near
the optimum), 4.3 mm at 20 /s, 9 mm at 30 /s; at 50 /s the robot falls. The optimum
moves with the horizon (4 s: ~12 /s; 10 s: ~10 /s, measured): tune on the steps you care
about.

Gradients through contact: the feet stay on the ground (the swing foot's touchdown
latches once per swing, at a time that moves continuously with the gain), so the loss is
smooth in the gain between rare jumps; MuJoCo's default soft contacts are kept.
`tests/test_titan_mjx_tune.py` checks the forward-mode derivative against central
differences of the same MJX loss.

Settings: slope, tether, mu and horizon. Reference "default (ours)": body_gain = 3 /s
(`params.py`; the paper gives no executor).
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import replace
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco import runtime
from jaxloco.robots.titan import control, scenarios
from jaxloco.robots.titan import params as titan_params
from jaxloco.tune.objective import Objective

_P = titan_params.PARAMETERS
# log scale; the optimiser's lower bound keeps the gain positive (the sweep's is 0)
TUNABLES = (_P.tunable("body_gain", lo=0.1, scale="log"),)
SETTINGS = (
    replace(_P["slope"], default=float(titan_params.SLOPE_ANGLE), doc="slope of the plane (default: Sec. 8.4, "
            "30 deg); the robot walks straight up it"),
    _P["tether"],
    _P["mu"],
    _P["horizon"],
)
AUX = ("rms_cog_error", "max_cog_error", "min_nesm", "foot_slip", "max_tilt")
DEFAULT = {"body_gain": _P.default("body_gain")}  # default (ours)
START = (0.0, 4.0)  # [m] slope-frame start of the COG path, clear of the terrain's beam stub at the origin
FIELD = scenarios.FrameField(n_along=1, n_across=1)  # one flush beam stub at the origin: plain ground
CM2 = 1e4  # [cm^2 / m^2]


def plan(slope: float) -> scenarios.Plan:
    """The walk: one cycle of the standard crawl gait up the fall line of the plane."""
    return scenarios.demo_crawl_plan(1, start=START).to_world(slope)


@functools.lru_cache(maxsize=4)
def loss_scenario(horizon: float, backend: str = "mjx"):
    """The objective's scenario for `horizon` s (one per horizon and backend, kept)."""
    return scenarios.make_scenario(6, horizon_s=horizon, field=FIELD, backend=backend)


@functools.lru_cache(maxsize=4)
def _rollout_fn(horizon: float):
    from jaxloco.sim import mjx as mjx_backend

    return mjx_backend.rollout_fn(loss_scenario(horizon))


def cog_error(p: Mapping[str, Any], records: Mapping[str, jax.Array]) -> dict[str, jax.Array]:
    """The loss (cm^2) and the rms and max in-plane error [m] of the whole-robot centre of
    mass against the plan's body target over the plan's records (one simulation)."""
    n, _ = control.frames(p)
    err = records["cog"] - records["body_target"]
    err = err - (err @ n)[:, None] * n
    e2 = jnp.sum(err * err, axis=-1)
    running = (records["step"] >= 0).astype(e2.dtype)
    mean = jnp.sum(running * e2) / jnp.maximum(jnp.sum(running), 1.0)
    return {"loss": CM2 * mean, "rms_cog_error": jnp.sqrt(mean), "max_cog_error": jnp.sqrt(jnp.max(running * e2))}


def loss_params(settings: Mapping[str, Any], n: int = 1, **overrides) -> dict[str, jax.Array]:
    """The scenario's params batch (n simulations) for the settings."""
    slope = float(settings["slope"])
    return scenarios.params_batch(plan(slope), n, theta=slope, tether=float(settings["tether"]),
                                  mu=float(settings["mu"]), **overrides)


def make_loss(settings: Mapping[str, Any]):
    """`Objective.make_loss`: loss_fn(values) -> (loss, metrics) of one MJX rollout; the
    loss is nan when the simulation diverged (the runner then stops)."""
    runtime.single_thread_lapack()
    run = _rollout_fn(float(settings["horizon"]))
    base = {k: np.asarray(v)[0] for k, v in loss_params(settings).items()}

    def loss_fn(values):
        dtype = jnp.result_type(*values.values())
        p = {k: jnp.asarray(v) if np.issubdtype(v.dtype, np.integer) or v.dtype == bool else jnp.asarray(v, dtype)
             for k, v in base.items()}
        p["body_gain"] = values["body_gain"]
        records, metrics, final = run(p, jax.random.PRNGKey(0))
        m = cog_error(p, records)
        m.update({k: metrics[k] for k in ("min_nesm", "foot_slip", "max_tilt")})
        return jnp.where(final.alive, m["loss"], jnp.nan), {k: m[k] for k in AUX}

    return loss_fn


BODY_GAIN_TUNE = Objective(
    name="titan.body_gain",
    doc="TITAN XI footstep executor: the integral body-correction gain minimising the whole-robot COG's squared "
    "in-plane error against the plan over the first steps of the crawl gait (default: the Sec. 8.4 30 deg slope), "
    "by forward-mode gradients through an MJX rollout",
    tunables=TUNABLES,
    settings=SETTINGS,
    make_loss=make_loss,
    references={"default (ours)": DEFAULT},
    x64=True,
    grad_mode="forward",
)
