"""The teleoperator of T² Snake-3's operations (Sec. V-D) as a model (ours): what the
person holding the joysticks adds to the script of commands.

The paper's robot is teleoperated: "the operator uses a joystick to change the target
velocity of the controlled variable w_d_dot, and w_d is calculated by numerical
integration" (Sec. IV-C), "the operator needs to compensate for the error by operating
a joystick" (Sec. V-E), and the switching state is entered "under the command of the
operator" when a joint reaches its limit and the robot cannot move on (Sec. IV-C5, Fig.
14 d-g). The paper gives the commands, not the operator, so everything here is ours:

  * the script (`kinsim.Target` with steps): the commands the operator means to give,
    played on the operator's own clock. The intended pose of the controlled point is
    where it was seen at t = 0 plus the script's change (`OperatorState.seen0`);
  * correction (`gain` [1/s], 0 = none): watching the controlled point, the operator
    adds to w_d_dot `gain` x (intended - seen position), integrated into an offset of
    the target position, at most `limit` [m] per axis (a person does not pull without
    bound at something that does not move). Positions only: attitude errors of a few
    degrees are hard to see;
  * mode switching (`enter`, `exit`): when a base yaw joint (theta_4..theta_9: Fig. 14
    d, f, "the joint reached the limit angle and the robot could not move backward")
    reaches `enter` x its limit (`base_limit_ratio` of the encoders' angles, as the
    operator sees the robot stall), the operator
    stops the script's clock and commands the switching state for at least `min_switch`
    s and until every such joint is below `exit` x its limit; then the script resumes
    where it stopped. `enter` > 1 (default 2.0) never switches.

The model is a small state machine on explicit state (`OperatorState`), pure JAX, used
by `sim_control.task_space_controller` at every control period.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import jax
import jax.numpy as jnp

from jaxloco.robots.snake import control, kinsim, params

Array = jax.Array

# the operator's parameters in a simulation's params dict (defaults ours; 0 gain and enter 2.0: no operator)
# (gain and enter here are "off", not the parameters' defaults of `snake.operations`)
PARAM_DEFAULTS: dict[str, float] = {
    "operator_gain": 0.0,  # [1/s] joystick correction of the position error
    "operator_limit": 0.1,  # [m] the largest correction per axis
    "operator_enter": 2.0,  # a joint at this fraction of its limit: the operator switches modes (> 1: never)
    # ... until every joint is below this fraction, and at least this long [s]
    **params.PARAMETERS.defaults(("operator_exit", "operator_min_switch")),
}


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class OperatorState:
    """The operator's state: the time the script has been paused [s] (its clock is t -
    paused), the correction added to the target position (3,) [m], whether the switching
    state is commanded and since when [s], and the controlled point's pose seen at t = 0
    (6,) [m, rad] (world frame)."""

    paused: Array
    offset: Array
    switching: Array
    since: Array
    seen0: Array


class Command(NamedTuple):
    """What the operator commands this period: the controller's target w~_d (7,) and its
    rate (7,), the intended pose of the controlled point (6,) (world frame, [m, rad]) and
    whether the switching state is commanded."""

    wd: Array
    wd_dot: Array
    intent: Array
    switching: Array


def initial_state(seen0: Array) -> OperatorState:
    """At t = 0: no pause, no correction, no switching, the point seen at `seen0`."""
    dtype = seen0.dtype
    return OperatorState(jnp.zeros((), dtype), jnp.zeros(3, dtype), jnp.asarray(False), jnp.zeros((), dtype), seen0)


def base_limit_ratio(phi: Array) -> Array:
    """max |theta_i| / limit_i over the base part's yaw joints theta_4..theta_9 of phi (12,)
    (1 at a limit, Table I)."""
    base = slice(params.N_H, params.N_PHI)
    return jnp.max(jnp.abs(phi[base]) / jnp.asarray(control.PHI_LIMITS, phi.dtype)[base])


def switch_command(switching: Array, held: Array, ratio: Array, enter: Array, exit_: Array, min_switch: Array) -> Array:
    """The operator's switching command with hysteresis: on when the limit ratio (1 at a
    joint limit) reaches `enter`; once on (for `held` s), kept while the ratio is above
    `exit_` or for `min_switch` s."""
    return jnp.where(switching, (ratio > exit_) | (held < min_switch), ratio >= enter)


def step(state: OperatorState, script: kinsim.Target, t: Array, seen: Array, ratio: Array, dt: float, gain: Array,
         limit: Array, enter: Array, exit_: Array, min_switch: Array) -> tuple[OperatorState, Command]:
    """One control period of the operator at time t [s] (module docstring): `seen` the controlled
    point's pose (6,) as the operator sees it, `ratio` the joints' limit ratio
    (`control.limit_ratio` of the encoder angles), dt [s]. Returns the next state and
    this period's command."""
    switching = switch_command(state.switching, t - state.since, ratio, enter, exit_, min_switch)
    since = jnp.where(switching & ~state.switching, t, state.since)
    moving = jnp.where(switching, 0.0, 1.0).astype(seen.dtype)
    wd, wd_dot = script.at(t - state.paused)
    intent = state.seen0 + (wd[:6] - script.w0[:6])
    error = intent[:3] - seen[:3]
    offset = jnp.clip(state.offset + dt * gain * error, -limit, limit)
    wd = wd.at[:3].add(offset)
    wd_dot = (moving * wd_dot).at[:3].add((offset - state.offset) / dt)
    nxt = OperatorState(state.paused + (1.0 - moving) * dt, offset, switching, since, state.seen0)
    return nxt, Command(wd, wd_dot, intent, switching)
