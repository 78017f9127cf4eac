"""`snake.reach_gain` tuning objective: the task-space gain K of Eq. 13 (`gain_k`, 1/s;
optionally k_eta) of T² Snake-3's feedback controller, tuned by gradient descent through
an MJX rollout of the closed loop in forward mode (`Objective.grad_mode = "forward"`,
`jax.jacfwd`: MJX's constraint solver is a `while_loop`, which reverse mode cannot
differentiate, see `jaxloco.sim.mjx`).

The experiment is `sim_analysis`' reach on its "plane" model (MJX has no cylinder-box
collision): from the settled robot (`sim_analysis.settled_state`: 8 s simulated once in
MuJoCo's C code, outside the gradient), the gripper tip's target rises by d_z (default
3 cm, world z) over `ramp` s from t_start; the loss is `sim_analysis.reach_metrics`'
loss, the mean squared tip position error over the `horizon` in cm^2 plus `w_effort`
times the mean squared commanded joint speed [rad^2/s^2].

Why K has a finite optimum, and why the horizon is 3 s: a small K leaves the tip
error that the head part's sag under its soft servos makes as the posture changes; a
large K feeds the measured tip back through position servos that lag and excites the
head part's lightly damped bounce on them (period ~0.7 s). On native MuJoCo (5 s runs,
`snake.reach`) that bounce grows slowly from K ~ 1.5 /s on and fast from 2 /s, so a
1.5 s rollout still rewards K ~ 1.5 (its optimum), while 3 s put the optimum near
1 /s and 4-5 s near 0.75 /s (tip up); the default horizon is 3 s (1500 physics steps).

Gradients through contact: the wheels stay on the ground, so the loss is smooth in K
between rare jumps (MJX's contact points or solver iterations change discretely: at
K = 1 a jump of 1e-4 in the loss lies within 1e-4 of K), which finite differences must
avoid with steps of ~1e-5; forward mode does not see them. MuJoCo's default soft
contacts (solref 0.02 s) are kept. Forward mode costs one tangent per tuned tunable:
tune `gain_k` alone (k_eta then stays at its [init] value).

Settings: horizon, t_start, ramp, d_x, d_y, d_z, w_effort (as in the `snake.reach`
analysis) and settle. Reference "paper": K = 1 /s (`control.ControlParams`' default,
the paper gives no value) with k_eta = 0.1.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import replace
from typing import Any

import jax
import jax.numpy as jnp

from jaxloco import runtime
from jaxloco.robots.snake import params as snake_params
from jaxloco.robots.snake import sim_analysis
from jaxloco.sim.scenario import first_row
from jaxloco.tune.objective import Objective

GROUND = "plane"  # the MJX-compatible model (sim_analysis.build_model)

_P = snake_params.PARAMETERS
# log scale, bounds for the optimiser (tighter than the sweep's K, wider than its k_eta)
TUNABLES = (
    _P.tunable("gain_k", lo=0.05, hi=50.0, scale="log"),
    _P.tunable("k_eta", lo=1e-4, hi=100.0, scale="log"),
)
_A = {p.name: p for p in sim_analysis.PARAMS}
# the snake.reach parameters; an MJX rollout is short (at most 10 s) and compiled per horizon and settle,
# which the runner passes as settings (sweepable: a tune setting, not a sweep axis)
SETTINGS = (
    replace(_A["horizon"], doc="simulated time of the reach (after the settling): the MJX rollout's length",
            hi=10.0, sweepable=True),
    replace(_A["t_start"], doc="the target starts to move at this time", hi=10.0),
    replace(_A["ramp"], hi=10.0),
    _A["d_x"],
    _A["d_y"],
    _A["d_z"],
    _A["w_effort"],
    replace(_A["settle"], doc="settling before the reach (MuJoCo C, once, outside the gradient)", sweepable=True),
)
AUX = ("rms_error", "final_error", "max_error", "effort")
PAPER = {t.name: t.default for t in TUNABLES}  # K = 1 /s (ControlParams' default), k_eta = 0.1


@functools.lru_cache(maxsize=4)
def _rollout_fn(horizon: float, settle: float):
    from jaxloco.sim import mjx as mjx_backend

    return mjx_backend.rollout_fn(sim_analysis.reach_scenario(GROUND, horizon, settle))


def make_loss(settings: Mapping[str, Any]):
    """`Objective.make_loss`: loss_fn(values) -> (loss, metrics) of one MJX rollout;
    the loss is nan when the simulation diverged (the runner then stops)."""
    horizon, settle = float(settings["horizon"]), float(settings["settle"])
    runtime.single_thread_lapack()
    run = _rollout_fn(horizon, settle)
    base = sim_analysis.reach_params(1, t_start=settings["t_start"], ramp=settings["ramp"],
                          **{k: settings[k] for k in sim_analysis.DELTA_POS})
    delta = [float(settings[k]) for k in sim_analysis.DELTA_POS]

    def loss_fn(values):
        dtype = jnp.result_type(*values.values())
        p = first_row(base, dtype)
        p["gain"] = values["gain_k"]
        p["k_eta"] = values["k_eta"]
        records, _, final = run(p, jax.random.PRNGKey(0))
        m = sim_analysis.reach_metrics(
            records["tip"],
            records["phi_cmd"],
            jnp.asarray(delta, dtype),
            settings["t_start"],
            settings["ramp"],
            1.0,
            settings["w_effort"],
        )
        loss = jnp.where(final.alive, m["loss"], jnp.nan)
        return loss, {k: m[k] for k in AUX}

    return loss_fn


REACH_GAIN_TUNE = Objective(
    name="snake.reach_gain",
    doc="T² Snake-3 gripper-tip reach under feedback task-space control: the gain K minimising the tip's mean "
    "squared error (+ a small joint-speed penalty), by forward-mode gradients through an MJX rollout",
    tunables=TUNABLES,
    settings=SETTINGS,
    make_loss=make_loss,
    references={"paper": PAPER},
    x64=True,
    grad_mode="forward",
)
