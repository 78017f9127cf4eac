"""Running a sweep: grid -> equally shaped chunks -> one jitted batch call each -> chunk files.

Every check that can fail on user input (spec, output directory, `make_batch_fn(fixed)`)
runs before the first chunk is computed and before anything is written.
"""

from __future__ import annotations

import datetime as _dt
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa

from jaxloco import info
from jaxloco.analysis import Summary
from jaxloco.sweep import store
from jaxloco.sweep.errors import SweepInterrupted
from jaxloco.sweep.grid import Grid, chunk_bounds, expand
from jaxloco.sweep.schema import check_names, checked_outputs, chunk_table, table_schema
from jaxloco.sweep.spec import SweepSpec, load_spec, spec_from_dict
from jaxloco.sweep.summary import summarize

ROW_ORDER = "product of [params] factors, last varying fastest; seeds innermost"


@dataclass(frozen=True)
class SweepResult:
    """The finished table, the output directory and the summary that goes with it.

    summary is None only when the analysis' summarize function failed (`summary_error`).
    """

    table: pa.Table
    path: Path
    summary: Summary | None
    chunks_computed: int = 0
    chunks_reused: int = 0
    written: tuple[Path, ...] = ()
    warnings: tuple[str, ...] = ()
    summary_error: str | None = None

    @property
    def table_path(self) -> Path:
        return self.path / store.TABLE


def run(
    spec: SweepSpec | str | Path | Mapping[str, Any],
    *,
    resume: bool = False,
    overwrite: bool = False,
    progress: bool = True,
    output: str | Path | None = None,
    configure_jax: bool = True,
    on_chunk: Callable[[int, int], None] | None = None,
) -> SweepResult:
    """Run (or resume) a sweep and return its table.

    spec: a SweepSpec, a path to a TOML spec, or a dict in the TOML layout.
    output: overrides the spec's output directory. configure_jax: call
    `jaxloco.runtime.configure(x64=analysis.x64, cache_dir=True)` first.
    on_chunk(index, n_chunks): called after each chunk file is saved.
    Raises SpecError for user errors (before computing anything) and SweepInterrupted
    (a KeyboardInterrupt) when interrupted; saved chunks stay for `resume=True`.
    """
    if isinstance(spec, Mapping):
        spec = spec_from_dict(spec)
    elif not isinstance(spec, SweepSpec):
        spec = load_spec(spec)
    if output is not None:
        spec = spec.with_options(output=output)
    analysis = spec.analysis
    check_names(analysis)
    out = spec.output
    grid = expand(spec)
    bounds = chunk_bounds(grid.n_rows, spec.chunk_size)
    spec_hash = spec.hash
    mode = store.check_output(out, spec_hash, resume=resume, overwrite=overwrite)

    import jax

    from jaxloco import runtime

    if configure_jax:
        runtime.configure(x64=analysis.x64, cache_dir=True)
    host = analysis.executor == "host"
    fn = analysis.make_batch_fn(dict(spec.fixed))
    if not host:
        fn = jax.jit(fn)

    versions = info.versions()
    store.open_output(out, _manifest(spec, spec_hash, len(bounds), versions), mode)
    done, warnings = store.saved_chunks(out, bounds, spec_hash) if mode == "resume" else (set(), [])
    todo = [i for i in range(len(bounds)) if i not in done]

    schema = table_schema(analysis, spec_hash, swept=tuple(spec.swept))
    provenance = {
        "analysis": analysis.name,
        "jaxloco_version": versions["jaxloco"],
        "jax_version": versions["jax"],
        "mujoco_version": versions["mujoco"],
    }
    # the batch axis is sharded over every JAX device (all CPU cores, or the GPUs); one
    # compiled call takes at most MAX_ROWS_PER_DEVICE rows per device, larger chunks are
    # run in several calls of that shape
    devices = jax.devices()
    per_call = min(spec.chunk_size, grid.n_rows, MAX_ROWS_PER_DEVICE * len(devices))
    batch = -(-per_call // len(devices)) * len(devices)
    if host:  # the analysis batches itself: one call per chunk, no padding
        batch = spec.chunk_size
    sharding = jax.sharding.NamedSharding(jax.sharding.Mesh(np.array(devices), ("batch",)),
                                          jax.sharding.PartitionSpec("batch"))
    x64 = bool(jax.config.jax_enable_x64)
    keys_by_seed = np.stack([np.asarray(jax.random.PRNGKey(int(s)), dtype=np.uint32) for s in grid.seed_values])
    done_rows = sum(stop - start for i, (start, stop) in enumerate(bounds) if i in done)

    from jaxloco.sweep.display import row_progress

    try:
        with row_progress(grid.n_rows, done_rows, enabled=progress) as bar:
            for count, index in enumerate(todo):
                bar.chunk_started(index, len(bounds), first=count == 0)
                start, stop = bounds[index]
                swept, seed_pos = grid.rows(start, stop)
                parts = []
                for lo in range(0, stop - start, batch):
                    hi = min(lo + batch, stop - start)
                    if host:
                        inputs = {name: v[lo:hi] for name, v in swept.items()}
                        raw = fn(inputs, keys_by_seed[seed_pos[lo:hi]])
                        parts.append(checked_outputs(analysis, raw, hi - lo))
                        continue
                    inputs = {name: _padded(_device_array(v[lo:hi], x64), batch) for name, v in swept.items()}
                    keys = _padded(keys_by_seed[seed_pos[lo:hi]], batch)
                    raw = fn(*jax.device_put((inputs, keys), sharding))
                    parts.append({k: v[: hi - lo] for k, v in checked_outputs(analysis, raw, batch).items()})
                outputs = {k: np.concatenate([part[k] for part in parts]) for k in parts[0]}
                table = chunk_table(
                    schema,
                    analysis,
                    start=start,
                    swept=swept,
                    fixed=spec.fixed,
                    seeds=grid.seed_values[seed_pos],
                    outputs=outputs,
                    provenance=provenance,
                )
                store.write_chunk(out, index, table)
                bar.advance(stop - start)
                if on_chunk is not None:
                    on_chunk(index, len(bounds))
            bar.finish()
        table = store.assemble(out, len(bounds))
        written = store.write_table(out, table, csv="csv" in spec.formats)
    except KeyboardInterrupt:
        raise SweepInterrupted(store.count_saved(out, len(bounds)), len(bounds), out) from None

    summary, summary_error = None, None
    try:
        summary = summarize(table, analysis)
    except Exception as exc:  # the table is written; a broken summary must not hide it
        summary_error = f"{type(exc).__name__}: {exc}"
    return SweepResult(
        table=table,
        path=out,
        summary=summary,
        chunks_computed=len(todo),
        chunks_reused=len(done),
        written=tuple(written),
        warnings=tuple(warnings),
        summary_error=summary_error,
    )


# jaxlib 0.10.2's batched LAPACK kernels on CPU were seen to deadlock when one call
# batched about 1,000 small factorizations (the leg-grope QP at vmapped batch 1,000 hung;
# 512 ran). Keeping each compiled call at or below this many rows per device avoids it.
MAX_ROWS_PER_DEVICE = 256


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


def _manifest(spec: SweepSpec, spec_hash: str, n_chunks: int, versions: dict[str, str]) -> dict[str, Any]:
    return {
        "format": 1,
        "analysis": spec.analysis.name,
        "name": spec.name,
        "source": spec.source,
        "spec_hash": spec_hash,
        "rows": spec.n_rows,
        "chunks": n_chunks,
        "chunk_size": spec.chunk_size,
        "row_order": ROW_ORDER,
        "spec": spec.content(),
        "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "versions": versions,
    }


__all__ = ["Grid", "SweepResult", "run"]
