"""The rows of a sweep: the spec's swept values combined in a fixed, documented order.

Row r (0 <= r < n_rows) is parameter combination r // n_seeds with seed
seeds[r % n_seeds] (seeds innermost). Combinations are the product of the spec's factors
(groups of zipped parameters, in [params] order) in C order: the last factor varies
fastest. Rows are produced on demand, so a large sweep never holds all of them at once.
Axes are numpy arrays of the parameter's kind: float64, int64, bool, or unicode ("<U..")
for a string parameter with choices (a categorical axis, e.g. a task name).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from jaxloco.sweep.spec import SweepSpec

_NUMPY_KIND = {"float": np.float64, "int": np.int64, "bool": np.bool_, "str": np.str_}


@dataclass(frozen=True, eq=False)
class Grid:
    """The expanded rows of a sweep. `axes[name]` holds a swept parameter's own values."""

    axes: dict[str, np.ndarray]
    factors: tuple[tuple[str, ...], ...]
    seed_values: np.ndarray  # the distinct seeds, in spec order
    n_rows: int

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(len(self.axes[f[0]]) for f in self.factors)

    def __len__(self) -> int:
        return self.n_rows

    def rows(self, start: int, stop: int) -> tuple[dict[str, np.ndarray], np.ndarray]:
        """Swept values and seed positions (indices into `seed_values`) of rows [start, stop)."""
        if not 0 <= start <= stop <= self.n_rows:
            raise IndexError(f"rows [{start}, {stop}) outside [0, {self.n_rows})")
        r = np.arange(start, stop, dtype=np.int64)
        combo, seed_pos = np.divmod(r, len(self.seed_values))
        columns: dict[str, np.ndarray] = {}
        if self.factors:
            positions = np.unravel_index(combo, self.shape)
            for factor, pos in zip(self.factors, positions):
                for name in factor:
                    columns[name] = self.axes[name][pos]
        return columns, seed_pos

    @cached_property
    def columns(self) -> dict[str, np.ndarray]:
        """Every swept parameter's value on every row, plus "seed"."""
        columns, seed_pos = self.rows(0, self.n_rows)
        return {**columns, "seed": self.seed_values[seed_pos]}


def expand(spec: SweepSpec) -> Grid:
    """The grid of a validated spec (see the module doc for the row order)."""
    axes = {}
    for name, values in spec.swept.items():
        kind = spec.analysis.param(name).kind
        axes[name] = np.asarray(values, dtype=_NUMPY_KIND[kind])
    return Grid(
        axes=axes,
        factors=spec.factors,
        seed_values=np.asarray(spec.seeds, dtype=np.int64),
        n_rows=spec.n_rows,
    )


def chunk_bounds(n_rows: int, chunk_size: int) -> list[tuple[int, int]]:
    """[start, stop) of each chunk: consecutive slices of `chunk_size` rows, the last shorter."""
    return [(s, min(s + chunk_size, n_rows)) for s in range(0, n_rows, chunk_size)]
