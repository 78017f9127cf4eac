"""The one rollout API: a scenario, a batch of parameter sets, a backend -> per-simulation
recorded signals (decimated), summary metrics and a status.

    result = rollout(scenario, params, backend="native")     # or backend="mjx"
    result.metrics["max_roll"], result.records["rpy"], result.status

`params` is a dict of arrays whose first axis is the batch (every simulation its own
controller gains, thresholds, terrain and physical parameters); `stack_params` builds it
from a list of per-simulation dicts. PRNG keys (for random terrain and perturbations)
come from `seeds` (one per simulation, default 0..B-1); each simulation's key is also
passed to the scenario as `params["key"]` (controllers and environments draw from it).
`record_state=True` adds every recorded period's MuJoCo state (qpos, mocap poses, time)
to the result (`RolloutResult.states`), for replays, on either backend.

`Simulator` is what a simulated sweep analysis runs its rollouts on
(`jaxloco.analysis`): the framework makes it (backend, threads, state recording) and the
analysis only calls `simulator.run(scenario, params)`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco.sim.backend import Backend, resolve
from jaxloco.sim.scenario import STATE_KEYS, Final, Scenario, per_scenario

DIVERGED = "diverged"
_STATE_PREFIX = "_state_"


@dataclass(frozen=True)
class RolloutResult:
    """Outputs of a batched rollout (numpy, batch axis first).

    records: signal -> (B, n_records, ...), sampled every `record_every` control periods
    from t = 0 (`times`). metrics: name -> (B,). status: (B,) strings, "ok", one of the
    scenario's statuses, or "diverged". t_diverged: (B,) [s], nan where none diverged.
    states (with `record_state`): STATE_KEYS -> (B, n_records, ...) MuJoCo states at the
    recorded periods (qpos, mocap_pos, mocap_quat, time [s]), else None."""

    records: dict[str, np.ndarray]
    metrics: dict[str, np.ndarray]
    status: np.ndarray
    t_diverged: np.ndarray
    times: np.ndarray
    final: Final
    backend: str
    timing: dict[str, float] = field(default_factory=dict)
    states: dict[str, np.ndarray] | None = None

    @property
    def n(self) -> int:
        return int(self.status.shape[0])

    @property
    def diverged(self) -> np.ndarray:
        return self.status == DIVERGED

    def row(self, i: int) -> dict[str, Any]:
        """Metrics and status of simulation i as plain Python values."""
        out = {k: v[i].item() for k, v in self.metrics.items()}
        out["status"] = str(self.status[i])
        out["t_diverged"] = float(self.t_diverged[i])
        return out


def stack_params(rows: Sequence[Mapping[str, Any]]) -> dict[str, jax.Array]:
    """A batched params dict from per-simulation dicts with the same keys."""
    if not rows:
        raise ValueError("stack_params: no parameter sets")
    keys = set(rows[0])
    for i, r in enumerate(rows):
        if set(r) != keys:
            raise ValueError(f"stack_params: row {i} has keys {sorted(r)}, row 0 has {sorted(keys)}")
    return {k: jnp.stack([jnp.asarray(r[k]) for r in rows]) for k in rows[0]}


def batch_size(params: Mapping[str, Any]) -> int:
    """The common leading dimension of every leaf of `params` (ValueError otherwise)."""
    sizes = {np.shape(x)[0] if np.ndim(x) else None for x in jax.tree_util.tree_leaves(params)}
    if len(sizes) != 1 or None in sizes:
        raise ValueError(f"params: every leaf needs the same leading batch dimension, got {sorted(map(str, sizes))}")
    return sizes.pop()


def rollout(
    scenario: Scenario,
    params: Mapping[str, Any],
    *,
    seeds: Sequence[int] | np.ndarray | None = None,
    backend: Backend = "native",
    nthread: int = 0,
    progress: bool = False,
    record_state: bool = False,
) -> RolloutResult:
    """Run `scenario` closed loop for every parameter set of the batch `params`.

    backend "native" (mujoco.batch on `nthread` threads, 0 = all cores; the CPU
    workhorse) or "mjx" (one jitted scan, sharded over the JAX devices; differentiable:
    see `jaxloco.sim.mjx`). record_state: also return the recorded periods' MuJoCo
    states (`RolloutResult.states`)."""
    n = batch_size(params)
    if seeds is None:
        seeds = np.arange(n)
    seeds = np.asarray(seeds)
    if seeds.shape != (n,):
        raise ValueError(f"seeds: expected {n} seeds, got shape {seeds.shape}")
    params = {k: jnp.asarray(v) for k, v in params.items()}
    if "key" in params:  # keys given by the caller (e.g. a sweep row's seed)
        keys = params["key"]
    else:
        keys = jnp.stack([jax.random.PRNGKey(int(s)) for s in seeds])
        params["key"] = keys  # the simulation's PRNG key, for controllers and environments too
    if backend not in ("native", "mjx"):
        raise ValueError(f"backend: expected 'native' or 'mjx', got {backend!r}")
    if backend == "native":
        from jaxloco.sim import native

        out = native.run(scenario, params, keys, nthread=nthread, progress=progress, record_state=record_state)
        states = out["states"]
    else:
        from jaxloco.sim import mjx

        out = mjx.run(recording_scenario(scenario) if record_state else scenario, params, keys)
        states = {key: np.asarray(out["records"].pop(_STATE_PREFIX + key)) for key in STATE_KEYS} \
            if record_state else None
    return _result(scenario, out, backend, states)


@dataclass(frozen=True)
class Run:
    """One rollout a `Simulator` ran while recording states: the scenario, its batched
    params and the result (with `states`)."""

    scenario: Scenario
    params: Mapping[str, Any]
    result: RolloutResult


@dataclass(eq=False)
class Simulator:
    """Where a simulated analysis runs its rollouts (`jaxloco.analysis`), made and held by
    the framework: the backend, the physics threads (native backend; 0 = all cores) and,
    for a replay, `record_state` (every run is then kept in `runs`, states included)."""

    backend: Backend = "native"
    nthread: int = 0
    record_state: bool = False
    runs: list[Run] = field(default_factory=list)

    def run(self, scenario: Scenario, params: Mapping[str, Any]) -> RolloutResult:
        """`rollout(scenario, params)` on this simulator's backend and threads."""
        result = rollout(scenario, params, backend=self.backend, nthread=self.nthread,
                         record_state=self.record_state)
        if self.record_state:
            self.runs.append(Run(scenario, dict(params), result))
        return result


def simulator_for(values: Mapping[str, Any], record_state: bool = False) -> Simulator:
    """The simulator of an analysis' fixed values: its `backend` parameter (default
    "native"; "auto" resolved, `jaxloco.sim.backend`) and `nthread` (default 0: all
    cores)."""
    return Simulator(backend=resolve(str(values.get("backend", "native"))), nthread=int(values.get("nthread", 0)),
                     record_state=record_state)


_RECORDING: dict[int, Any] = {}


def recording_scenario(scenario: Scenario) -> Scenario:
    """`scenario` with qpos, mocap poses and time added to its records, for MJX (the
    native backend copies them from its batch instead); one object per scenario, so that
    repeated replays reuse its compiled functions."""
    record = scenario.record

    def recorded(p, data, obs, ctrl_state, env_state):
        out = dict(record(p, data, obs, ctrl_state, env_state))
        out.update({_STATE_PREFIX + key: getattr(data, key) for key in STATE_KEYS})
        return out

    return per_scenario(_RECORDING, scenario, lambda: scenario.with_(record=recorded))


def _result(scenario: Scenario, out: dict[str, Any], backend: str,
            states: dict[str, np.ndarray] | None = None) -> RolloutResult:
    metrics = out["metrics"]
    codes = np.asarray(metrics.get("status", np.zeros(len(out["alive"]), int)), int)
    names = np.asarray(scenario.statuses, dtype=object)
    status = np.where(out["alive"], names[np.clip(codes, 0, len(names) - 1)], DIVERGED).astype(str)
    times = np.arange(scenario.n_records) * scenario.record_every * scenario.control_dt
    return RolloutResult(
        records=out["records"],
        metrics=metrics,
        status=status,
        t_diverged=np.asarray(out["t_diverged"], float),
        times=times,
        final=out["final"],
        backend=backend,
        timing=out.get("timing", {}),
        states=states,
    )
