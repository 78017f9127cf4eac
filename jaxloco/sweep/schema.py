"""The columns of a sweep table and how one chunk's results become an Arrow table.

Columns, in order: `row` (int64); every parameter of the analysis in its declared order
(float64 / int64 / bool / string); every metric (float64 / int64 / bool); `status`
(string, from `Analysis.statuses`); `seed` (int64); `analysis`, `jaxloco_version`,
`jax_version`, `mujoco_version` (strings). Each parameter and metric field carries
`unit`, `doc` and `role` field metadata (role "swept" or "fixed" for a parameter, a
swept string parameter included: its column is a string column like a fixed one's); the
schema metadata key `jaxloco` holds a JSON description of the analysis and the spec hash.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any

import numpy as np
import pyarrow as pa

from jaxloco.analysis import Analysis
from jaxloco.errors import AnalysisError

ARROW_KIND = {"float": pa.float64(), "int": pa.int64(), "bool": pa.bool_(), "str": pa.string()}
NUMPY_KIND = {"float": np.float64, "int": np.int64, "bool": np.bool_}
PROVENANCE = ("analysis", "jaxloco_version", "jax_version", "mujoco_version")
RESERVED = ("row", "status", "seed", *PROVENANCE)
METADATA_KEY = b"jaxloco"


def check_names(analysis: Analysis) -> None:
    """Parameter, metric and reserved column names must all differ."""
    names = [p.name for p in analysis.params] + [m.name for m in analysis.metrics] + list(RESERVED)
    clashes = sorted({n for n in names if names.count(n) > 1})
    if clashes:
        raise AnalysisError(f"analysis '{analysis.name}': column name(s) used twice: {', '.join(clashes)}")


def table_schema(analysis: Analysis, spec_hash: str, swept: tuple[str, ...] = ()) -> pa.Schema:
    def described(name: str, kind: str, unit: str, doc: str, role: str) -> pa.Field:
        return pa.field(name, ARROW_KIND[kind], metadata={"unit": unit, "doc": doc, "role": role})

    fields = [pa.field("row", pa.int64(), metadata={"doc": "row index in the sweep's order", "role": "index"})]
    for p in analysis.params:
        role = "swept" if p.name in swept else "fixed"
        fields.append(described(p.name, p.kind, p.unit, p.doc, role))
    for m in analysis.metrics:
        fields.append(described(m.name, m.kind, m.unit, m.doc, "metric"))
    status_doc = "one of: " + ", ".join(analysis.statuses)
    fields.append(pa.field("status", pa.string(), metadata={"doc": status_doc, "role": "status"}))
    fields.append(pa.field("seed", pa.int64(), metadata={"doc": "PRNG seed of the row", "role": "seed"}))
    fields.extend(pa.field(name, pa.string(), metadata={"role": "provenance"}) for name in PROVENANCE)
    description = {
        "analysis": analysis.name,
        "doc": analysis.doc,
        "spec_hash": spec_hash,
        "swept": list(swept),
        "params": [
            {
                "name": p.name,
                "kind": p.kind,
                "unit": p.unit,
                "doc": p.doc,
                "default": _jsonable(p.default),
                "range": p.range_text(),
            }
            for p in analysis.params
        ],
        "metrics": [{"name": m.name, "kind": m.kind, "unit": m.unit, "doc": m.doc} for m in analysis.metrics],
        "statuses": list(analysis.statuses),
    }
    return pa.schema(fields, metadata={METADATA_KEY: json.dumps(description).encode()})


def _jsonable(value: Any) -> Any:
    return value if isinstance(value, (str, int, float, bool, type(None))) else repr(value)


def chunk_table(
    schema: pa.Schema,
    analysis: Analysis,
    *,
    start: int,
    swept: Mapping[str, np.ndarray],
    fixed: Mapping[str, Any],
    seeds: np.ndarray,
    outputs: Mapping[str, np.ndarray],
    provenance: Mapping[str, str],
) -> pa.Table:
    """One chunk's rows. `outputs` are the analysis' metrics and status, already trimmed."""
    n = len(seeds)
    columns: list[pa.Array] = [pa.array(np.arange(start, start + n, dtype=np.int64))]
    for p in analysis.params:
        if p.name in swept:
            columns.append(pa.array(swept[p.name], type=ARROW_KIND[p.kind]))
        else:
            columns.append(pa.array([fixed[p.name]] * n, type=ARROW_KIND[p.kind]))
    for m in analysis.metrics:
        columns.append(pa.array(outputs[m.name], type=ARROW_KIND[m.kind]))
    labels = np.asarray(analysis.statuses, dtype=object)[outputs["status"]]
    columns.append(pa.array(labels.tolist(), type=pa.string()))
    columns.append(pa.array(np.asarray(seeds, dtype=np.int64)))
    for name in PROVENANCE:
        columns.append(pa.array([provenance[name]] * n, type=pa.string()))
    return pa.Table.from_arrays(columns, schema=schema)


def checked_outputs(analysis: Analysis, raw: Any, batch: int) -> dict[str, np.ndarray]:
    """The batch function's result as numpy arrays of the declared kinds, or AnalysisError."""
    if not isinstance(raw, Mapping):
        raise AnalysisError(
            f"analysis '{analysis.name}': batch function returned {type(raw).__name__}, expected a dict"
        )
    expected = {m.name for m in analysis.metrics} | {"status"}
    got = set(raw)
    if got != expected:
        missing, extra = sorted(expected - got), sorted(got - expected)
        raise AnalysisError(
            f"analysis '{analysis.name}': batch function returned the wrong keys"
            f" (missing: {', '.join(missing) or '-'}; undeclared: {', '.join(map(str, extra)) or '-'})"
        )
    out: dict[str, np.ndarray] = {}
    kinds = {m.name: m.kind for m in analysis.metrics}
    for name in expected:
        value = np.asarray(raw[name])
        if value.shape != (batch,):
            raise AnalysisError(f"analysis '{analysis.name}': '{name}' has shape {value.shape}, expected ({batch},)")
        if name == "status":
            if value.dtype.kind not in "iub":
                raise AnalysisError(f"analysis '{analysis.name}': 'status' must hold integer codes, got {value.dtype}")
            value = value.astype(np.int64)
            bad = value[(value < 0) | (value >= len(analysis.statuses))]
            if bad.size:
                raise AnalysisError(
                    f"analysis '{analysis.name}': status code {int(bad[0])} is not an index of its "
                    f"{len(analysis.statuses)} statuses"
                )
            out[name] = value
        else:
            out[name] = value.astype(NUMPY_KIND[kinds[name]])
    return out
