"""Running a sweep: grid -> equally shaped chunks -> one jitted batch call each -> chunk files.

`run` is the driver: it validates everything, opens the output directory and writes each
chunk file as it arrives. An executor (`jaxloco.sweep.executors`) computes the chunks, in
this process ("local") or in Ray worker processes ("ray"), with `jaxloco.sweep.chunks`.
The table, its spec hash and provenance do not depend on the executor, so a run started
with one executor can be resumed with another.

Every check that can fail on user input (spec, output directory, `batch_fn(fixed)`,
the executor's connection) runs before the first chunk is computed and before anything
is written.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pyarrow as pa

from jaxloco import info
from jaxloco.analysis import Summary
from jaxloco.errors import SweepInterrupted
from jaxloco.sweep import store
from jaxloco.sweep.chunks import SweepWork
from jaxloco.sweep.executors import Executor, get_executor
from jaxloco.sweep.grid import chunk_bounds
from jaxloco.sweep.schema import check_names
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
    executor: str | Executor = "local",
) -> SweepResult:
    """Run (or resume) a sweep and return its table.

    spec: a SweepSpec, a path to a TOML spec, or a dict in the TOML layout.
    output: overrides the spec's output directory. configure_jax: call
    `jaxloco.runtime.configure(x64=analysis.x64, cache_dir=True)` first.
    on_chunk(index, n_chunks): called after each chunk file is saved (in the order the
    chunks finish, which for the "ray" executor need not be index order).
    executor: "local" (this process), "ray" (a local Ray instance, one task per chunk) or
    an executor object such as `jaxloco.sweep.executors.RayExecutor(address=...)`.
    Raises SpecError for user errors (before computing anything) and SweepInterrupted
    (a KeyboardInterrupt) when interrupted; saved chunks stay for `resume=True`.
    """
    if isinstance(spec, Mapping):
        spec = spec_from_dict(spec)
    elif not isinstance(spec, SweepSpec):
        spec = load_spec(spec)
    if output is not None:
        spec = spec.with_options(output=output)
    chosen = get_executor(executor)
    analysis = spec.analysis
    check_names(analysis)
    out = spec.output
    bounds = chunk_bounds(spec.n_rows, spec.chunk_size)
    spec_hash = spec.hash
    mode = store.check_output(out, spec_hash, resume=resume, overwrite=overwrite)

    import jax

    from jaxloco import runtime

    if configure_jax:
        runtime.configure(x64=analysis.x64, cache_dir=True)
    fn = analysis.batch_fn(dict(spec.fixed))  # its user errors come before anything runs
    work = SweepWork(
        spec,
        spec_hash,
        x64=bool(jax.config.jax_enable_x64),
        cpu_devices=jax.device_count() if jax.default_backend() == "cpu" else None,
        batch_fn=fn if chosen.in_process else None,
    )

    with chosen.session():  # e.g. connect to Ray: refused before anything is written
        versions = info.versions()
        store.open_output(out, _manifest(spec, spec_hash, len(bounds), versions), mode)
        done, warnings = store.saved_chunks(out, bounds, spec_hash) if mode == "resume" else (set(), [])
        todo = [i for i in range(len(bounds)) if i not in done]
        done_rows = sum(stop - start for i, (start, stop) in enumerate(bounds) if i in done)

        from jaxloco.sweep.display import row_progress

        try:
            with (
                row_progress(spec.n_rows, done_rows, enabled=progress) as bar,
                contextlib.closing(chosen.chunks(work, todo)) as results,
            ):
                pending = list(todo)
                if pending:
                    bar.chunk_started(pending[0], len(bounds), first=True)
                clock, first = time.perf_counter(), True
                for index, table in results:
                    store.write_chunk(out, index, table)
                    now = time.perf_counter()  # wall time since the previous chunk was saved
                    store.record_chunk_time(out, index, now - clock, first=first)
                    clock, first = now, False
                    pending.remove(index)
                    start, stop = bounds[index]
                    bar.advance(stop - start)
                    if on_chunk is not None:
                        on_chunk(index, len(bounds))
                    if pending:
                        bar.chunk_started(pending[0], len(bounds), first=False)
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


__all__ = [
    "SweepResult",
    "run",
]
