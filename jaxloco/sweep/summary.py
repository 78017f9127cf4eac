"""The short human summary of a sweep table (the analysis' own, or status counts)."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from jaxloco import analysis as registry
from jaxloco import paths
from jaxloco.analysis import Analysis, Summary
from jaxloco.errors import SpecError


def status_counts(table: pa.Table, analysis: Analysis) -> Summary:
    """Rows per status, in the analysis' status order (statuses not declared come last).

    With swept string columns (categorical axes, e.g. a task name) the rows are counted
    per value of those columns (in the table's order) and status; zero counts are left out.
    """
    groups = swept_string_columns(table)
    if groups:
        return _grouped_status_counts(table, analysis, groups)
    counts = Counter(table.column("status").to_pylist()) if "status" in table.column_names else Counter()
    total = table.num_rows
    order = _status_order(analysis, counts)
    rows = tuple((status, str(counts.get(status, 0)), _share(counts.get(status, 0), total)) for status in order)
    return Summary(title=f"{analysis.name}: {total} rows by status", columns=("status", "rows", "share"), rows=rows)


def swept_string_columns(table: pa.Table) -> list[str]:
    """The names of a sweep table's swept string columns (field metadata role "swept")."""
    return [
        f.name
        for f in table.schema
        if pa.types.is_string(f.type) and (f.metadata or {}).get(b"role") == b"swept"
    ]


def _grouped_status_counts(table: pa.Table, analysis: Analysis, groups: list[str]) -> Summary:
    keys = list(zip(*(table.column(name).to_pylist() for name in groups), strict=True))
    statuses = table.column("status").to_pylist() if "status" in table.column_names else [None] * len(keys)
    per_group: dict[tuple, Counter] = {}
    for key, status in zip(keys, statuses, strict=True):
        per_group.setdefault(key, Counter())[status] += 1
    rows = []
    for key, counts in per_group.items():
        total = sum(counts.values())
        for status in _status_order(analysis, counts):
            if counts.get(status):
                rows.append((*key, str(status), str(counts[status]), _share(counts[status], total)))
    title = f"{analysis.name}: {table.num_rows} rows by {', '.join(groups)} and status"
    return Summary(title=title, columns=(*groups, "status", "rows", "share"), rows=tuple(rows))


def _status_order(analysis: Analysis, counts: Counter) -> list:
    return list(analysis.statuses) + sorted(set(counts) - set(analysis.statuses), key=str)


def _share(count: int, total: int) -> str:
    return f"{100.0 * count / total:.1f}%" if total else "-"


def summarize(table: pa.Table, analysis: Analysis) -> Summary:
    """`analysis.summarize(table)`, or the status counts when the analysis has none."""
    if analysis.summarize is None:
        return status_counts(table, analysis)
    return analysis.summarize(table)


def read_table(path: str | Path) -> tuple[pa.Table, Analysis]:
    """A sweep table from disk and its analysis (named by its `analysis` column)."""
    label = str(path)
    p = Path(path)
    if not paths.exists(p):
        raise SpecError(f"{label}: no such file")
    if paths.is_dir(p):
        raise SpecError(f"{label}: is a directory; give the table.parquet inside it")
    try:
        table = pq.read_table(p)
    except (OSError, pa.ArrowException) as exc:
        raise SpecError(f"{label}: not a readable Parquet file ({exc})") from None
    if "analysis" not in table.column_names:
        raise SpecError(f"{label}: no 'analysis' column; not a jaxloco sweep table")
    names = sorted(set(table.column("analysis").drop_null().to_pylist()))
    if len(names) != 1:
        raise SpecError(f"{label}: expected one analysis name in its 'analysis' column, found {len(names)}")
    try:
        analysis = registry.get(names[0])
    except SpecError as exc:
        raise SpecError(f"{label}: {exc}") from None
    return table, analysis
