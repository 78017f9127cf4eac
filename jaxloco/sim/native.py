"""The native backend: MuJoCo's multithreaded `mujoco.batch.Batch` steps the physics in
C; the scenario's controller, observation, environment and records run as one jitted,
vmapped JAX function called once per control period.

Per-simulation model fields are written through `Batch.expand`; fields that
`mj_setConst` reads (masses, inertias, body poses) are followed by `Batch.set_const()`
so that derived constants (subtree masses, invweight0, ...) are recomputed. Results
are bit-identical for any number of threads (the batch's guarantee; the JAX part does
not depend on it).

Divergence: a simulation whose state is non-finite, whose joint speeds exceed the
scenario's limit, that raises a MuJoCo error or whose warning counters rise (bad
qpos/qvel/qacc/ctrl, contact or constraint buffer full: MuJoCo would otherwise reset it
silently) is stopped; the others go on.
"""

from __future__ import annotations

import time
from typing import Any

import jax
import jax.numpy as jnp
import mujoco
import mujoco.batch
import numpy as np

from jaxloco.batching import vmap_in_blocks
from jaxloco.sim import data as simdata
from jaxloco.sim import programs
from jaxloco.sim.scenario import STATE_KEYS, Final, Scenario, init_fn, initial_activation, per_scenario, tick_fn

# warnings that mean the simulation can no longer be trusted
DIVERGENCE_WARNINGS = (
    mujoco.mjtWarning.mjWARN_BADQPOS,
    mujoco.mjtWarning.mjWARN_BADQVEL,
    mujoco.mjtWarning.mjWARN_BADQACC,
    mujoco.mjtWarning.mjWARN_BADCTRL,
    mujoco.mjtWarning.mjWARN_CONTACTFULL,
    mujoco.mjtWarning.mjWARN_CNSTRFULL,
)
# The controller's and environment's init run over the batch in vmapped blocks of this
# many rows (`batching.vmap_in_blocks`), so that an init with large intermediates (the
# leg-grope walk plans its 16 cycles at about 3 MB per row) needs memory for one block,
# not for the whole batch. Default (ours).
INIT_ROWS = 256


def make_batch(scenario: Scenario, params: Any, nsim: int, nthread: int = 0) -> mujoco.batch.Batch:
    """A Batch of the scenario's model with the per-simulation model fields of `params`
    (a pytree whose leaves have a leading axis of nsim) written in."""
    batch = mujoco.batch.Batch(scenario.model, nsim, nthread)
    set_const = False
    for f in scenario.model_fields:
        values = np.asarray(jax.vmap(f.value)(params))
        arr = batch.expand(f.name)
        index = f.index if isinstance(f.index, tuple) else (f.index,)
        arr[(slice(None), *index)] = values
        set_const |= f.needs_set_const
    if set_const:
        batch.set_const()
    return batch


def run(
    scenario: Scenario,
    params: Any,
    keys: jax.Array,
    *,
    nthread: int = 0,
    progress: bool = False,
    record_state: bool = False,
    init_rows: int | None = INIT_ROWS,
) -> dict[str, Any]:
    """Run the scenario for a batch of parameter sets (leaves with leading axis B) and
    PRNG keys (B, 2). Returns a dict with records (B, R, ...), metrics (B,), final
    (batched `Final`) and timings, and with `record_state` the MuJoCo states at the
    recorded periods ("states": STATE_KEYS -> (B, R, ...), copied from the batch on the
    host: the compiled tick is the same as without); `jaxloco.sim.rollout.rollout` wraps it.
    init_rows: the controller's init runs in blocks of this many rows (None: all at once;
    `INIT_ROWS`)."""
    if init_rows is not None and (int(init_rows) != init_rows or init_rows < 1):
        raise ValueError(f"init_rows must be a positive int or None, got {init_rows!r}")
    nsim = int(keys.shape[0])
    t0 = time.perf_counter()
    batch = make_batch(scenario, params, nsim, nthread)
    bound = simdata.bind_native(batch)  # before any call: outputs bound later read zero until the next call
    # the inputs written every period, bound once (attribute access re-binds each time)
    inputs = {name: batch.bind(name) for name in ("ctrl", "mocap_pos", "mocap_quat")}
    jitted = _jitted_inits(scenario, init_rows)
    init_state = jitted["initial_state"](params, keys)
    batch.reset(stage=mujoco.mjtStage.mjSTAGE_NONE)
    for name in ("qpos", "qvel", "ctrl", "mocap_pos", "mocap_quat"):
        batch.bind(name)[...] = np.asarray(getattr(init_state, name))
    if scenario.model.na:
        batch.bind("act")[...] = np.asarray(initial_activation(scenario.model, jnp.asarray(init_state.ctrl)))
    batch.forward()
    cstate, estate = jitted["init"](params, simdata.from_native(bound))
    layout = _layout(bound)
    flat = _pack(bound, layout, nsim)
    tick = _jitted_tick(scenario, layout, (params, cstate, estate, flat))
    nu, nmocap = scenario.model.nu, scenario.model.nmocap
    warn_idx = np.array([int(w) for w in DIVERGENCE_WARNINGS])
    warnings0 = batch.warning[:, warn_idx, 1].sum(axis=1).copy()

    alive = np.ones(nsim, bool)
    t_div = np.full(nsim, np.nan)
    records: dict[str, np.ndarray] = {}
    states: dict[str, np.ndarray] = {}
    bar = _progress(scenario.horizon, enabled=progress)
    t_setup = time.perf_counter() - t0
    try:
        for t in range(scenario.horizon):
            # one packed array in, one packed array out: per-call overhead is per array
            flat = _pack(bound, layout, nsim)
            cstate, estate, out, rec = tick(params, cstate, estate, flat)
            if t % scenario.record_every == 0:
                _store(records, rec, t // scenario.record_every, scenario.n_records)
                if record_state:
                    _store(states, {k: bound[k] for k in STATE_KEYS}, t // scenario.record_every, scenario.n_records)
            out = np.asarray(out)
            ctrl, mocap_pos = out[:, :nu], out[:, nu:nu + 3 * nmocap].reshape(nsim, nmocap, 3)
            mocap_quat = out[:, nu + 3 * nmocap:nu + 7 * nmocap].reshape(nsim, nmocap, 4)
            newly = (out[:, -1] > 0.5) & alive
            _mark(alive, t_div, newly, bound["time"])
            ids = np.flatnonzero(alive)
            if not ids.size:
                break
            if ids.size == nsim:
                inputs["ctrl"][...] = ctrl
                inputs["mocap_pos"][...] = mocap_pos
                inputs["mocap_quat"][...] = mocap_quat
            else:
                inputs["ctrl"][ids] = ctrl[ids]
                inputs["mocap_pos"][ids] = mocap_pos[ids]
                inputs["mocap_quat"][ids] = mocap_quat[ids]
            _step(batch, ids, scenario.substeps, alive, t_div)
            warned = (batch.warning[:, warn_idx, 1].sum(axis=1) > warnings0) & alive
            _mark(alive, t_div, warned, batch.time)
            if bar is not None:
                bar.advance(bar.task_ids[0])
    finally:
        if bar is not None:
            bar.stop()
    for t_rest in range(t + 1, scenario.horizon):  # only after everything diverged
        if t_rest % scenario.record_every == 0:
            _store(records, rec, t_rest // scenario.record_every, scenario.n_records)
            if record_state:
                _store(states, {k: bound[k] for k in STATE_KEYS}, t_rest // scenario.record_every,
                       scenario.n_records)
    t_loop = time.perf_counter() - t0 - t_setup
    final_data = simdata.from_native(bound)
    final = Final(final_data, cstate, estate, jnp.asarray(alive), jnp.asarray(t_div))
    metrics = jitted["summarize"](params, records, final)
    return {
        "records": records,
        "states": states if record_state else None,
        "metrics": {k: np.asarray(v) for k, v in metrics.items()},
        "final": final,
        "alive": alive,
        "t_diverged": t_div,
        "timing": {"setup_s": t_setup, "loop_s": t_loop, "total_s": time.perf_counter() - t0},
    }


_TICKS: dict[int, Any] = {}
_INITS: dict[int, Any] = {}


def _jitted_inits(scenario: Scenario, init_rows: int | None) -> dict[str, Any]:
    """The jitted, vmapped initial_state, controller/environment init (in blocks of
    `init_rows` rows) and summarize of a scenario, kept as long as the scenario lives so
    repeated rollouts do not re-trace them, and on disk (`programs.CachedJit`) so that a
    later process does not either."""
    jitted = per_scenario(_INITS, scenario, lambda: {
        "initial_state": programs.CachedJit(scenario, "native initial_state",
                                            lambda: jax.vmap(scenario.initial_state)),
        "summarize": programs.CachedJit(scenario, "native summarize", lambda: jax.vmap(scenario.summarize)),
    })
    key = ("init", init_rows)
    if key not in jitted:
        jitted[key] = programs.CachedJit(scenario, f"native init rows={init_rows}",
                                         lambda: vmap_in_blocks(init_fn(scenario), block=init_rows))
    return {**jitted, "init": jitted[key]}


def _layout(bound: dict[str, np.ndarray]) -> tuple[tuple[str, int, tuple[int, ...]], ...]:
    """(field, width, per-simulation shape) of each SimData field in the packed array."""
    return tuple((name, int(np.prod(bound[name].shape[1:], dtype=int)), bound[name].shape[1:])
                 for name in simdata.FIELDS)


def _pack(bound: dict[str, np.ndarray], layout, nsim: int) -> np.ndarray:
    """The SimData fields of the batch in one (nsim, width) array, in `layout`'s order."""
    return np.concatenate([bound[name].reshape(nsim, -1) for name, _, _ in layout], axis=1)


def _unpack(flat, layout) -> simdata.SimData:
    out, start = {}, 0
    for name, width, shape in layout:
        out[name] = flat[start:start + width].reshape(shape)
        start += width
    out["site_xmat"] = out["site_xmat"].reshape(-1, 3, 3)
    return simdata.SimData(**out)


def _jitted_tick(scenario: Scenario, layout, args: tuple):
    """The jitted, vmapped tick of a scenario on the packed data, for arguments shaped
    like `args` = (params, ctrl_state, env_state, packed data); it returns (ctrl_state,
    env_state, [ctrl | mocap_pos | mocap_quat | bad], record). A `programs.CachedJit` per
    scenario object and layout (reused across calls, and on disk for later processes),
    resolved once per rollout, so the periods do not read the call signature."""
    ticks = per_scenario(_TICKS, scenario, dict)
    if layout not in ticks:
        def make():
            tick = tick_fn(scenario)

            def packed(params, cstate, estate, flat):
                data = _unpack(flat, layout)
                cstate, estate, ctrl, mocap_pos, mocap_quat, rec, bad = tick(params, cstate, estate, data)
                dtype = flat.dtype
                out = jnp.concatenate([ctrl.astype(dtype), mocap_pos.reshape(-1).astype(dtype),
                                       mocap_quat.reshape(-1).astype(dtype), bad.astype(dtype)[None]])
                return cstate, estate, out, rec

            return jax.vmap(packed)

        ticks[layout] = programs.CachedJit(scenario, f"native tick {layout}", make)
    return ticks[layout].resolve(*args)


def _step(batch: mujoco.batch.Batch, ids: np.ndarray, nstep: int, alive: np.ndarray, t_div: np.ndarray) -> None:
    """Step the simulations `ids`; those that raise a MuJoCo error are marked diverged."""
    try:
        batch.step(ids=None if ids.size == batch.nsim else ids, nstep=nstep)
    except mujoco.batch.SimulationError as exc:
        failed = np.zeros_like(alive)
        failed[exc.ids] = True
        _mark(alive, t_div, failed, batch.time)


def _mark(alive: np.ndarray, t_div: np.ndarray, newly: np.ndarray, when: Any) -> None:
    if newly.any():
        t_div[newly] = np.asarray(when)[newly]
        alive[newly] = False


def _store(records: dict[str, np.ndarray], rec: dict[str, Any], index: int, n: int) -> None:
    for name, value in rec.items():
        value = np.asarray(value)
        if name not in records:
            records[name] = np.zeros((value.shape[0], n, *value.shape[1:]), value.dtype)
        records[name][:, index] = value


def _progress(total: int, enabled: bool):
    if not enabled:
        return None
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    bar = Progress(TextColumn("simulating"), BarColumn(), TextColumn("{task.completed}/{task.total} periods"),
                   TimeRemainingColumn(), transient=True)
    bar.add_task("sim", total=total)
    bar.start()
    return bar
