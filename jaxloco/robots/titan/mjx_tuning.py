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
(1 s), then steps of 3 s (default 10 s: the two left-leg swings on three legs and the
first COG shift).

Loss: the body correction's tracking error, the mean over the plan's control periods
(the settling excluded) of the squared in-plane distance between the whole-robot centre
of mass and the executor's own target for it (`record`'s `cog` and `cog_target`: the
plan's COG moved with the supporting feet, `control.support_shift`; world frame, in the
plane of the slope) in mm^2. Why a finite optimum: a small gain leaves the servos' sag
and lag in the COG for long (the COG trails the target through each shift); a large
one rings against the servos (gain x control period ~1 at 25 /s) and makes the feet
slip. Measured on native MuJoCo, default settings, rms error over the 9 s of plan: 4.1
mm at 1 /s, 2.2 mm at 3 /s (the default), 1.3 mm at 8 /s, 1.11 mm at 16 /s (the
optimum), 1.19 mm at 20 /s, then the loop rings: 3.2 mm at 25 /s, 5.9 mm at 30 /s (and
the robot falls at 50 /s). Over one whole cycle (20 s) the optimum is the same (1.30 mm
at 16 /s, 2.5 mm at 3 /s). The optimum sits at ~2/3 of the gain where the loop starts
ringing: the tunable's upper bound (20 /s, the titan.walk range) keeps the optimiser
below it, and `--validate` walks the tuned gain on frames and slopes.

Gradients through contact: the feet stay on the ground (the swing foot's touchdown
latches once per swing, at a time that moves continuously with the gain), so the loss is
smooth in the gain between rare jumps; MuJoCo's default soft contacts are kept.
`tests/test_titan_mjx_tune.py` checks the forward-mode derivative against central
differences of the same MJX loss.

Reproducibility: the loss is a deterministic, smooth function of the gain for one
compiled program, but a rounding-level change of the program (XLA's optimisation flags,
the params folded as constants or passed in) can move it by 1-3 %. The cause is the
four-legged stance at t = 0: its contact forces are poorly determined (the internal
forces of the closed chain barely change the accelerations), the first constraint solve
stops after 0-3 iterations, and a 1e-15 relative change of qpos moves 3-4 kN of the
~17 kN per foot between the feet (measured on MuJoCo's C engine as well); the feet keep
that split through the settling. Native MuJoCo and MJX, compiled alike, give the same
loss (to 1e-14 m in the centre of mass over 4 s); across such changes, within 3 %.

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
from jaxloco.sim.scenario import first_row
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
MM2 = 1e6  # [mm^2 / m^2]


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
    """The loss (mm^2) and the rms and max in-plane error [m] of the whole-robot centre of
    mass against the executor's target for it over the plan's records (one simulation)."""
    n, _ = control.frames(p)
    err = records["cog"] - records["cog_target"]
    err = err - (err @ n)[:, None] * n
    e2 = jnp.sum(err * err, axis=-1)
    running = (records["step"] >= 0).astype(e2.dtype)
    mean = jnp.sum(running * e2) / jnp.maximum(jnp.sum(running), 1.0)
    return {"loss": MM2 * mean, "rms_cog_error": jnp.sqrt(mean), "max_cog_error": jnp.sqrt(jnp.max(running * e2))}


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
    base = {k: np.asarray(v) for k, v in loss_params(settings).items()}

    def loss_fn(values):
        dtype = jnp.result_type(*values.values())
        p = first_row(base, dtype)
        p["body_gain"] = values["body_gain"]
        records, metrics, final = run(p, jax.random.PRNGKey(0))
        m = cog_error(p, records)
        m.update({k: metrics[k] for k in ("min_nesm", "foot_slip", "max_tilt")})
        return jnp.where(final.alive, m["loss"], jnp.nan), {k: m[k] for k in AUX}

    return loss_fn


BODY_GAIN_TUNE = Objective(
    name="titan.body_gain",
    doc="TITAN XI footstep executor: the integral body-correction gain minimising the whole-robot COG's squared "
    "in-plane error against the executor's target over the first steps of the crawl gait (default: the Sec. 8.4 "
    "30 deg slope), by forward-mode gradients through an MJX rollout",
    tunables=TUNABLES,
    settings=SETTINGS,
    make_loss=make_loss,
    references={"default (ours)": DEFAULT},
    x64=True,
    grad_mode="forward",
)
