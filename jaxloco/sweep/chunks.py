"""Computing the chunks of a sweep: what every executor runs, in the driver's process or in
a worker's.

`compute_chunk(prepare(spec), index)` depends on the spec and the chunk index only. A
worker process receives a `ChunkJob` (a picklable description of the spec), rebuilds the
spec and keeps the prepared, jitted batch function per spec hash (`compute_job_chunk`).
The driver (`jaxloco.sweep.runner.run`) hands executors a `SweepWork`.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import pyarrow as pa

from jaxloco import analysis as registry
from jaxloco import info
from jaxloco.analysis import Analysis, sweep_problem
from jaxloco.errors import SpecError
from jaxloco.sweep.grid import Grid, chunk_bounds, expand
from jaxloco.sweep.schema import checked_outputs, chunk_table, table_schema
from jaxloco.sweep.spec import SweepSpec, spec_from_dict


@dataclass(frozen=True, eq=False)
class SweepWork:
    """What an executor gets from the driver: the validated spec, its hash, the float64
    flag JAX runs with, the driver's JAX CPU device count (None when JAX runs on GPUs)
    and, for the local executor, the batch function already made."""

    spec: SweepSpec
    spec_hash: str
    x64: bool
    cpu_devices: int | None = None
    batch_fn: Callable[..., Any] | None = None



# ------------------------------------------------------------- computing one chunk


@dataclass(frozen=True, eq=False)
class PreparedSweep:
    """Everything a process needs to compute any chunk of one sweep: the grid, the
    (jitted, unless executor "host") batch function, the table schema, the call shape."""

    spec: SweepSpec
    grid: Grid
    bounds: list[tuple[int, int]]
    fn: Callable[..., Any]
    host: bool
    schema: pa.Schema
    provenance: dict[str, str]
    batch: int
    sharding: Any
    x64: bool
    keys_by_seed: np.ndarray


def prepare(spec: SweepSpec, batch_fn: Callable[..., Any] | None = None) -> PreparedSweep:
    """Make (and jit) the batch function and fix the call shape of `spec`'s chunks.

    JAX must already be configured (float64 flag, CPU devices). batch_fn: the result of
    `analysis.batch_fn(fixed)` when the caller already has it.
    """
    import jax

    analysis = spec.analysis
    _check_swept(spec)
    grid = expand(spec)
    host = analysis.executor == "host"
    fn = batch_fn if batch_fn is not None else analysis.batch_fn(dict(spec.fixed))
    if not host:
        fn = jitted_batch(analysis.name, fn)
    versions = info.versions()
    provenance = {
        "analysis": analysis.name,
        "jaxloco_version": versions["jaxloco"],
        "jax_version": versions["jax"],
        "mujoco_version": versions["mujoco"],
    }
    devices = jax.devices()
    batch = rows_per_call(spec.chunk_size, grid.n_rows, len(devices), host)
    sharding = jax.sharding.NamedSharding(
        jax.sharding.Mesh(np.array(devices), ("batch",)), jax.sharding.PartitionSpec("batch")
    )
    keys_by_seed = np.stack([np.asarray(jax.random.PRNGKey(int(s)), dtype=np.uint32) for s in grid.seed_values])
    return PreparedSweep(
        spec=spec,
        grid=grid,
        bounds=chunk_bounds(grid.n_rows, spec.chunk_size),
        fn=fn,
        host=host,
        schema=table_schema(analysis, spec.hash, swept=tuple(spec.swept)),
        provenance=provenance,
        batch=batch,
        sharding=sharding,
        x64=bool(jax.config.jax_enable_x64),
        keys_by_seed=keys_by_seed,
    )


def jitted_batch(analysis_name: str, fn: Callable[..., Any]) -> Callable[..., Any]:
    """`jax.jit(fn)` for a JAX analysis' batch function, its programs kept on disk
    (`jaxloco.sim.programs.CachedJit`, keyed by `fn` by value: the analysis' code and the
    sweep's fixed values), so that a later process loads the traced program instead of
    tracing the analysis again (seconds for a rollout under `vmap`). A batch function
    holding code from outside jaxloco (a user's analysis) is traced every time."""
    from jaxloco.sim import programs

    return programs.CachedJit(fn, f"sweep batch {analysis_name}", lambda: fn)


def _check_swept(spec: SweepSpec) -> None:
    """SpecError if a swept parameter cannot be swept (e.g. a string under JAX). Spec
    validation already refuses these; this guards specs changed with `dataclasses.replace`."""
    for name in spec.swept:
        problem = sweep_problem(spec.analysis.param(name), spec.analysis.executor)
        if problem:
            raise SpecError(f"{spec.source}: params.{name}: {problem}")


def rows_per_call(chunk_size: int, n_rows: int, n_devices: int, host: bool) -> int:
    """Rows of one call of the batch function (every call of a sweep has this shape).

    A JAX analysis runs each chunk as one compiled call whose batch axis is sharded over
    every JAX device (all CPU cores, or the GPUs), its rows padded to a multiple of
    n_devices. There is no cap per call: JAX analyses emit no LAPACK call (whose batched
    CPU kernels could deadlock at ~1,000 factorizations per call; tests/test_no_lapack.py
    guards this), so `chunk_size` alone sets the call's size. A host analysis batches
    itself: one call per chunk of chunk_size rows, not padded.
    """
    if host:
        return chunk_size
    per_call = min(chunk_size, n_rows)
    return -(-per_call // n_devices) * n_devices


def call_args(
    prepared: PreparedSweep, swept: Mapping[str, np.ndarray], seed_pos: np.ndarray, rows: int
) -> tuple:
    """The arguments of `prepared.fn` for the first `rows` rows of a chunk's `grid.rows(...)`:
    as they are for a host analysis, else padded to `prepared.batch` rows and placed on the
    devices."""
    import jax

    p = prepared
    if p.host:
        return {name: v[:rows] for name, v in swept.items()}, p.keys_by_seed[seed_pos[:rows]]
    inputs = {name: _padded(_device_array(v[:rows], p.x64), p.batch) for name, v in swept.items()}
    keys = _padded(p.keys_by_seed[seed_pos[:rows]], p.batch)
    return jax.device_put((inputs, keys), p.sharding)


def compute_chunk(prepared: PreparedSweep, index: int) -> pa.Table:
    """Chunk `index` of the sweep as its Arrow table (rows bounds[index], every column)."""
    p = prepared
    analysis = p.spec.analysis
    start, stop = p.bounds[index]
    swept, seed_pos = p.grid.rows(start, stop)
    rows = stop - start
    raw = p.fn(*call_args(p, swept, seed_pos, rows))
    if p.host:
        outputs = checked_outputs(analysis, raw, rows)
    else:
        outputs = {k: v[:rows] for k, v in checked_outputs(analysis, raw, p.batch).items()}
    return chunk_table(
        p.schema,
        analysis,
        start=start,
        swept=swept,
        fixed=p.spec.fixed,
        seeds=p.grid.seed_values[seed_pos],
        outputs=outputs,
        provenance=p.provenance,
    )


# ------------------------------------------------------- chunks in another process


@dataclass(frozen=True)
class ChunkJob:
    """A sweep described for a worker process (plain data; pickles).

    spec: the resolved spec in the TOML layout (every parameter value explicit), rebuilt
    with `spec_from_dict` on the worker and checked against spec_hash. x64: the float64
    flag the driver runs with. cpu_devices: JAX CPU devices to expose in the worker
    (None: its core count; it only takes effect in a process whose JAX backend has not
    started yet). analysis: sent along only for an analysis registered at run time (a
    builtin is looked up by name on the worker).
    """

    spec: dict[str, Any]
    spec_hash: str
    x64: bool
    cpu_devices: int | None = None
    analysis: Analysis | None = None

    @classmethod
    def of(cls, spec: SweepSpec, *, x64: bool, cpu_devices: int | None = None) -> ChunkJob:
        name = spec.analysis.name
        builtin = registry.is_builtin(name)
        return cls(
            spec=spec_document(spec),
            spec_hash=spec.hash,
            x64=x64,
            cpu_devices=cpu_devices,
            analysis=None if builtin else spec.analysis,
        )

    def rebuild(self) -> SweepSpec:
        """The spec again, validated; RuntimeError if it is not the driver's (hash differs)."""
        if self.analysis is not None:
            registry.register(self.analysis)
        spec = spec_from_dict(self.spec, source=f"<sweep {self.spec_hash[:12]}>")
        if spec.hash != self.spec_hash:
            raise RuntimeError(
                f"the worker rebuilt a different sweep (hash {spec.hash[:12]}, driver {self.spec_hash[:12]});"
                " are the same jaxloco versions installed on the driver and the workers?"
            )
        return spec


def spec_document(spec: SweepSpec) -> dict[str, Any]:
    """`spec` in the TOML layout with every value explicit: `spec_from_dict` of it gives a
    spec with the same rows, chunks and hash (output and formats are the driver's business)."""
    sweep: dict[str, Any] = {
        "analysis": spec.analysis.name,
        "name": spec.name,
        "chunk_size": spec.chunk_size,
        "seeds": list(spec.seeds),
    }
    groups = [list(f) for f in spec.factors if len(f) > 1]
    if groups:
        sweep["zip"] = groups
    return {
        "sweep": sweep,
        "fixed": dict(spec.fixed),
        "params": {name: list(values) for name, values in spec.swept.items()},
    }


# per worker process: (spec hash, x64) -> prepared sweep, the most recently used last
_PREPARED: OrderedDict[tuple[str, bool], PreparedSweep] = OrderedDict()
PREPARED_PER_PROCESS = 4


def compute_job_chunk(job: ChunkJob, index: int) -> pa.Table:
    """Chunk `index` of `job`'s sweep, computed in this (worker) process.

    The first call for a sweep configures JAX as the local runner does
    (`runtime.configure(x64=job.x64, cache_dir=True)`), rebuilds the spec and makes and
    jits the batch function; later calls for the same sweep reuse it.
    """
    import jax

    from jaxloco import runtime

    key = (job.spec_hash, job.x64)
    prepared = _PREPARED.get(key)
    if prepared is None:
        runtime.configure(x64=job.x64, cache_dir=True, cpu_devices=job.cpu_devices)
        prepared = prepare(job.rebuild())
        _PREPARED[key] = prepared
        while len(_PREPARED) > PREPARED_PER_PROCESS:
            _PREPARED.popitem(last=False)
    else:
        _PREPARED.move_to_end(key)
        jax.config.update("jax_enable_x64", job.x64)  # another sweep may have changed it
    return compute_chunk(prepared, index)


def _device_array(values: np.ndarray, x64: bool) -> np.ndarray:
    if values.dtype == np.float64:
        return values if x64 else values.astype(np.float32)
    if values.dtype == np.int64:
        return values.astype(np.int32)
    return values


def _padded(values: np.ndarray, size: int) -> np.ndarray:
    """`values` with its last row repeated up to `size` rows (all chunks share one shape)."""
    missing = size - len(values)
    if missing <= 0:
        return values
    return np.concatenate([values, np.repeat(values[-1:], missing, axis=0)])


__all__ = [
    "ChunkJob",
    "PreparedSweep",
    "SweepWork",
    "call_args",
    "compute_chunk",
    "compute_job_chunk",
    "prepare",
    "rows_per_call",
    "spec_document",
]
