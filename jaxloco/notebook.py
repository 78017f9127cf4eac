"""What the notebooks in `notebooks/` share: one switch between the full settings (what a
reader runs) and small ones (what the test suite runs, so the notebooks never rot), and
"load the table if it exists, else compute it".

    JAXLOCO_NOTEBOOK_SMALL=1   shrink every sweep (a few values per swept parameter,
                               one seed, shorter horizons) and every tuning (a few steps)
    JAXLOCO_NOTEBOOK_OUT=DIR   write results under DIR instead of ../results (relative to
                               notebooks/); with SMALL set and no OUT, a temporary directory
                               (removed when the process exits)

In small mode nothing is read from ../results, so the suite always executes the real
computation of every notebook, on small settings. Importing this module does not import JAX.
"""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

SMALL_ENV = "JAXLOCO_NOTEBOOK_SMALL"
OUT_ENV = "JAXLOCO_NOTEBOOK_OUT"

_TMP: dict[str, Path] = {}


def small() -> bool:
    """True when the notebook should run its small settings (JAXLOCO_NOTEBOOK_SMALL set, not 0)."""
    return os.environ.get(SMALL_ENV, "").strip() not in ("", "0", "false", "no")


def results_dir(name: str, default_root: str | Path = "../results") -> Path:
    """Where a notebook keeps the results called `name` (see the module doc)."""
    root = os.environ.get(OUT_ENV)
    if root:
        return Path(root) / name
    if small():
        if "root" not in _TMP:
            _TMP["root"] = _temporary_root()
        return _TMP["root"] / name
    return Path(default_root) / name


def _temporary_root() -> Path:
    """A new temporary directory for small-mode results, removed when the process exits."""
    root = Path(tempfile.mkdtemp(prefix="jaxloco_notebook_"))
    atexit.register(shutil.rmtree, root, ignore_errors=True)
    return root


def evenly(n: int, keep: int) -> list[int]:
    """`keep` indices spread evenly over range(n), first and last included (all when n <= keep)."""
    if keep < 1:
        raise ValueError("keep must be >= 1")
    if n <= keep:
        return list(range(n))
    if keep == 1:
        return [0]
    return sorted({int(round(i)) for i in np.linspace(0, n - 1, keep)})


def shrink(
    spec: Any,
    keep: int = 2,
    *,
    fixed: Mapping[str, Any] | None = None,
    keep_by_name: Mapping[str, int] | None = None,
    seeds: int = 1,
) -> Any:
    """A smaller copy of a SweepSpec: each swept factor keeps `keep` evenly spread values
    (`keep_by_name` per parameter; a zipped group by its first name), the first `seeds`
    seeds, and `fixed` overrides (checked against the analysis' ranges)."""
    keep_by_name = dict(keep_by_name or {})
    swept: dict[str, tuple[Any, ...]] = {}
    for factor in spec.factors:
        n = len(spec.swept[factor[0]])
        chosen = evenly(n, keep_by_name.get(factor[0], keep))
        for name in factor:
            swept[name] = tuple(spec.swept[name][i] for i in chosen)
    swept = {name: swept[name] for name in spec.swept}  # the spec's [params] order
    new_fixed = dict(spec.fixed)
    for name, value in (fixed or {}).items():
        param = spec.analysis.param(name, where=f"shrink.fixed.{name}")
        if name in swept:
            raise ValueError(f"shrink: '{name}' is swept; it cannot be fixed here")
        new_fixed[name] = param.check(value, where=f"shrink.fixed.{name}")
    return replace(spec, swept=swept, fixed=new_fixed, seeds=spec.seeds[:seeds], name=spec.name)


def sweep_table(spec_path: str | Path, name: str | None = None, *, small_options: Mapping[str, Any] | None = None,
                progress: bool = False):
    """The table of a sweep spec: read from results_dir(name) when it is there (full mode),
    else computed (resuming saved chunks). small_options go to `shrink` in small mode.
    Returns (pyarrow table, the SweepSpec that made it)."""
    from jaxloco.sweep import load_spec, run
    from jaxloco.sweep.summary import read_table

    spec = load_spec(spec_path)
    name = name or spec.name
    out = results_dir(name)
    if small():
        spec = shrink(spec, **dict(small_options or {}))
    table_path = out / "table.parquet"
    if table_path.is_file() and not small():
        table, _ = read_table(table_path)
        return table, spec.with_options(output=out)
    result = run(spec, output=out, resume=(out / "manifest.json").is_file(), progress=progress)
    return result.table, spec.with_options(output=out)


def tune_result(
    spec_path: str | Path,
    name: str | None = None,
    *,
    small_steps: int = 3,
    small_settings: Mapping[str, Any] | None = None,
    progress: bool = False,
):
    """The loss curve and comparison of a tune spec: read from results_dir(name) when there
    (full mode), else tuned (small mode: `small_steps` steps, the spec's settings updated
    with `small_settings`, each checked like a spec's). Returns (curve, comparison)."""
    import pyarrow.parquet as pq

    from jaxloco.tune import load_spec, run

    spec = load_spec(spec_path)
    name = name or spec.name
    out = results_dir(name)
    if not small() and (out / "tuned.parquet").is_file() and (out / "loss_curve.parquet").is_file():
        return pq.read_table(out / "loss_curve.parquet"), pq.read_table(out / "tuned.parquet")
    if small() and small_settings:
        checked = {}
        for key, value in small_settings.items():
            where = f"small_settings.{key}"
            checked[key] = spec.objective.setting(key, where=where).check(value, where=where)
        spec = replace(spec, settings={**spec.settings, **checked})
    result = run(spec, out=out, steps=small_steps if small() else None, progress=progress)
    return result.curve, result.comparison


__all__ = ["OUT_ENV", "SMALL_ENV", "evenly", "results_dir", "shrink", "small", "sweep_table", "tune_result"]
