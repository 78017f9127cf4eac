"""One row of a sweep, from its table (`table.parquet`) or from its spec's grid.

`load_row(path, index)` reads a sweep table, or a sweep spec (TOML): then the spec's
output table if it exists and was made by this spec (same spec hash), else the row of
the spec's grid (`jaxloco.sweep.grid`, nothing is run; the row then has no metrics).
Every parameter of the analysis is resolved (fixed ones included), so the row alone
decides the replay. Errors are one-line `SpecError`s (missing file, bad spec, row out of
range).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from jaxloco import paths, specs
from jaxloco.analysis import Analysis
from jaxloco.errors import SpecError


@dataclass(frozen=True)
class Row:
    """One row of a sweep: the analysis, every parameter value, the seed, and (when the
    row comes from a table) its metrics and status.

    values: parameter name -> plain Python value, every parameter of the analysis.
    swept: names of the parameters the sweep varied (shown on the video).
    metrics: metric name -> value from the table, None when the row was not run.
    """

    analysis: Analysis
    index: int
    n_rows: int
    values: Mapping[str, Any]
    seed: int
    swept: tuple[str, ...]
    metrics: Mapping[str, Any] | None
    status: str | None
    source: str
    notes: tuple[str, ...] = field(default=())

    @property
    def key(self) -> np.ndarray:
        """The row's PRNG key (2,) uint32, as the sweep makes it (`jax.random.PRNGKey(seed)`)."""
        import jax

        return np.asarray(jax.random.PRNGKey(int(self.seed)), dtype=np.uint32)


def plain_data(value: Any) -> Any:
    return value.item() if isinstance(value, np.generic) else value


def _check_index(index: int, n_rows: int, source: str) -> None:
    if isinstance(index, bool) or not isinstance(index, (int, np.integer)):
        raise SpecError(f"--row: expected an integer, got {index!r}")
    if not 0 <= index < n_rows:
        last = f"0..{n_rows - 1}" if n_rows else "none: the table is empty"
        raise SpecError(f"--row: {index} is out of range ({source} has {n_rows} rows: {last})")


def row_from_table(table: Any, analysis: Analysis, index: int, source: str) -> Row:
    """Row `index` (the table's `row` column) of a sweep table (pyarrow.Table)."""
    rows = np.asarray(table.column("row").to_numpy()) if "row" in table.column_names else np.arange(table.num_rows)
    n_rows = int(rows.max()) + 1 if rows.size else 0
    _check_index(index, n_rows, source)
    hits = np.flatnonzero(rows == index)
    if not hits.size:
        raise SpecError(f"--row: row {index} is missing from {source}")
    i = int(hits[0])

    def cell(name: str) -> Any:
        return plain_data(table.column(name)[i].as_py())

    values: dict[str, Any] = {}
    for p in analysis.params:
        values[p.name] = cell(p.name) if p.name in table.column_names else p.default
    swept = tuple(
        name for name in table.column_names
        if (table.schema.field(name).metadata or {}).get(b"role") == b"swept"
    )
    metrics = {m.name: cell(m.name) for m in analysis.metrics if m.name in table.column_names}
    status = cell("status") if "status" in table.column_names else None
    seed = int(cell("seed")) if "seed" in table.column_names else 0
    return Row(analysis, index, n_rows, values, seed, swept, metrics, status, source)


def _table_hash(table: Any) -> str | None:
    meta = table.schema.metadata or {}
    try:
        return json.loads(meta[b"jaxloco"].decode()).get("spec_hash")
    except (KeyError, ValueError, AttributeError):
        return None


def load_row(path: str | Path, index: int) -> Row:
    """Row `index` of the sweep at `path`: a table (.parquet), a spec (.toml) or a bundled
    spec's name; see the module docstring."""
    from jaxloco.sweep.summary import read_table

    p = specs.resolve(path)  # a path, or a bundled spec's name (SpecError listing them on a typo)
    if not paths.exists(p):
        raise SpecError(f"{path}: no such file")
    if p.suffix.lower() != ".toml":
        table, analysis = read_table(p)
        return row_from_table(table, analysis, index, str(path))

    from jaxloco.sweep import expand, load_spec

    spec = load_spec(p)
    table_path = spec.output / "table.parquet"
    notes: list[str] = []
    if paths.is_file(table_path, where=f"{path}: sweep.output"):
        table, analysis = read_table(table_path)
        if analysis.name == spec.analysis.name and _table_hash(table) == spec.hash:
            return row_from_table(table, analysis, index, str(table_path))
        notes.append(f"{table_path} was made by another spec; using the row of {path}'s grid")
    else:
        notes.append(f"{table_path} does not exist (sweep not run): the row's metrics come from the replay only")
    grid = expand(spec)
    _check_index(index, grid.n_rows, str(path))
    columns, seed_pos = grid.rows(index, index + 1)
    values = dict(spec.fixed)
    values.update({name: plain_data(v[0]) for name, v in columns.items()})
    values = {p.name: values[p.name] for p in spec.analysis.params}
    seed = int(grid.seed_values[seed_pos[0]])
    return Row(spec.analysis, index, grid.n_rows, values, seed, tuple(spec.swept), None, None, str(path),
               tuple(notes))
