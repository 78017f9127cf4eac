"""What a rollout needs: a scenario (model, terrain dynamics, initial state, horizon,
records and metrics) and a controller, all pure JAX except the compiled MuJoCo model.

The controller protocol (one simulation; the backends vmap it over the batch):
    init(params, obs) -> state
    step(params, state, obs) -> (state, action)
`params` is the simulation's parameter pytree (a dict of scalars/arrays: controller
gains, thresholds, terrain and physical parameters), `obs` is what the scenario's
`observe` builds from `SimData`, `action` is the (nu,) control vector written to
MjData.ctrl for the next control period (position targets for position actuators).

A scenario may also carry an `Environment`: pure-JAX terrain dynamics run at the
control rate beside the controller (e.g. fragile footholds that drop away once their
load exceeds a threshold). It owns the mocap bodies' poses.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from functools import partial
from typing import Any

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from jaxloco.sim.data import SimData

Array = jax.Array
Params = Mapping[str, Any]

# the MuJoCo state a rollout records with `record_state` (replays): RolloutResult.states
STATE_KEYS = ("qpos", "mocap_pos", "mocap_quat", "time")

# model fields that mj_setConst reads: changing them per simulation needs the derived
# constants (subtree masses, invweight0, ...) recomputed
MASS_FIELDS = frozenset(
    {"body_mass", "body_inertia", "body_ipos", "body_iquat", "dof_armature", "body_pos", "body_quat"}
)


@dataclass(frozen=True)
class Controller:
    """A pure-JAX controller: `init(params, obs) -> state`, `step(params, state, obs) -> (state, action)`."""

    init: Callable[[Params, Any], Any]
    step: Callable[[Params, Any, Any], tuple[Any, Array]]
    name: str = "controller"


@dataclass(frozen=True)
class Environment:
    """Terrain dynamics at the control rate: `init(params, data) -> state` and
    `step(params, state, data) -> (state, mocap_pos (nmocap, 3), mocap_quat (nmocap, 4))`."""

    init: Callable[[Params, SimData], Any]
    step: Callable[[Params, Any, SimData], tuple[Any, Array, Array]]


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class InitialState:
    """Initial MuJoCo state of one simulation (world frame, SI)."""

    qpos: Array
    qvel: Array
    ctrl: Array
    mocap_pos: Array
    mocap_quat: Array


def initial_activation(model: mujoco.MjModel, ctrl: Array) -> Array:
    """Actuator activations (..., na) at rest for the controls `ctrl` (..., nu): every
    actuator with a state (a servo's setpoint filter, MJCF `timeconst`) starts at its
    control, the filter's steady state (MuJoCo starts it at 0, which would command the
    joints to zero at t = 0). Integrator-type states get the same value."""
    ids = np.nonzero(model.actuator_actnum > 0)[0]
    adr = model.actuator_actadr[ids] + model.actuator_actnum[ids] - 1
    act = jnp.zeros((*ctrl.shape[:-1], model.na), ctrl.dtype)
    return act.at[..., adr].set(ctrl[..., ids])


@dataclass(frozen=True)
class ModelField:
    """A per-simulation model field: `model.<name>[index] = value(params)`.

    index: a static numpy index into the field (e.g. `(geom_ids, 0)` for the sliding
    friction of some geoms); value(params) returns an array of the indexed shape.
    Fields in MASS_FIELDS get their derived constants recomputed (native backend
    only: the MJX backend refuses them, see `jaxloco.sim.mjx`)."""

    name: str
    index: Any
    value: Callable[[Params], Array]

    @property
    def needs_set_const(self) -> bool:
        return self.name in MASS_FIELDS


def friction_field(geom_ids: Any, key: str = "mu") -> ModelField:
    """The sliding friction of the geoms `geom_ids` set per simulation to params[key]
    (the terrain friction coefficient of a scenario)."""
    ids = np.asarray(geom_ids)
    return ModelField("geom_friction", (ids, 0), lambda p: jnp.full(ids.shape, p[key]))


def position_servo_fields(actuator_ids: Any, kp_key: str, kv_key: str) -> tuple[ModelField, ModelField]:
    """The stiffness and damping of the position servos `actuator_ids` (MuJoCo's
    position actuator: gainprm[0] = kp, biasprm[1] = -kp, biasprm[2] = -kv) set per
    simulation to params[kp_key] [N m/rad] and params[kv_key] [N m s/rad]."""
    ids = np.asarray(actuator_ids)
    n = ids.shape[0]
    bias_index = (np.concatenate([ids, ids]), np.repeat(np.array([1, 2]), n))
    return (
        ModelField("actuator_gainprm", (ids, 0), lambda p: jnp.full(n, p[kp_key])),
        ModelField("actuator_biasprm", bias_index,
                   lambda p: jnp.concatenate([jnp.full(n, -p[kp_key]), jnp.full(n, -p[kv_key])])),
    )


@dataclass(frozen=True)
class DivergenceTest:
    """When a simulation counts as diverged: a non-finite state, a joint speed above
    `qvel_limit` [m/s or rad/s] (penetration blow-ups show up as huge speeds), or
    (native backend) a MuJoCo warning (bad qpos/qvel/qacc/ctrl, contact or constraint
    buffer full)."""

    qvel_limit: float = 100.0

    def __call__(self, data: SimData) -> Array:
        finite = jnp.all(jnp.isfinite(data.qpos)) & jnp.all(jnp.isfinite(data.qvel))
        fast = jnp.max(jnp.abs(jnp.where(jnp.isfinite(data.qvel), data.qvel, 0.0))) > self.qvel_limit
        return ~finite | fast


@dataclass(frozen=True)
class Scenario:
    """A closed-loop simulation to run for a batch of parameter sets.

    model: the compiled MuJoCo model (robot + terrain), shared by every simulation.
    initial_state(params, key) -> InitialState.
    observe(data) -> obs: what the controller sees (the same in every backend).
    record(params, data, obs, ctrl_state, env_state) -> dict of signals, sampled every
        `record_every` control periods (decimation).
    summarize(params, records, final) -> dict of scalar metrics; `records` maps each
        signal to its (n_records, ...) history, `final` is a `Final`.
    horizon: number of control periods; substeps: physics steps per control period
        (control period = substeps * model.opt.timestep).
    statuses: names of the scenario's own outcome codes (metric "status", int; 0 "ok").
    """

    name: str
    model: mujoco.MjModel
    controller: Controller
    initial_state: Callable[[Params, Array], InitialState]
    observe: Callable[[SimData], Any]
    record: Callable[[Params, SimData, Any, Any, Any], dict[str, Array]]
    summarize: Callable[[Params, dict[str, Array], Final], dict[str, Array]]
    horizon: int
    substeps: int = 10
    record_every: int = 1
    environment: Environment | None = None
    model_fields: tuple[ModelField, ...] = ()
    divergence: DivergenceTest = field(default_factory=DivergenceTest)
    statuses: tuple[str, ...] = ("ok",)

    def __post_init__(self) -> None:
        if self.horizon < 1 or self.substeps < 1 or self.record_every < 1:
            raise ValueError(f"scenario {self.name}: horizon, substeps and record_every must be >= 1")
        if self.horizon % self.record_every:
            raise ValueError(
                f"scenario {self.name}: horizon ({self.horizon}) must be a multiple of record_every "
                f"({self.record_every})"
            )

    @property
    def control_dt(self) -> float:
        return float(self.substeps * self.model.opt.timestep)

    @property
    def n_records(self) -> int:
        return self.horizon // self.record_every

    @property
    def physics_steps(self) -> int:
        return self.horizon * self.substeps

    def with_(self, **changes) -> Scenario:
        return replace(self, **changes)


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class Final:
    """End of one rollout: the last data, controller and environment states, whether the
    simulation ran to the end without diverging and, if not, when it diverged [s]."""

    data: SimData
    ctrl_state: Any
    env_state: Any
    alive: Array  # () bool
    t_diverged: Array  # () [s], nan when alive


def tick_fn(scenario: Scenario) -> Callable:
    """The per-control-period computation shared by the backends (one simulation):
    (params, ctrl_state, env_state, data) -> (ctrl_state, env_state, ctrl, mocap_pos,
    mocap_quat, record, bad)."""

    env = scenario.environment

    def tick(params, cstate, estate, data: SimData):
        obs = scenario.observe(data)
        rec = scenario.record(params, data, obs, cstate, estate)
        cstate, action = scenario.controller.step(params, cstate, obs)
        if env is not None:
            estate, mocap_pos, mocap_quat = env.step(params, estate, data)
        else:
            mocap_pos, mocap_quat = data.mocap_pos, data.mocap_quat
        bad = scenario.divergence(data)
        return cstate, estate, action, mocap_pos, mocap_quat, rec, bad

    return tick


def init_fn(scenario: Scenario) -> Callable:
    """(params, data) -> (ctrl_state, env_state) for one simulation."""

    env = scenario.environment

    def init(params, data: SimData):
        cstate = scenario.controller.init(params, scenario.observe(data))
        estate = env.init(params, data) if env is not None else jnp.zeros(())
        return cstate, estate

    return init


def model_field_values(scenario: Scenario, params: Params) -> dict[str, np.ndarray]:
    """The full per-simulation arrays of every swept model field for one simulation
    (used by the MJX backend; the native backend writes through `Batch.expand`)."""
    out: dict[str, Any] = {}
    for f in scenario.model_fields:
        base = out.get(f.name, jnp.asarray(getattr(scenario.model, f.name)))
        out[f.name] = base.at[f.index].set(f.value(params))
    return out


def params_batch(defaults: Mapping[str, float], n: int, overrides: Mapping[str, Any],
                 int_keys: tuple[str, ...] = ()) -> dict[str, jax.Array]:
    """A batch of n parameter dicts for a scenario: `defaults` with `overrides` (scalars,
    or arrays of length n to vary a parameter), every leaf of shape (n,); float, except
    `int_keys`. KeyError naming any override that is not a parameter (a typo would
    otherwise silently leave the default in place)."""
    unknown = set(overrides) - set(defaults)
    if unknown:
        raise KeyError(f"params_batch: unknown parameters {sorted(unknown)}")
    return {k: jnp.broadcast_to(jnp.asarray(v, jnp.int32 if k in int_keys else jnp.result_type(float)), (n,))
            for k, v in {**defaults, **overrides}.items()}


def first_row(batch: Mapping[str, Any], dtype: Any) -> dict[str, jax.Array]:
    """The first simulation's params of a batch (`params_batch`): float leaves cast to
    `dtype` (a tune objective's: forward-mode tangents need one float type throughout),
    integer and boolean leaves kept."""
    return {k: jnp.asarray(v[0], dtype) if jnp.issubdtype(v.dtype, jnp.floating) else jnp.asarray(v[0])
            for k, v in batch.items()}


def seed_jitter(keys: Any, n: int) -> np.ndarray:
    """(B, n) numbers uniform in [-1, 1) drawn from the rows' PRNG keys (B, 2): the
    perturbations of a "perturbed trial" (start pose, friction, ...), one draw per key.
    Pure: the same keys give the same numbers."""
    return np.asarray(_uniform_per_key(jnp.asarray(np.asarray(keys, np.uint32)), n))


@partial(jax.jit, static_argnums=1)
def _uniform_per_key(keys: jax.Array, n: int) -> jax.Array:
    """One jitted program per (batch, n): run eagerly, the vmapped draw lowered again on
    every call (every chunk of a sweep)."""
    return jax.vmap(lambda k: jax.random.uniform(k, (n,), minval=-1.0, maxval=1.0))(keys)


def per_scenario(cache: dict[int, Any], scenario: Any, make: Callable[[], Any]) -> Any:
    """`cache[id(scenario)]`, made by `make()` on a miss; the entry is dropped when the
    scenario is garbage-collected (compiled functions live as long as their scenario)."""
    key = id(scenario)
    hit = cache.get(key)
    if hit is None or hit[0]() is not scenario:
        hit = (weakref.ref(scenario), make())
        cache[key] = hit
        weakref.finalize(scenario, cache.pop, key, None)
    return hit[1]
