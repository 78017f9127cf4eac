"""The files of a tuning run (written atomically with the sweep store's `atomic_write`).

    <output>/loss_curve.parquet   one row per evaluated step: step, loss, grad_norm,
                                  every tunable, every aux metric (step 0 = initial values)
    <output>/tuned.parquet        one row per compared parameter set: label ("initial",
                                  "tuned" = the best-loss step, then the references),
                                  step, loss, every tunable, every aux metric
    <output>/*.csv                the same tables, when "csv" is in the spec's formats
    <output>/loss_curve.png       loss against step, when matplotlib is installed

The schema metadata key `jaxloco` holds JSON: the objective, the resolved spec, the best
step and the jaxloco/JAX versions. Other files in the directory are left alone.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.csv as pa_csv
import pyarrow.parquet as pq

from jaxloco.sweep.schema import METADATA_KEY
from jaxloco.sweep.store import atomic_write
from jaxloco.tune.spec import TuneSpec

CURVE = "loss_curve"
TUNED = "tuned"
PLOT = "loss_curve.png"
RESERVED = ("label", "step", "loss", "grad_norm")


def all_files(out: Path) -> list[Path]:
    return [out / f"{stem}.{ext}" for stem in (CURVE, TUNED) for ext in ("parquet", "csv")] + [out / PLOT]


def _fields(spec: TuneSpec, aux: Sequence[str]) -> list[pa.Field]:
    fields = []
    for t in spec.objective.tunables:
        role = "tuned" if t.name in spec.params else "fixed"
        fields.append(pa.field(t.name, pa.float64(), metadata={"unit": t.unit, "doc": t.doc, "role": role}))
    fields.extend(pa.field(name, pa.float64(), metadata={"role": "metric"}) for name in aux)
    return fields


def metadata(spec: TuneSpec, versions: Mapping[str, str], best_step: int | None) -> dict[bytes, bytes]:
    objective = spec.objective
    description = {
        "kind": "tune",
        "objective": objective.name,
        "doc": objective.doc,
        "name": spec.name,
        "source": spec.source,
        "spec": spec.content(),
        "best_step": best_step,
        "tunables": [
            {"name": t.name, "unit": t.unit, "doc": t.doc, "scale": t.scale, "range": t.range_text()}
            for t in objective.tunables
        ],
        "references": {k: dict(v) for k, v in objective.references.items()},
        "versions": dict(versions),
        "written": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
    }
    return {METADATA_KEY: json.dumps(description).encode()}


def curve_table(
    spec: TuneSpec, rows: Mapping[str, Sequence[float]], aux: Sequence[str], meta: dict[bytes, bytes]
) -> pa.Table:
    """`rows`: column name -> one value per step ("step", "loss", "grad_norm", tunables, aux)."""
    schema = pa.schema(
        [
            pa.field("step", pa.int64(), metadata={"doc": "optimizer updates before this evaluation"}),
            pa.field("loss", pa.float64(), metadata={"role": "loss"}),
            pa.field(
                "grad_norm", pa.float64(), metadata={"doc": "global norm of the gradient in the optimised coordinates"}
            ),
            *_fields(spec, aux),
        ],
        metadata=meta,
    )
    return pa.Table.from_pydict({name: list(rows[name]) for name in schema.names}, schema=schema)


def comparison_table(
    spec: TuneSpec, rows: Sequence[Mapping[str, Any]], aux: Sequence[str], meta: dict[bytes, bytes]
) -> pa.Table:
    """One row per parameter set: dicts with label, step (None for references), loss, tunables, aux."""
    schema = pa.schema(
        [
            pa.field("label", pa.string()),
            pa.field("step", pa.int64(), metadata={"doc": "the curve's step (empty for references)"}),
            pa.field("loss", pa.float64(), metadata={"role": "loss"}),
            *_fields(spec, aux),
        ],
        metadata=meta,
    )
    return pa.Table.from_pylist([dict(row) for row in rows], schema=schema)


def write_tables(out: Path, tables: Mapping[str, pa.Table], formats: Sequence[str]) -> list[Path]:
    """Each table as <stem>.parquet (and <stem>.csv); returns the paths written."""
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for stem, table in tables.items():
        path = out / f"{stem}.parquet"
        atomic_write(path, lambda tmp, table=table: pq.write_table(table, tmp))
        written.append(path)
        if "csv" in formats:
            path = out / f"{stem}.csv"
            atomic_write(path, lambda tmp, table=table: pa_csv.write_csv(table, tmp))
            written.append(path)
    return written


def plot_curve(out: Path, steps: Sequence[int], losses: Sequence[float], best_step: int, title: str) -> Path | None:
    """loss_curve.png (log y when every loss is > 0); None when matplotlib is not installed."""
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError:
        return None
    fig = Figure(figsize=(6.0, 3.6), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    ax.plot(steps, losses, lw=1.2)
    finite = [v for v in losses if math.isfinite(v)]
    if finite and min(finite) > 0:
        ax.set_yscale("log")
    ax.axvline(best_step, color="0.6", ls="--", lw=0.8, label=f"best (step {best_step})")
    ax.set_xlabel("step")
    ax.set_ylabel("loss")
    ax.set_title(title, fontsize=10)
    ax.legend(loc="upper right", fontsize=8)
    path = out / PLOT
    atomic_write(path, lambda tmp: fig.savefig(tmp, format="png", dpi=120))
    return path
