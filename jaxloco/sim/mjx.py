"""The MJX backend: the whole closed-loop rollout (controller, environment, physics,
records, metrics) of one simulation is a pure JAX function built from `lax.scan`s; the
batch is `jax.vmap` of it, jitted once and sharded over every JAX device (all CPU cores
with `jaxloco.runtime.configure`, or the GPUs).

Per-simulation model fields are built inside the vmapped function from the
simulation's parameters (`Model.tree_replace`), so the batched model carries a batch
axis exactly on the swept fields (the "in_axes tree" of a batched MJX model) and every
other field stays shared. Fields that MuJoCo derives at compile time from masses and
inertias (`body_subtreemass`, `*_invweight0`) would go stale, so mass-like fields
(`scenario.MASS_FIELDS`) are refused here: sweep them with the native backend.

Gradients (`rollout_fn` is differentiable end to end):
  * forward mode (`jax.jacfwd`, `jax.jvp`) works for any solver settings and is the
    right tool for a few parameters;
  * reverse mode (`jax.grad`) only works when the model's constraint solver runs a
    fixed number of iterations: set `model.opt.iterations = 1` (MJX's solver is a
    `while_loop`, which JAX cannot reverse-differentiate otherwise);
  * use float64 for gradient checks; contacts make the dynamics piecewise smooth, so
    finite differences need steps well inside one contact mode. Through the leg-grope
    robot's earlier stiff, nearly hard toe contacts (solref 0.004, solimp 0.99)
    forward-mode and central differences disagreed over 40 ms (tests/test_sim.py
    checks the contact-free case): tune through contacts with soft contact parameters
    or a smoothed objective.

MJX has no no-slip post-solver: a model with `opt.noslip_iterations > 0` (the leg-grope
robot) runs without it here, with a warning, and its loaded contacts creep a little as
MuJoCo's soft friction does.
"""

from __future__ import annotations

import contextlib
import io
import time
import warnings
from typing import Any, Callable

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

with contextlib.redirect_stdout(io.StringIO()):  # mujoco.mjx prints "Failed to import warp" without NVIDIA Warp
    from mujoco import mjx

from jaxloco.batching import vmap_in_blocks
from jaxloco.sim import backend, programs
from jaxloco.sim import data as simdata
from jaxloco.sim.scenario import Final, Scenario, init_fn, initial_activation, model_field_values, per_scenario, tick_fn


def check_supported(scenario: Scenario) -> None:
    """Raise ValueError (one line) for what this backend cannot do."""
    stale = sorted({f.name for f in scenario.model_fields if f.needs_set_const})
    if stale:
        raise ValueError(
            f"mjx backend: per-simulation {', '.join(stale)} would leave derived constants stale; "
            "use the native backend for mass/inertia sweeps"
        )
    if scenario.model.opt.noslip_iterations > 0:
        warnings.warn(
            f"mjx backend: {scenario.name} uses MuJoCo's no-slip solver "
            f"(noslip_iterations={scenario.model.opt.noslip_iterations}), which MJX does not have; "
            "its contacts will creep more than on the native backend",
            stacklevel=3,
        )


def rollout_fn(scenario: Scenario):
    """`run(params, key) -> (records, metrics, final)` for ONE simulation, pure JAX:
    vmap, jit, shard or differentiate it. records map each signal to (n_records, ...).

    The program holds MuJoCo's forward dynamics once: the rollout is one loop over
    control periods k = 0..N (N = n_records x record_every), each first the physics of
    period k - 1 (`physics`: substeps x `mjx.step`, written as `mjx.forward` and then
    the integrator, from the controls written into the data) and then the control of
    period k (`control`: the controller's tick and its record). In iteration 0 the
    physics is a step of zero length that keeps the solver's warm start, which computes
    what `mjx.forward` computes and leaves the state as it was, and the control first
    starts the controller (`init`); in the last one (k = N) the control is skipped. That
    computes what `mjx.forward`, `init` and then N x (tick, `mjx.step` x substeps)
    compute (`tests/test_sim.py` checks it against that sequence written out), without
    a second copy of the forward dynamics in the program for the initial `mjx.forward`
    (`docs/simulation.md`, "One forward dynamics per program": a third less to compile).
    The switches are `lax.cond`s on the loop index, which is the same for every
    simulation of a batch, so under `vmap` they stay branches and the branch not taken
    costs nothing."""
    check_supported(scenario)
    mx = mjx.put_model(scenario.model)
    tick = jax.jit(tick_fn(scenario))  # jitted: each is traced once, for the carry's shapes and in the loop
    init = jax.jit(init_fn(scenario))
    integrate = _integrator(scenario.model)
    substeps, every, n_records = scenario.substeps, scenario.record_every, scenario.n_records
    n_periods = n_records * every

    def run(params, key):
        m = mx.tree_replace(model_field_values(scenario, params)) if scenario.model_fields else mx
        s0 = scenario.initial_state(params, key)
        d = mjx.make_data(m)
        dtype = d.qpos.dtype
        d = d.replace(
            qpos=s0.qpos.astype(dtype),
            qvel=s0.qvel.astype(dtype),
            ctrl=s0.ctrl.astype(dtype),
            mocap_pos=s0.mocap_pos.astype(dtype),
            mocap_quat=s0.mocap_quat.astype(dtype),
        )
        if scenario.model.na:
            d = d.replace(act=initial_activation(scenario.model, s0.ctrl.astype(dtype)))
        cstate, estate = _placeholder(jax.eval_shape(init, params, simdata.from_mjx(d)))
        tick_out = jax.eval_shape(tick, params, cstate, estate, simdata.from_mjx(d))

        def substep(first: jax.Array, x):
            """One physics step (`mjx.step`: `mjx.forward`, then the integrator); in
            iteration 0 the forward dynamics alone, as a step of zero length that keeps
            the solver's warm start (so repeating it changes nothing). The data keep
            `mjx.make_data`'s dtypes (`mjx.forward` writes some index fields as int64)."""
            y = mjx.forward(m, x)
            y = integrate(m.tree_replace({"opt.timestep": jnp.where(first, 0.0, m.opt.timestep)}), y)
            y = y.replace(qacc_warmstart=jnp.where(first, x.qacc_warmstart, y.qacc_warmstart))
            return jax.tree_util.tree_map(lambda new, old: new.astype(old.dtype), y, x)

        def physics(k, d, alive):
            """The physics of period k - 1 (from the controls its control wrote into d);
            in iteration 0 the initial forward dynamics."""
            advance = lambda d: jax.lax.fori_loop(0, substeps, lambda _, x: substep(k == 0, x), d)
            d1 = jax.lax.cond(k > n_periods, lambda x: x, advance, d)
            return jax.tree_util.tree_map(lambda new, old: jnp.where(alive, new, old), d1, d)

        def control(k, d, cstate, estate, alive, t_div):
            """The control of period k (the controller started in iteration 0); skipped in
            the last iteration (k = N)."""
            data = simdata.from_mjx(d)
            cstate, estate = jax.lax.cond(k == 0, lambda: init(params, data), lambda: (cstate, estate))
            idle = lambda: (cstate, estate, *_placeholder(tick_out[2:]))  # no action, no record, not bad
            cstate, estate, ctrl, mocap_pos, mocap_quat, rec, bad = jax.lax.cond(
                k < n_periods, lambda: tick(params, cstate, estate, data), idle)
            t_div = jnp.where(alive & bad, data.time, t_div)
            alive = alive & ~bad
            apply = alive & (k < n_periods)
            act = [jnp.where(apply, new.astype(dtype), old) for new, old in
                   ((ctrl, d.ctrl), (mocap_pos, d.mocap_pos), (mocap_quat, d.mocap_quat))]
            d = d.replace(ctrl=act[0], mocap_pos=act[1], mocap_quat=act[2])
            return d, cstate, estate, alive, t_div, rec

        def period(carry, k):
            d, cstate, estate, alive, t_div = carry
            d = physics(k, d, alive)
            d, cstate, estate, alive, t_div, rec = control(k, d, cstate, estate, alive, t_div)
            return (d, cstate, estate, alive, t_div), rec

        def block(carry, b):
            carry, recs = jax.lax.scan(period, carry, b * every + jnp.arange(every))
            return carry, jax.tree_util.tree_map(lambda r: r[0], recs)

        carry0 = _like_key((d, cstate, estate, jnp.asarray(True), jnp.asarray(jnp.nan, dtype)), key)
        (d, cstate, estate, alive, t_div), records = jax.lax.scan(block, carry0, jnp.arange(n_records + 1))
        records = jax.tree_util.tree_map(lambda r: r[:-1], records)  # the last block: the final physics
        final = Final(simdata.from_mjx(d), cstate, estate, alive, t_div)
        return records, scenario.summarize(params, records, final), final

    return run


def _integrator(model) -> Callable:
    """MJX's integrator of `model.opt.integrator`, the second half of `mjx.step`
    (`mjx.step` = `mjx.forward`, then this)."""
    integrators = {mujoco.mjtIntegrator.mjINT_EULER: mjx.euler, mujoco.mjtIntegrator.mjINT_RK4: mjx.rungekutta4,
                   mujoco.mjtIntegrator.mjINT_IMPLICITFAST: mjx.implicit}
    kind = mujoco.mjtIntegrator(model.opt.integrator)
    if kind not in integrators:
        raise ValueError(f"mjx backend: MJX has no {kind.name} integrator (use Euler, RK4 or implicitfast)")
    return integrators[kind]


def _placeholder(shapes: Any) -> Any:
    """Zeros of the shapes and dtypes of `jax.eval_shape`'s result."""
    return jax.tree_util.tree_map(lambda s: jnp.zeros(s.shape, s.dtype), shapes)


def _like_key(tree: Any, key: jax.Array) -> Any:
    """`tree` unchanged in value, every leaf made to depend on `key` (a `where` on a
    predicate that is always false), so that under `jax.vmap` every leaf carries the
    batch axis whenever the key does. A scan whose initial carry is partly unbatched is
    batched again once its body makes the carry batched (JAX's fixed point over the
    carry), and nested scans multiply that: the rollout's trace took about twice as long."""
    never = jnp.any(jax.random.key_data(key) != jax.random.key_data(key)) if jnp.issubdtype(
        key.dtype, jax.dtypes.prng_key) else jnp.any(key != key)
    return jax.tree_util.tree_map(lambda x: jnp.where(never, x, x), tree)


_COMPILED: dict[int, Any] = {}

CPU_ROWS_PER_DEVICE = 4
"""Rows each CPU device simulates at once. jaxlib 0.10.2's batched LAPACK Cholesky (MJX
factorizes the mass matrix and the constraint solver's Hessian with it) hung XLA's CPU
thread pool from 8 OCTOPUS rows per device on (docs/simulation.md, "MJX on CPU runs
large batches block by block"), so on CPU a larger batch runs as a `lax.map` over
vmapped blocks of this many rows per device (`batching.vmap_in_blocks`)."""

ACCELERATOR_ROWS_PER_DEVICE = 8192
"""Rows each GPU or TPU simulates at once, default (ours): bounds the memory of one
block (a controller's init can be large: the leg-grope walk plans 16 cycles per row,
3 MB each) at a batch that GPUs run well (MuJoCo's maintainers report a Go1 scene at
about 3.0M steps/s at batch 8,192 on one GPU). Not yet measured on one here."""


def block_size(n_devices: int, platform: str | None = None, rows_per_device: int | None = None) -> int:
    """Rows per vmapped block for a batch sharded over `n_devices` on `platform` (JAX's
    default when None): `rows_per_device` per device, by default `CPU_ROWS_PER_DEVICE`
    on CPU and `ACCELERATOR_ROWS_PER_DEVICE` on a GPU or TPU."""
    if rows_per_device is None:
        platform = backend.platform() if platform is None else platform
        rows_per_device = CPU_ROWS_PER_DEVICE if platform == "cpu" else ACCELERATOR_ROWS_PER_DEVICE
    if int(rows_per_device) != rows_per_device or rows_per_device < 1:
        raise ValueError(f"rows_per_device must be a positive int, got {rows_per_device!r}")
    return int(rows_per_device) * n_devices


def program(scenario: Scenario, block: int | None) -> programs.CachedJit:
    """The jitted batched rollout of `rollout_fn`, one vmap (`block` None) or a `lax.map`
    over vmapped blocks of `block` rows, from the program cache (`jaxloco.sim.programs`:
    a later process loads it instead of tracing it) where the scenario can be keyed there.
    Kept as long as the scenario lives."""
    fns = per_scenario(_COMPILED, scenario, dict)
    if block not in fns:
        fns[block] = programs.CachedJit(scenario, f"mjx.run block={block}",
                                        lambda: vmap_in_blocks(rollout_fn(scenario), block=block))
    return fns[block]


def run(scenario: Scenario, params: Any, keys: jax.Array, *, shard: bool = True,
        rows_per_device: int | None = None) -> dict[str, Any]:
    """Run the scenario for a batch (leaves with leading axis B); the batch is padded to
    a multiple of the device count and sharded over the devices when `shard`. A batch of
    more than `rows_per_device` rows per device (`block_size`: 4 on CPU, 8,192 on an
    accelerator by default) runs block by block, padded to whole blocks."""
    t0 = time.perf_counter()
    nsim = int(keys.shape[0])
    devices = jax.devices()
    n_dev = len(devices) if shard else 1
    block = block_size(n_dev, rows_per_device=rows_per_device)
    blocks = block if nsim > block else None
    multiple = n_dev if nsim <= block else block
    padded = -(-nsim // multiple) * multiple
    pad = lambda x: jnp.concatenate([x, jnp.repeat(x[-1:], padded - nsim, axis=0)]) if padded > nsim else x
    inputs = jax.tree_util.tree_map(lambda x: pad(jnp.asarray(x)), (params, keys))
    if n_dev > 1:
        mesh = jax.sharding.Mesh(np.array(devices), ("batch",))
        inputs = jax.device_put(inputs, jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec("batch")))
    records, metrics, final = program(scenario, blocks)(*inputs)
    cut = lambda x: np.asarray(x)[:nsim]
    records = {k: cut(v) for k, v in records.items()}
    metrics = {k: cut(v) for k, v in metrics.items()}
    final = jax.tree_util.tree_map(lambda x: jnp.asarray(x)[:nsim], final)
    alive = np.asarray(final.alive)
    return {
        "records": records,
        "metrics": metrics,
        "final": final,
        "alive": alive,
        "t_diverged": np.asarray(final.t_diverged, float),
        "timing": {"total_s": time.perf_counter() - t0},
    }
