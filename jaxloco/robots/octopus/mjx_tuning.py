"""`octopus.climb_lift` tuning objective: Delta_E (`delta_e`, rad/period), the boom step of
the CLM's CLIMB (Eq. 28), tuned by gradient descent through an MJX rollout of the closed
loop in forward mode (`Objective.grad_mode = "forward"`, `jax.jacfwd`: MJX's constraint
solver is a `while_loop`, which reverse mode cannot differentiate, see `jaxloco.sim.mjx`).

The question: which Delta_E lifts the body at a wanted speed? The CLIMB (our level lift,
`climb_paper` = 0, set here: `LEVEL_LIFT`; the controller's default is the paper's climb)
lowers the pushing arms' EPRAs by Delta_E l1 per period along the world vertical, so
the body rises about 24.5 Delta_E m/s as commanded; the actual rise is slower and not
proportional: the arms take turns to keep the body within the level band, the servos
lag and the arms sag under the load. The loss is the mean
squared error [cm^2] between the COG's rise and `lift_speed` x t over the first `horizon`
seconds of the CLIMB (`lift_metrics`); its optimum is the Delta_E whose lift runs at
`lift_speed` (default 0.1 m/s, ours; the paper gives neither Delta_E nor a lift speed).

The experiment starts at the CLIMB start (`climb_start`): the CLM walks up to the step of
`height` from the `octopus.step_climb` defaults (0.7 m away, heading straight, mu 0.8),
detects it, squares up and places its rear arms (PREPARE), 23.2 s on a 400 mm step,
simulated once in MuJoCo's C code outside the gradient. Nothing before the CLIMB reads
Delta_E, so that state is the same for every Delta_E, and the rollout (`climb_scenario`)
continues from it, the controller resumed with its state and clock (`resumed`). Within
the horizon only the CLIMB's lift runs: Delta_E enters through the arms' commands.

Gradients through contact: the arm rollers and crawler wheels switch contacts at periods
that move with Delta_E (at Delta_E = 0.006 on the 400 mm step the left-front roller, which
carried 0.2 N, lifted off in period 37 or 38 of the CLIMB from the CLIMB start before 7 Dec
2026), so over 1 s the loss jumps by
~1e-4 cm^2 between smooth pieces 1e-6 to 1e-5 rad/period wide. Forward mode gives the
slope of the piece: central differences with steps of 1e-6 agree to 2e-9 relative
(tests/test_octopus_mjx_tune.py, over 0.6 s), while a stencil of 1e-5 straddles the
roller's jump and is 0.5 % off over 1 s. MuJoCo's default soft contacts are kept.
Forward mode costs one tangent per tuned tunable; Delta_E is the only one (Delta_F does
not act within the first 2 s: the flippers turn once the front is lifted).

Settings: horizon (the CLIMB seconds on MJX), height (the step; above `crawl_max_h` so
that the arms climb it) and lift_speed. Reference "default (ours)": Delta_E = 0.006.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco import runtime
from jaxloco.errors import SpecError
from jaxloco.robots.octopus import clm, operator, scenarios
from jaxloco.robots.octopus.params import PARAMETERS
from jaxloco.sim.scenario import Controller, InitialState, Scenario, first_row
from jaxloco.tune.objective import Objective

KIND = "step1"  # the 400 mm one-terrace step of the paper (any height in the settings)
MAX_APPROACH_S = 45.0  # [s] the walk, detection and PREPARE reach the CLIMB within this (40.3 s at 0.55 m)
LIFT_UNIT = 0.01  # [m] the loss is in cm^2

# the climb tuned here: our level lift (a named option; the CLM's default is the paper's Eqs. 28-29, whose
# booms turn by Delta_E in joint space)
LEVEL_LIFT = {"climb_paper": 0.0}
TUNABLES = (PARAMETERS.tunable("delta_e", lo=0.001, hi=0.02, scale="log"),)  # tighter than the sweep's range
SETTINGS = (
    *PARAMETERS.select(
        "horizon", "height", "lift_speed",
        horizon={"default": 2.0, "lo": 0.1, "hi": 10.0, "sweepable": True,
                 "doc": "CLIMB time simulated on MJX from the CLIMB start (the loss' window)"},
        height={"lo": 0.3, "doc": "the step climbed (above crawl_max_h = 0.25 m, so that the arms climb it)"},
    ),
)
# beside the loss: `lift_metrics`' lift [m], mean_lift_speed [m/s], rms_error [m]; max_tilt, the largest
# |roll| or |pitch| over the horizon [rad]
AUX = ("lift", "mean_lift_speed", "rms_error", "max_tilt")
DEFAULT = {t.name: t.default for t in TUNABLES}  # Delta_E = 0.006 rad/period, default (ours)


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class ClimbStart:
    """The MuJoCo and controller state of one simulation when its CLIMB begins: joint
    positions and speeds, the controls applied in the last period, the CLM state and the
    time [s] since the start of the walk."""

    qpos: jax.Array
    qvel: jax.Array
    ctrl: jax.Array
    ctrl_state: clm.ClmState
    time: jax.Array


def _controller() -> Controller:
    """The controller of `octopus.step_climb` with the CLM (the operator layer off by default)."""
    return operator.with_operator(clm.make_controller())


@functools.lru_cache(maxsize=4)
def climb_start(height: float) -> ClimbStart:
    """Walk up to a `height` m step with the `octopus.step_climb` defaults on native MuJoCo
    (one thread) until the CLM enters CLIMB: its state then (`ClimbStart`), read from the
    records of every control period (a record holds the state after that many periods).
    SpecError (one line) when it does not within MAX_APPROACH_S."""
    from jaxloco.sim.rollout import rollout

    walk = scenarios.make_scenario(KIND, _controller(), horizon_s=MAX_APPROACH_S, record_every=1)
    p = scenarios.params_batch(1, height=height, **LEVEL_LIFT)

    def record(p, data, obs, c, e):
        leaves = {f"ctrl_state_{i}": x for i, x in enumerate(jax.tree_util.tree_leaves(c))}
        return {"qpos": data.qpos, "qvel": data.qvel, "ctrl": data.ctrl, "time": data.time, **leaves}

    r = rollout(walk.with_(record=record, summarize=lambda p, r, final: {}), p, backend="native", nthread=1)
    treedef = jax.tree_util.tree_structure(r.final.ctrl_state)
    states = [r.records[f"ctrl_state_{i}"][0] for i in range(treedef.num_leaves)]
    phase = jax.tree_util.tree_unflatten(treedef, states).phase
    if r.diverged[0] or not (phase == clm.CLIMB).any():
        raise SpecError(f"settings.height: the CLM did not start its CLIMB within {MAX_APPROACH_S:g} s on a "
                        f"{height:g} m step (phase {clm.PHASE_NAMES[int(phase[-1])]} at the end, status "
                        f"{r.status[0]})")
    k = int(np.argmax(phase == clm.CLIMB))
    at = lambda x: jnp.asarray(x[k])  # noqa: E731
    return ClimbStart(qpos=at(r.records["qpos"][0]), qvel=at(r.records["qvel"][0]), ctrl=at(r.records["ctrl"][0]),
                      ctrl_state=jax.tree_util.tree_unflatten(treedef, [at(x) for x in states]),
                      time=at(r.records["time"][0]))


def resumed(controller: Controller, state: Any, t0: jax.Array) -> Controller:
    """`controller` resumed from `state` at time t0 [s]: init returns `state` (whatever it
    observes), step sees the observation's "time" shifted by t0 (the rollout starts at 0)."""

    def step(p, s, obs):
        return controller.step(p, s, {**obs, "time": obs["time"] + t0})

    return Controller(init=lambda p, obs: state, step=step, name=controller.name)


@functools.lru_cache(maxsize=4)
def climb_scenario(height: float, horizon: float) -> Scenario:
    """The CLIMB of a `height` m step from its start (`climb_start`) for `horizon` s,
    recorded every control period; one object per (height, horizon), so its compiled
    rollouts are reused."""
    start = climb_start(height)
    base = scenarios.make_scenario(KIND, _controller(), horizon_s=horizon, record_every=1)

    def initial_state(p, key):
        terrain = base.initial_state(p, key)  # the step placed from p
        dtype = terrain.mocap_pos.dtype
        return InitialState(qpos=start.qpos.astype(dtype), qvel=start.qvel.astype(dtype),
                            ctrl=start.ctrl.astype(dtype), mocap_pos=terrain.mocap_pos,
                            mocap_quat=terrain.mocap_quat)

    return base.with_(name=f"octopus.{KIND}_climb", initial_state=initial_state,
                      controller=resumed(base.controller, start.ctrl_state, start.time))


def params(n: int = 1, height: float = 0.4, **overrides) -> dict[str, jax.Array]:
    """The parameters of n climbs of `climb_scenario(height, ...)`: the step_climb
    defaults with the step height, our level lift (`LEVEL_LIFT`) and `overrides` (e.g.
    delta_e, arrays of length n)."""
    return scenarios.params_batch(n, height=height, **{**LEVEL_LIFT, **overrides})


def lift_metrics(cog_z: jax.Array, dt: float, lift_speed: jax.Array | float) -> dict[str, jax.Array]:
    """The lift of the body from records of the COG height cog_z (n,) [m] every dt s (the
    first at the CLIMB start): loss = mean of ((z - z_0 - lift_speed t) / 1 cm)^2 [cm^2];
    lift = z_{n-1} - z_0 [m]; mean_lift_speed = lift / t_{n-1} [m/s]; rms_error [m]."""
    z = jnp.asarray(cog_z)
    t = jnp.arange(z.shape[0], dtype=z.dtype) * dt
    err = z - z[0] - lift_speed * t
    lift = z[-1] - z[0]
    return {"loss": jnp.mean((err / LIFT_UNIT) ** 2), "lift": lift, "mean_lift_speed": lift / t[-1],
            "rms_error": jnp.sqrt(jnp.mean(err**2))}


@functools.lru_cache(maxsize=4)
def _rollout_fn(height: float, horizon: float):
    from jaxloco.sim import mjx as mjx_backend

    return mjx_backend.rollout_fn(climb_scenario(height, horizon))


def make_loss(settings: Mapping[str, Any]):
    """`Objective.make_loss`: loss_fn(values) -> (loss, metrics) of one MJX rollout of the
    CLIMB; the loss is nan when the simulation diverged (the runner then stops)."""
    height, horizon = float(settings["height"]), float(settings["horizon"])
    runtime.single_thread_lapack()
    run = _rollout_fn(height, horizon)
    dt = climb_scenario(height, horizon).control_dt
    base = params(1, height)

    def loss_fn(values):
        dtype = jnp.result_type(*values.values())
        p = first_row(base, dtype)
        p["delta_e"] = values["delta_e"]
        records, _, final = run(p, jax.random.PRNGKey(0))
        m = lift_metrics(records["cog"][:, 2], dt, settings["lift_speed"])
        tilt = jnp.max(jnp.abs(records["rpy"][:, :2]))
        loss = jnp.where(final.alive, m["loss"], jnp.nan)
        return loss, {"lift": m["lift"], "mean_lift_speed": m["mean_lift_speed"], "rms_error": m["rms_error"],
                      "max_tilt": tilt}

    return loss_fn


CLIMB_LIFT_TUNE = Objective(
    name="octopus.climb_lift",
    doc="OCTOPUS CLM climb: the boom step Delta_E that lifts the body at lift_speed (mean squared error of the "
    "COG's rise over the first seconds of the CLIMB), by forward-mode gradients through an MJX rollout from the "
    "CLIMB start",
    tunables=TUNABLES,
    settings=SETTINGS,
    make_loss=make_loss,
    references={"default (ours)": DEFAULT},
    x64=True,
    grad_mode="forward",
)
