"""Tune -> sweep hand-off: validate tuned values with a sweep (e.g. on the native MuJoCo
backend, over terrains the loss never saw).

A tuning run's `tuned.parquet` holds one row per compared parameter set ("initial",
"tuned", then the objective's references). `validation_spec` turns a sweep spec into
one whose mapped parameters take exactly those sets: they leave [fixed] / [params] and
become one zipped factor, placed first, so the sweep's other swept parameters and seeds
are crossed with every set. `compare` then reads the finished table back per set: the
rows, the fraction with status "ok" and the mean, min and max of every metric.

Mapping tunable -> sweep parameter: by default every tunable whose name is a parameter
of the sweep's analysis (the robots' objectives use the analyses' names on purpose);
give `mapping` to rename, e.g. {"gain_k": "gain_k"}. Sets whose mapped values are
equal (e.g. the initial values are a reference's) are run once and labelled together
("initial=default (ours)"). The tuned values must lie in the sweep parameter's range, else
SpecError says which one. Importing this module does not import JAX.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from jaxloco import paths
from jaxloco.errors import SpecError
from jaxloco.sweep.spec import SweepSpec

LABEL = "label"


@dataclass(frozen=True)
class ParamSet:
    """One compared parameter set: its label(s) and the mapped sweep parameters' values."""

    label: str
    values: Mapping[str, float]


def read_tuned(path: str | Path) -> tuple[pa.Table, Path]:
    """The comparison table of a tuning run: `path` is its output directory or its
    tuned.parquet / tuned.csv. Returns the table and the run's directory."""
    path = Path(path)
    if paths.is_dir(path):
        candidates = [path / "tuned.parquet", path / "tuned.csv"]
    else:
        candidates = [path]
    for candidate in candidates:
        if paths.is_file(candidate):
            try:
                if candidate.suffix == ".csv":
                    import pyarrow.csv as pa_csv

                    table = pa_csv.read_csv(candidate)
                else:
                    table = pq.read_table(candidate)
            except (pa.ArrowInvalid, OSError) as exc:
                raise SpecError(f"{candidate}: not a readable tuning table ({' '.join(str(exc).split())})") from None
            if LABEL not in table.column_names:
                raise SpecError(f"{candidate}: no '{LABEL}' column; expected the tuned.parquet of `jaxloco tune`")
            return table, candidate.parent
    raise SpecError(f"{path}: no tuned.parquet here; run `jaxloco tune` first (or give its output directory)")


def param_sets(
    table: pa.Table, spec: SweepSpec, mapping: Mapping[str, str] | None = None, labels: Sequence[str] | None = None
) -> tuple[list[ParamSet], dict[str, str]]:
    """The distinct parameter sets of a tuning table, as sweep parameter values (checked
    against the sweep analysis' ranges), and the mapping tunable -> sweep parameter used."""
    analysis = spec.analysis
    columns = [c for c in table.column_names if c not in (LABEL, "step", "loss")]
    roles = {c: (table.schema.field(c).metadata or {}).get(b"role") for c in columns}
    if any(role is not None for role in roles.values()):  # parquet: only the tunables' columns
        columns = [c for c in columns if roles[c] in (b"tuned", b"fixed")]
    if mapping is None:
        known = {p.name for p in analysis.params}
        mapping = {c: c for c in columns if c in known}
        if not mapping:
            raise SpecError(
                f"no tunable of the tuning table ({', '.join(columns) or 'none'}) is a parameter of "
                f"analysis '{analysis.name}'; give the mapping tunable -> parameter"
            )
    for tunable, param in mapping.items():
        if tunable not in table.column_names:
            raise SpecError(f"map: '{tunable}' is not a column of the tuning table")
        analysis.param(param, where=f"map.{tunable}")
    rows = table.to_pylist()
    present = [row[LABEL] for row in rows]
    wanted = list(labels) if labels is not None else present
    for label in wanted:
        if label not in present:
            raise SpecError(f"labels: no row '{label}' in the tuning table (has: {', '.join(present)})")
    sets: list[ParamSet] = []
    for row in rows:
        if row[LABEL] not in wanted:
            continue
        values = {}
        for tunable, param in mapping.items():
            value = row[tunable]
            if value is None or not math.isfinite(float(value)):
                raise SpecError(f"row '{row[LABEL]}': {tunable} is not a finite number")
            values[param] = analysis.param(param).check(float(value), where=f"{row[LABEL]}.{tunable} -> {param}")
        for existing in sets:
            if existing.values == values:
                sets[sets.index(existing)] = replace(existing, label=f"{existing.label}={row[LABEL]}")
                break
        else:
            sets.append(ParamSet(row[LABEL], values))
    return sets, dict(mapping)


def validation_spec(spec: SweepSpec, sets: Sequence[ParamSet], output: str | Path | None = None) -> SweepSpec:
    """`spec` with the sets' parameters zipped into one factor, first (slowest) in the row order."""
    if not sets:
        raise SpecError("no parameter sets to validate")
    names = list(sets[0].values)
    for name in names:
        param = spec.analysis.param(name)
        if not param.sweepable or param.kind == "str":
            raise SpecError(f"{spec.source}: '{name}' cannot be swept, so tuned values cannot be handed to it")
    swept = {name: tuple(s.values[name] for s in sets) for name in names}
    swept.update({k: v for k, v in spec.swept.items() if k not in swept})
    factors = [tuple(names)]
    for factor in spec.factors:
        rest = tuple(n for n in factor if n not in names)
        if rest:
            factors.append(rest)
    fixed = {k: v for k, v in spec.fixed.items() if k not in names}
    changes: dict[str, Any] = {"swept": swept, "fixed": fixed, "factors": tuple(factors), "combine": "product"}
    changes["name"] = f"{spec.name}_validation"
    if output is not None:
        changes["output"] = Path(output)
    return replace(spec, **changes)


def labels_of(table: pa.Table, sets: Sequence[ParamSet]) -> np.ndarray:
    """The set label of every row of a validation sweep's table (matched on the values)."""
    out = np.full(table.num_rows, "", dtype=object)
    for s in sets:
        hit = np.ones(table.num_rows, dtype=bool)
        for name, value in s.values.items():
            column = np.asarray(table.column(name).to_numpy(zero_copy_only=False), dtype=float)
            hit &= np.isclose(column, value, rtol=1e-12, atol=0.0)
        out[hit] = s.label
    if (out == "").any():
        raise SpecError("the validation table has rows that match no tuned parameter set")
    return out


def compare(table: pa.Table, sets: Sequence[ParamSet], spec: SweepSpec) -> pa.Table:
    """One row per set: label, its values, rows, ok fraction and each metric's mean/min/max."""
    labels = labels_of(table, sets)
    status = np.asarray(table.column("status").to_pylist(), dtype=object) if "status" in table.column_names else None
    metrics = [m for m in spec.analysis.metrics if m.name in table.column_names and m.kind != "bool"]
    bools = [m for m in spec.analysis.metrics if m.name in table.column_names and m.kind == "bool"]
    records = []
    for s in sets:
        mask = labels == s.label
        record: dict[str, Any] = {LABEL: s.label, **{k: float(v) for k, v in s.values.items()}}
        record["rows"] = int(mask.sum())
        if status is not None:
            record["ok_fraction"] = float(np.mean(status[mask] == "ok"))
        for m in bools:
            record[f"{m.name}_fraction"] = float(np.mean(np.asarray(table.column(m.name).to_pylist())[mask]))
        for m in metrics:
            values = np.asarray(table.column(m.name).to_numpy(zero_copy_only=False), dtype=float)[mask]
            finite = values[np.isfinite(values)]
            for stat, fn in (("mean", np.mean), ("min", np.min), ("max", np.max)):
                record[f"{m.name}_{stat}"] = float(fn(finite)) if finite.size else math.nan
        records.append(record)
    return pa.Table.from_pylist(records)


@dataclass(frozen=True)
class Validated:
    """A finished validation: the sets, the mapping, the sweep's result and the comparison."""

    sets: tuple[ParamSet, ...]
    mapping: Mapping[str, str]
    sweep: Any  # jaxloco.sweep.runner.SweepResult
    comparison: pa.Table
    written: tuple[Path, ...]


def validate(
    tuned: str | Path | pa.Table,
    sweep: SweepSpec | str | Path,
    *,
    mapping: Mapping[str, str] | None = None,
    labels: Sequence[str] | None = None,
    output: str | Path | None = None,
    progress: bool = True,
    **run_options: Any,
) -> Validated:
    """Run `sweep` once per parameter set of a tuning run and compare the sets.

    tuned: the tuning run's directory / tuned.parquet, or its comparison table (then give
    `output`). output: the validation sweep's directory (default: <tuning dir>/validation);
    a finished or interrupted validation of the same sets there is resumed, one of other
    sets replaced. run_options go to `jaxloco.sweep.run` (e.g. executor options).
    Writes validation.parquet / .csv next to the sweep's table.
    """
    from jaxloco.sweep import runner, store
    from jaxloco.sweep.spec import load_spec

    if isinstance(tuned, pa.Table):
        table, base = tuned, None
    else:
        table, base = read_tuned(tuned)
    if not isinstance(sweep, SweepSpec):
        sweep = load_spec(sweep)
    if output is None:
        if base is None:
            raise SpecError("validate: give an output directory for the validation sweep")
        output = base / "validation"
    sets, used = param_sets(table, sweep, mapping, labels)
    spec = validation_spec(sweep, sets, output=output)
    out = spec.output
    manifest = out / store.MANIFEST
    same = paths.is_file(manifest, where="output") and store.read_manifest(out).get("spec_hash") == spec.hash
    result = runner.run(spec, resume=same, overwrite=not same and paths.exists(out) and any(out.iterdir()),
                        progress=progress, **run_options)
    comparison = compare(result.table, sets, spec)
    written = write_comparison(out, comparison)
    return Validated(tuple(sets), used, result, comparison, tuple(written))


def write_comparison(out: Path, comparison: pa.Table, csv: bool = True) -> list[Path]:
    """validation.parquet (and .csv) in `out`."""
    from jaxloco.tune.output import write_tables

    return write_tables(out, {"validation": comparison}, ["parquet", "csv"] if csv else ["parquet"])


__all__ = [
    "ParamSet",
    "Validated",
    "validate",
    "compare",
    "labels_of",
    "param_sets",
    "read_tuned",
    "validation_spec",
    "write_comparison",
]
