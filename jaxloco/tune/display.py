"""Terminal output of `jaxloco tune` / `jaxloco objectives`: the progress bar and rich
tables (nothing here computes). Cell texts are rendered literally (no rich markup)."""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING

from rich.console import Console
from rich.progress import (
    MofNCompleteColumn,
    Progress,
    TimeElapsedColumn,
    TimeRemainingColumn,
)
from rich.table import Column, Table
from rich.text import Text

from jaxloco.analysis import Param
from jaxloco.sweep.display import analyses_table
from jaxloco.terminal import DocTable, FoldedTable, Labelled, fixed_text, progress_columns
from jaxloco.tune.objective import Objective, Tunable

if TYPE_CHECKING:
    from jaxloco.tune.result import TuneResult


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


def steps_progress_bar(total: int, console: Console) -> Progress:
    """The tuning's progress line, with the fields that fit the console's width."""
    fields = [
        (0, fixed_text("{task.description}"), len("references")),
        (1, Labelled(MofNCompleteColumn(), after=" steps"), len(f"{total}/{total} steps")),
        (2, fixed_text("loss {task.fields[loss]}"), len("loss -1.234e-05")),
        (3, fixed_text("best {task.fields[best]}"), len("best -1.234e-05")),
        (5, TimeElapsedColumn(table_column=Column(no_wrap=True)), len("0:00:00")),
        (4, Labelled(TimeRemainingColumn(), before="ETA "), len("ETA 10:00:00")),
    ]
    return Progress(*progress_columns(console.width, fields), console=console)


@contextmanager
def step_progress(total: int, *, enabled: bool, console: Console | None = None) -> Iterator[StepProgress]:
    if not enabled:
        yield StepProgress(None, None)
        return
    progress = steps_progress_bar(total, console or Console(stderr=True))
    with progress:
        task = progress.add_task("compiling", total=total, loss="-", best="-")
        yield StepProgress(progress, task)


def _format(value: object) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.6g}" if math.isfinite(value) else str(value)
    return str(value)


def objectives_table(rows: list[tuple[str, str]]) -> Table:
    table = analyses_table(rows)
    table.title = "objectives"
    return table


def _role(t: Tunable) -> str:
    return "tunable" + (", log scale" if t.scale == "log" else "")


def _tunable_head(t: Tunable, references: dict[str, str]) -> Text:
    """A tunable's block headline: role, default (unit), range, then each reference's value."""
    unit = f" {t.unit}" if t.unit else ""
    refs = "".join(f", {label} {value}" for label, value in references.items() if value != "-")
    head = Text(t.name, style="bold")
    head.append(f": {_role(t)}, default {_format(t.default)}{unit}, range {t.range_text()}{refs}")
    return head


def _setting_head(p: Param) -> Text:
    unit = f" {p.unit}" if p.unit else ""
    head = Text(p.name, style="bold")
    head.append(f": setting ({p.kind}), default {p.default!r}{unit}, range {p.range_text()}")
    return head


def describe_table(objective: Objective) -> DocTable:
    """One row per tunable (its default and each reference's value) and per setting: a table,
    or one block per row in a narrow terminal."""
    labels = list(objective.references)
    rows, heads = [], []
    for t in objective.tunables:
        refs = {label: _format(objective.references[label].get(t.name)) for label in labels}
        rows.append((t.name, _role(t), _format(t.default), *refs.values(), t.unit, t.range_text(), t.doc))
        heads.append(_tunable_head(t, refs))
    for p in objective.settings:
        rows.append((p.name, f"setting ({p.kind})", repr(p.default), *([""] * len(labels)), p.unit, p.range_text(),
                     p.doc))
        heads.append(_setting_head(p))
    columns = ("name", "role", "default", *labels, "unit", "range", "doc")
    justify = ["right" if column in labels else "left" for column in columns]
    return DocTable(f"{objective.name}: parameters", columns, rows, heads=heads, justify=justify)


def result_table(result: TuneResult) -> FoldedTable:
    """Quantities down, parameter sets (initial, tuned, references) across; tuned tunables
    marked *. Within the console's width: the sets are split over stacked tables if needed."""
    rows = result.comparison.to_pylist()
    spec = result.spec
    title = f"{spec.name}: {spec.objective.name}, {spec.steps} {spec.optimizer} steps, best at step {result.best_step}"
    units = {t.name: t.unit for t in spec.objective.tunables}
    names = ["loss", *units, *result.comparison.column_names[3 + len(units) :]]
    cells = [(f"{name} *" if name in spec.params else name, units.get(name, ""), *(_format(row[name]) for row in rows))
             for name in names]
    labels = [str(row["label"]) for row in rows]
    return FoldedTable(("", "unit", *labels), cells, title=title, justify=["left", "left", *["right"] * len(labels)],
                       keys=2)


def print_result(result: TuneResult, console: Console | None = None) -> None:
    console = console or Console()
    console.print(result_table(result))
    console.print(Text("* tuned; the others stay at their initial values"))


def validation_table(comparison, title: str) -> FoldedTable:
    """A validation (`jaxloco.tune.handoff.compare`): quantities down, parameter sets across,
    within the console's width."""
    rows = comparison.to_pylist()
    names = [n for n in comparison.column_names[1:] if not n.endswith(("_min", "_max"))]
    cells = [(name, *(_format(row[name]) for row in rows)) for name in names]
    labels = [str(row["label"]) for row in rows]
    return FoldedTable(("", *labels), cells, title=title, justify=["left", *["right"] * len(labels)])
