"""Pinned sweep tables: the small sweeps the suite runs keep giving the same table.

`check_table(table)` compares a sweep's table (its swept columns, metrics and statuses)
with the one stored in `tests/data/tables/<analysis>-<spec hash>.json`, NaN-aware, floats
within RTOL / ATOL (other machines' CPUs and MuJoCo builds round differently). A change
that is meant to change results rewrites them:

    JAXLOCO_WRITE_TABLES=1 python -m pytest tests/test_compile_once.py tests/test_leggrope_analysis.py ...

and the diff of the JSON files shows what changed. `benchmarks/compare_specs.py` is the
full-size check (every bundled spec against another revision).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

DIR = Path(__file__).resolve().parent / "data" / "tables"
# Other XLA versions order float operations differently: with jax 0.11.2 (Python 3.12; CI
# runs 0.10.2) a 40 s closed loop of the snake's door moved by 1.0e-6 relative and a
# near-zero support capacity of the leg-grope walk by 1.4e-8 N (7 Dec 2026). Changes
# meant to change results move them by orders of magnitude more.
RTOL, ATOL = 1e-5, 1e-7
WRITE = "JAXLOCO_WRITE_TABLES"


def _columns(table: Any) -> tuple[str, str, dict[str, list[Any]]]:
    meta = json.loads(table.schema.metadata[b"jaxloco"])
    names = [*meta["swept"], *(m["name"] for m in meta["metrics"]), "status", "seed"]
    columns = {n: table.column(n).to_pylist() for n in names if n in table.column_names}
    return meta["analysis"], meta["spec_hash"], columns


def path_of(analysis: str, spec_hash: str) -> Path:
    return DIR / f"{analysis}-{spec_hash[:12]}.json"


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, float) or isinstance(b, float):
        if a is None or b is None:
            return a is b
        fa, fb = float(a), float(b)
        if math.isnan(fa) or math.isnan(fb):
            return math.isnan(fa) and math.isnan(fb)
        return math.isclose(fa, fb, rel_tol=RTOL, abs_tol=ATOL)
    return a == b


def check_table(table: Any) -> None:
    """Assert that `table` matches its pinned table (or write it, with JAXLOCO_WRITE_TABLES=1)."""
    analysis, spec_hash, columns = _columns(table)
    path = path_of(analysis, spec_hash)
    if os.environ.get(WRITE):
        DIR.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps({"analysis": analysis, "spec_hash": spec_hash, "columns": columns}, indent=0,
                                   sort_keys=True) + "\n")
        return
    assert path.is_file(), f"no pinned table {path.name} for this sweep; write it with {WRITE}=1 (tests/tables.py)"
    pinned = json.loads(path.read_text())["columns"]
    assert sorted(pinned) == sorted(columns), f"{path.name}: columns {sorted(columns)}, pinned {sorted(pinned)}"
    bad = []
    for name, values in columns.items():
        rows = [i for i, (a, b) in enumerate(zip(values, pinned[name], strict=True)) if not _same(a, b)]
        if rows:
            i = rows[0]
            bad.append(f"{name} (rows {rows[:5]}: {values[i]!r}, pinned {pinned[name][i]!r})")
    assert not bad, f"{analysis}: the table differs from {path.name}: " + "; ".join(bad)
