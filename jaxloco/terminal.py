"""Rich output that fits the terminal's width (nothing here computes results).

`FoldedTable`: rows of short cells; one table if it fits (long headers wrap), else
several stacked tables that each repeat the key (first) columns. A cell is never cut.
`DocTable`: rows whose last cell is prose; a table when the prose column stays
readable, else one block per row (the other cells on a line, the prose indented below).
`progress_columns`: the fields of a progress line that fit the console's width.
Every text is rendered literally (no rich markup).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from rich.cells import cell_len
from rich.console import Console, ConsoleOptions, Group, RenderResult
from rich.padding import Padding
from rich.progress import BarColumn, ProgressColumn, Task, TextColumn
from rich.table import Column, Table
from rich.text import Text

MIN_DOC_WIDTH = 36  # the narrowest prose column a DocTable keeps as a table
DOC_INDENT = 4
MIN_BAR_WIDTH, MAX_BAR_WIDTH = 10, 40  # a progress bar takes the room the fields leave, within these


def _overhead(n_columns: int) -> int:
    """Borders and padding of a boxed table with n columns (one space each side of a cell)."""
    return 3 * n_columns + 1


def _longest_word(text: str) -> int:
    return max((cell_len(word) for word in text.split()), default=0)


@dataclass(frozen=True)
class _Widths:
    natural: int  # the header and every cell on one line
    tight: int  # every cell on one line, the header wrapped at spaces


def _column_widths(header: str, cells: Sequence[str]) -> _Widths:
    widest_cell = max((cell_len(c) for c in cells), default=0)
    return _Widths(max(cell_len(header), widest_cell), max(_longest_word(header), widest_cell, 1))


def _pack(widths: Sequence[int], capacity: int) -> list[list[int]]:
    """Greedy groups of consecutive column indices whose widths sum to at most capacity
    (a column wider than capacity gets a group of its own)."""
    groups: list[list[int]] = []
    used = capacity + 1
    for index, width in enumerate(widths):
        if groups and used + width <= capacity:
            groups[-1].append(index)
            used += width
        else:
            groups.append([index])
            used = width
    return groups


def _balanced_groups(widths: Sequence[int], capacity: int) -> list[list[int]]:
    """As few groups as `_pack` at `capacity`, with the widest group as narrow as possible."""
    count = len(_pack(widths, capacity))
    for smaller in range(min(max(widths, default=0), capacity), capacity):
        if len(_pack(widths, smaller)) == count:
            return _pack(widths, smaller)
    return _pack(widths, capacity)


def _fit_widths(widths: Sequence[_Widths], room: int) -> list[int]:
    """Column widths for `room` characters of content: each column tight, then widened
    towards its natural width, the smallest needs first, while room is left. When even
    tight does not fit, the widest column gives up the difference (its cells then wrap)."""
    sizes = [w.tight for w in widths]
    spare = room - sum(sizes)
    if spare < 0:
        widest = max(range(len(sizes)), key=sizes.__getitem__)
        sizes[widest] = max(1, sizes[widest] + spare)
        return sizes
    for index in sorted(range(len(widths)), key=lambda i: widths[i].natural - widths[i].tight):
        grow = min(widths[index].natural - sizes[index], spare)
        sizes[index], spare = sizes[index] + grow, spare - grow
    return sizes


def _fold(measured: Sequence[_Widths], width: int, keys: int) -> list[list[int]]:
    """Column indices of the stacked tables: the key columns (the first `keys`), then as few
    groups of the others as fit, packed at natural widths when that needs no more tables."""

    def groups(kind: str) -> list[list[int]]:
        steps = [getattr(w, kind) + 3 for w in measured]  # each column adds its width and a border
        return _balanced_groups(steps[keys:], width - 1 - sum(steps[:keys]))

    natural, tight = groups("natural"), groups("tight")
    chosen = natural if len(natural) <= len(tight) else tight
    return [[*range(keys), *(i + keys for i in group)] for group in chosen]


class FoldedTable:
    """Rows of plain-text cells drawn within the console's width; see the module doc.
    `keys`: how many leading columns every stacked table repeats."""

    def __init__(self, columns: Sequence[str], rows: Sequence[Sequence[object]], *, title: str | None = None,
                 justify: Sequence[str] | None = None, keys: int = 1) -> None:
        self.columns = [str(c) for c in columns]
        self.rows = [[str(cell) for cell in row] for row in rows]
        self.title, self.keys = title, keys
        self.justify = list(justify) if justify is not None else ["left"] * len(self.columns)

    def layout(self, width: int) -> list[tuple[list[int], list[int] | None]]:
        """The stacked tables for `width`: (column indices, column widths or None for natural)."""
        measured = [_column_widths(h, [r[i] for r in self.rows]) for i, h in enumerate(self.columns)]
        everything = list(range(len(self.columns)))
        if sum(w.natural for w in measured) + _overhead(len(measured)) <= width:
            return [(everything, None)]
        if sum(w.tight for w in measured) + _overhead(len(measured)) <= width or len(measured) <= self.keys + 1:
            return [(everything, _fit_widths(measured, width - _overhead(len(measured))))]
        groups = _fold(measured, width, self.keys)
        rooms = [width - _overhead(len(g)) for g in groups]  # content width of each stacked table
        others = [[measured[i] for i in g[self.keys :]] for g in groups]
        keys = measured[: self.keys]  # the same widths in every table, as wide as every table allows
        left = min(room - sum(w.tight for w in rest) for room, rest in zip(rooms, others, strict=True))
        key_widths = _fit_widths(keys, max(left, sum(w.tight for w in keys)))
        return [(g, [*key_widths, *_fit_widths(rest, room - sum(key_widths))])
                for g, room, rest in zip(groups, rooms, others, strict=True)]

    def _table(self, indices: list[int], widths: list[int] | None) -> Table:
        table = Table()
        for position, index in enumerate(indices):
            table.add_column(Text(self.columns[index]), justify=self.justify[index], overflow="fold",
                             width=None if widths is None else widths[position])
        for row in self.rows:
            table.add_row(*(Text(row[i]) for i in indices))
        return table

    def __rich_console__(self, console: Console, options: ConsoleOptions) -> RenderResult:
        if self.title:
            yield Text(self.title, style="table.title")
        for indices, widths in self.layout(options.max_width):
            yield self._table(indices, widths)


def _block_head(cells: Sequence[str]) -> Text:
    head = Text(cells[0], style="bold")
    rest = [c for c in cells[1:] if c]
    if rest:
        head.append(": " + ", ".join(rest))
    return head


class DocTable:
    """Rows whose last cell is prose (a doc); see the module doc. `heads` are the block
    headlines (default: the first cell, then the other non-empty cells)."""

    def __init__(self, title: str, columns: Sequence[str], rows: Sequence[Sequence[str]], *,
                 heads: Sequence[str | Text] | None = None, justify: Sequence[str] | None = None) -> None:
        self.title, self.columns = title, list(columns)
        self.rows = [[str(cell) for cell in row] for row in rows]
        self.heads = list(heads) if heads is not None else None
        self.justify = list(justify) if justify is not None else ["left"] * len(self.columns)

    def fits_as_table(self, width: int) -> bool:
        """Whether the cells before the doc stay on one line with MIN_DOC_WIDTH left for it."""
        fixed = [_column_widths(h, [r[i] for r in self.rows]).natural for i, h in enumerate(self.columns[:-1])]
        return sum(fixed) + MIN_DOC_WIDTH + _overhead(len(self.columns)) <= width

    def table(self) -> Table:
        table = Table(title=Text(self.title), title_justify="left")
        for index, column in enumerate(self.columns):
            last = index == len(self.columns) - 1
            table.add_column(Text(column), no_wrap=not last, overflow="fold", justify=self.justify[index])
        for row in self.rows:
            table.add_row(*map(Text, row))
        return table

    def blocks(self) -> Group:
        parts: list = [Text(self.title, style="table.title")]
        for index, row in enumerate(self.rows):
            head = self.heads[index] if self.heads is not None else _block_head(row[:-1])
            parts.append(head if isinstance(head, Text) else Text(head))
            if row[-1]:
                parts.append(Padding(Text(row[-1], overflow="fold"), (0, 0, 0, DOC_INDENT), expand=False))
        return Group(*parts)

    def __rich_console__(self, console: Console, options: ConsoleOptions) -> RenderResult:
        yield self.table() if self.fits_as_table(options.max_width) else self.blocks()


class Labelled(ProgressColumn):
    """A progress field with words around it ("ETA 0:01:02", "120/800 rows"); never wraps."""

    def __init__(self, inner: ProgressColumn, before: str = "", after: str = "") -> None:
        super().__init__(table_column=Column(no_wrap=True))
        self.inner, self.before, self.after = inner, before, after

    def render(self, task: Task) -> Text:
        text = Text(self.before)
        text.append_text(self.inner.render(task))  # type: ignore[arg-type]
        text.append(self.after)
        return text


def fixed_text(template: str) -> TextColumn:
    """A progress field of text that never wraps."""
    return TextColumn(template, markup=False, table_column=Column(no_wrap=True))


def progress_columns(width: int, fields: Sequence[tuple[int, ProgressColumn, int]]) -> list[ProgressColumn]:
    """The progress fields that fit `width`: `fields` are (priority, column, width it needs),
    the first one (the description) always kept; while they and a bar of MIN_BAR_WIDTH do
    not fit, the field with the largest priority number goes. The bar comes second and
    takes the room left, up to MAX_BAR_WIDTH."""
    kept = list(fields)
    while len(kept) > 1 and sum(w + 1 for _, _, w in kept) + MIN_BAR_WIDTH > width:
        kept.remove(max(kept[1:], key=lambda field: field[0]))
    bar = BarColumn(bar_width=None, table_column=Column(max_width=MAX_BAR_WIDTH))
    columns = [column for _, column, _ in kept]
    return [columns[0], bar, *columns[1:]]
