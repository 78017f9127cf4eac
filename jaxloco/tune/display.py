"""Terminal output of `jaxloco tune` / `jaxloco objectives`: the progress bar and rich
tables (nothing here computes). Cell texts are rendered literally (no rich markup)."""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING

from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)
from rich.table import Table
from rich.text import Text

from jaxloco.sweep.display import analyses_table
from jaxloco.tune.objective import Objective

if TYPE_CHECKING:
    from jaxloco.tune.runner import TuneResult


class StepProgress:
    """Steps done, the current and the best loss; `enabled=False` makes every call a no-op."""

    def __init__(self, progress: Progress | None, task: int | None) -> None:
        self._progress, self._task = progress, task

    def describe(self, text: str) -> None:
        if self._progress is not None and self._task is not None:
            self._progress.update(self._task, description=text)

    def update(self, step: int, loss: float, best: float) -> None:
        if self._progress is not None and self._task is not None:
            self._progress.update(self._task, completed=step, loss=f"{loss:.4g}", best=f"{best:.4g}")


@contextmanager
def step_progress(total: int, *, enabled: bool, console: Console | None = None) -> Iterator[StepProgress]:
    if not enabled:
        yield StepProgress(None, None)
        return
    progress = Progress(
        TextColumn("{task.description}", markup=False),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("steps  loss {task.fields[loss]}  best {task.fields[best]}", markup=False),
        TimeElapsedColumn(),
        TextColumn("ETA"),
        TimeRemainingColumn(),
        console=console or Console(stderr=True),
    )
    with progress:
        task = progress.add_task("compiling", total=total, loss="-", best="-")
        yield StepProgress(progress, task)


def _number(value: object) -> Text:
    if value is None:
        return Text("-")
    if isinstance(value, float):
        return Text(f"{value:.6g}" if math.isfinite(value) else str(value))
    return Text(str(value))


def objectives_table(rows: list[tuple[str, str]]) -> Table:
    table = analyses_table(rows)
    table.title = "objectives"
    return table


def describe_table(objective: Objective) -> Table:
    """One row per tunable (its default and each reference's value) and per setting."""
    labels = list(objective.references)
    table = Table(title=Text(f"{objective.name}: parameters"), title_justify="left")
    for column in ("name", "role", "default", *labels, "unit", "range", "doc"):
        table.add_column(Text(column), no_wrap=column != "doc", justify="right" if column in labels else "left")
    for t in objective.tunables:
        role = "tunable" + (", log scale" if t.scale == "log" else "")
        refs = (_number(objective.references[label].get(t.name)) for label in labels)
        table.add_row(Text(t.name), Text(role), _number(t.default), *refs, *map(Text, (t.unit, t.range_text(), t.doc)))
    for p in objective.settings:
        cells = (f"setting ({p.kind})", repr(p.default), *([""] * len(labels)), p.unit, p.range_text(), p.doc)
        table.add_row(Text(p.name), *map(Text, cells))
    return table


def result_table(result: TuneResult) -> Table:
    """Quantities down, parameter sets (initial, tuned, references) across; tuned tunables marked *."""
    rows = result.comparison.to_pylist()
    spec = result.spec
    title = f"{spec.name}: {spec.objective.name}, {spec.steps} {spec.optimizer} steps, best at step {result.best_step}"
    table = Table(title=Text(title), title_justify="left")
    table.add_column("", no_wrap=True)
    table.add_column("unit")
    for row in rows:
        table.add_column(Text(row["label"]), justify="right")
    units = {t.name: t.unit for t in spec.objective.tunables}
    names = ["loss", *units, *result.comparison.column_names[3 + len(units) :]]
    for name in names:
        label = f"{name} *" if name in spec.params else name
        table.add_row(Text(label), Text(units.get(name, "")), *(_number(row[name]) for row in rows))
    return table


def print_result(result: TuneResult, console: Console | None = None) -> None:
    console = console or Console()
    console.print(result_table(result))
    console.print(Text("* tuned; the others stay at their initial values"))


def validation_table(comparison, title: str) -> Table:
    """A validation (`jaxloco.tune.handoff.compare`): quantities down, parameter sets across."""
    rows = comparison.to_pylist()
    table = Table(title=Text(title), title_justify="left")
    table.add_column("", no_wrap=True)
    for row in rows:
        table.add_column(Text(row["label"]), justify="right")
    for name in comparison.column_names[1:]:
        if name.endswith(("_min", "_max")):
            continue
        table.add_row(Text(name), *(_number(row[name]) for row in rows))
    return table
