"""What a tuning run returns (`jaxloco.tune.run`)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import pyarrow as pa

    from jaxloco.tune.spec import TuneSpec


@dataclass(frozen=True)
class TuneResult:
    """The loss curve, the comparison table (initial, tuned, references) and the files written."""

    spec: TuneSpec
    path: Path
    curve: pa.Table
    comparison: pa.Table
    best_step: int
    written: tuple[Path, ...] = ()
    warnings: tuple[str, ...] = ()

    def row(self, label: str) -> dict[str, Any]:
        """The comparison row called `label` ("initial", "tuned" or a reference name)."""
        for row in self.comparison.to_pylist():
            if row["label"] == label:
                return row
        raise KeyError(label)

    def values(self, label: str = "tuned") -> dict[str, float]:
        """Every tunable's value in the row `label`."""
        row = self.row(label)
        return {t.name: row[t.name] for t in self.spec.objective.tunables}
