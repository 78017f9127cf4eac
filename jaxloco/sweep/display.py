"""Terminal output of sweeps: the progress bar and rich tables (nothing here computes).

Cell texts are rendered literally (no rich markup), so "[fixed]" stays "[fixed]".
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    ProgressColumn,
    Task,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)
from rich.table import Table
from rich.text import Text

from jaxloco.analysis import Analysis, Summary


class _RowsPerSecond(ProgressColumn):
    def render(self, task: Task) -> Text:
        speed = task.finished_speed or task.speed
        if speed is None:
            return Text("-- rows/s", style="progress.data.speed")
        return Text(f"{speed:,.1f} rows/s" if speed < 10 else f"{speed:,.0f} rows/s", style="progress.data.speed")


class RowProgress:
    """Rows done of the total, rows/s and ETA; `enabled=False` makes every call a no-op."""

    def __init__(self, progress: Progress | None, task: int | None) -> None:
        self._progress, self._task = progress, task

    def chunk_started(self, index: int, n_chunks: int, first: bool) -> None:
        if self._progress is not None and self._task is not None:
            note = " (includes JIT compilation)" if first else ""
            self._progress.update(self._task, description=f"chunk {index + 1}/{n_chunks}{note}")

    def finish(self, text: str = "done") -> None:
        if self._progress is not None and self._task is not None:
            self._progress.update(self._task, description=text)

    def advance(self, rows: int) -> None:
        if self._progress is not None and self._task is not None:
            self._progress.advance(self._task, rows)


@contextmanager
def row_progress(total: int, done: int, *, enabled: bool, console: Console | None = None) -> Iterator[RowProgress]:
    if not enabled:
        yield RowProgress(None, None)
        return
    progress = Progress(
        TextColumn("{task.description}", markup=False),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("rows"),
        _RowsPerSecond(),
        TimeElapsedColumn(),
        TextColumn("ETA"),
        TimeRemainingColumn(),
        console=console or Console(stderr=True),
    )
    with progress:
        task = progress.add_task("starting", total=total, completed=done)
        yield RowProgress(progress, task)


def _text(value: object) -> Text:
    return Text(str(value))


def summary_table(summary: Summary) -> Table:
    table = Table(title=Text(summary.title), title_justify="left", min_width=len(summary.title))
    for column in summary.columns:
        table.add_column(Text(column))
    for row in summary.rows:
        table.add_row(*(_text(cell) for cell in row))
    return table


def print_summary(summary: Summary, console: Console | None = None) -> None:
    """The summary table at its natural width: in a narrower terminal the lines wrap
    rather than every cell being cut to an ellipsis."""
    console = console or Console()
    table = summary_table(summary)
    natural = console.measure(table, options=console.options.update_width(100_000)).maximum
    if natural > console.width:  # the same output stream, wide enough for every cell
        console = Console(file=console.file, width=natural, color_system=console.color_system,
                          force_terminal=console.is_terminal, force_jupyter=False)
    console.print(table)
    for note in summary.notes:
        console.print(Text(note))


def analyses_table(rows: list[tuple[str, str]]) -> Table:
    table = Table(title="analyses", title_justify="left")
    table.add_column("name", no_wrap=True)
    table.add_column("description")
    for name, doc in rows:
        table.add_row(_text(name), _text(doc))
    return table


def describe_tables(analysis: Analysis) -> list[Table]:
    params = Table(title=Text(f"{analysis.name}: parameters"), title_justify="left")
    for column in ("name", "kind", "default", "unit", "range", "sweepable", "doc"):
        params.add_column(column, no_wrap=column in ("name", "default", "range"))
    for p in analysis.params:
        params.add_row(
            *map(
                _text,
                (
                    p.name,
                    p.kind,
                    repr(p.default),
                    p.unit,
                    p.range_text(),
                    "yes" if p.sweepable and p.kind != "str" else "no",
                    p.doc,
                ),
            )
        )
    metrics = Table(title=Text(f"{analysis.name}: metrics"), title_justify="left")
    for column in ("name", "kind", "unit", "doc"):
        metrics.add_column(column, no_wrap=column == "name")
    for m in analysis.metrics:
        metrics.add_row(*map(_text, (m.name, m.kind, m.unit, m.doc)))
    statuses = Table(title=Text(f"{analysis.name}: statuses"), title_justify="left")
    statuses.add_column("code")
    statuses.add_column("status")
    for code, status in enumerate(analysis.statuses):
        statuses.add_row(str(code), _text(status))
    return [params, metrics, statuses]


def first_line(doc: str) -> str:
    lines = [line.strip() for line in doc.strip().splitlines()]
    return lines[0] if lines else ""
