"""Terminal output of sweeps: the progress bar and rich tables (nothing here computes).

Cell texts are rendered literally (no rich markup), so "[fixed]" stays "[fixed]".
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from rich.console import Console, Group, RenderableType
from rich.padding import Padding
from rich.progress import (
    MofNCompleteColumn,
    Progress,
    ProgressColumn,
    Task,
    TimeElapsedColumn,
    TimeRemainingColumn,
)
from rich.table import Column, Table
from rich.text import Text

from jaxloco.analysis import Analysis, Param, Summary, sweep_problem
from jaxloco.terminal import (
    DocTable,
    FoldedTable,
    Labelled,
    fixed_text,
    progress_columns,
)

FIRST_CHUNK_NOTE = " +compile"  # the first chunk's time includes JIT compilation


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
            note = FIRST_CHUNK_NOTE if first else ""
            self._progress.update(self._task, description=f"chunk {index + 1}/{n_chunks}{note}")

    def finish(self, text: str = "done") -> None:
        if self._progress is not None and self._task is not None:
            self._progress.update(self._task, description=text)

    def advance(self, rows: int) -> None:
        if self._progress is not None and self._task is not None:
            self._progress.advance(self._task, rows)


def rows_progress_bar(total: int, console: Console) -> Progress:
    """The sweep's progress line, with the fields that fit the console's width."""
    fields = [
        (0, fixed_text("{task.description}"), len(f"chunk 10/10{FIRST_CHUNK_NOTE}")),
        (1, Labelled(MofNCompleteColumn(), after=" rows"), len(f"{total}/{total} rows")),
        (3, _RowsPerSecond(table_column=Column(no_wrap=True)), len("12,345 rows/s")),
        (4, TimeElapsedColumn(table_column=Column(no_wrap=True)), len("0:00:00")),
        (2, Labelled(TimeRemainingColumn(), before="ETA "), len("ETA 10:00:00")),
    ]
    return Progress(*progress_columns(console.width, fields), console=console)


@contextmanager
def row_progress(total: int, done: int, *, enabled: bool, console: Console | None = None) -> Iterator[RowProgress]:
    if not enabled:
        yield RowProgress(None, None)
        return
    progress = rows_progress_bar(total, console or Console(stderr=True))
    with progress:
        task = progress.add_task("starting", total=total, completed=done)
        yield RowProgress(progress, task)


def _text(value: object) -> Text:
    return Text(str(value))


def summary_table(summary: Summary) -> FoldedTable:
    """The summary's title and table, drawn within the console's width."""
    return FoldedTable(summary.columns, summary.rows, title=summary.title)


def print_summary(summary: Summary, console: Console | None = None) -> None:
    """The summary table within the console's width (long headers wrap, or the columns are
    split into stacked tables that repeat the first column; no cell is cut), then its notes."""
    console = console or Console()
    console.print(summary_table(summary))
    for note in summary.notes:
        console.print(Text(note))


def analyses_table(rows: list[tuple[str, str]]) -> Table:
    table = Table(title="analyses", title_justify="left")
    table.add_column("name", no_wrap=True)
    table.add_column("description")
    for name, doc in rows:
        table.add_row(_text(name), _text(doc))
    return table


def _sweepable(p: Param, executor: str) -> bool:
    """Whether a spec may sweep `p` (a string only with choices, in a host analysis)."""
    return sweep_problem(p, executor) is None


def _param_head(p: Param, executor: str) -> Text:
    """A parameter's block headline: name, kind, default (unit), range, sweepable."""
    unit = f" {p.unit}" if p.unit else ""
    sweepable = "sweepable" if _sweepable(p, executor) else "not sweepable"
    head = Text(p.name, style="bold")
    head.append(f": {p.kind}, default {p.default!r}{unit}, range {p.range_text()}, {sweepable}")
    return head


def params_table(analysis: Analysis) -> DocTable:
    ex = analysis.executor
    rows = [(p.name, p.kind, repr(p.default), p.unit, p.range_text(), "yes" if _sweepable(p, ex) else "no", p.doc)
            for p in analysis.params]
    return DocTable(f"{analysis.name}: parameters", ("name", "kind", "default", "unit", "range", "sweepable", "doc"),
                    rows, heads=[_param_head(p, ex) for p in analysis.params])


def metrics_table(analysis: Analysis) -> DocTable:
    rows = [(m.name, m.kind, m.unit, m.doc) for m in analysis.metrics]
    return DocTable(f"{analysis.name}: metrics", ("name", "kind", "unit", "doc"), rows)


def describe_tables(analysis: Analysis) -> list[RenderableType]:
    """Parameters and metrics (tables, or one block per row in a narrow terminal) and statuses."""
    statuses = Table(title=Text(f"{analysis.name}: statuses"), title_justify="left")
    statuses.add_column("code")
    statuses.add_column("status")
    for code, status in enumerate(analysis.statuses):
        statuses.add_row(str(code), _text(status))
    return [params_table(analysis), metrics_table(analysis), statuses]


def first_line(doc: str) -> str:
    lines = [line.strip() for line in doc.strip().splitlines()]
    return lines[0] if lines else ""


def bundled_specs_table(headers: list, directory: object = None) -> Group:
    """`jaxloco sweeps`: one block per bundled spec (`jaxloco.specs.Header`): its name and
    what it runs on one line, its size and recorded time on the next, then its question,
    indented and wrapped to the terminal; last, the directory the files are in."""
    blocks: list = [Text("bundled specs (run one by name: jaxloco sweep NAME / jaxloco tune NAME)", style="bold")]
    for h in headers:
        blocks.append(Text(""))
        blocks.append(Text.assemble((h.name, "bold cyan"), f"  {h.kind} of {h.target}"))
        facts = h.size + (f"; {h.time}" if h.time else "")
        blocks.append(Padding(Text(facts), (0, 0, 0, 2)))
        blocks.append(Padding(Text(h.question), (0, 0, 0, 2)))
    if directory is not None:
        blocks += [Text(""), Text(f"files: {directory} (copy one to change it; pass the copy's path)")]
    return Group(*blocks)
