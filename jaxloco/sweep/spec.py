"""Sweep specs: a TOML file (or a dict) -> a validated, resolved `SweepSpec`.

Structure (unknown keys, types, required keys) is checked with pydantic; meaning
(parameter names, ranges, fixed-vs-swept, zip groups) against the analysis registry.
Every user mistake raises `SpecError` with one line: `<source>: <key>: <problem>`.

Spec format::

    [sweep]
    analysis = "robot.analysis"   # required
    name = "..."                  # letters, digits, _ - . (default: the file stem, other characters
                                  # replaced by _; "sweep" for a dict)
    output = "results/..."        # default: results/<name>, relative to the working directory
    chunk_size = 256              # rows per compiled batch, >= 1
    seeds = [0]                   # list of distinct ints in [0, 2**31), or N meaning 0..N-1
    combine = "product"           # or "zip": every swept list zipped together
    zip = [["a", "b"]]            # with "product": groups zipped, groups then combined
    formats = ["parquet"]         # add "csv" for table.csv

    [fixed]                       # non-swept values overriding the analysis defaults
    [params]                      # swept: a list, or {start, stop, num[, scale="log"]},
                                  # or {start, stop, step}; a string parameter with
                                  # choices (host analyses only): a list of its choices,
                                  # e.g. task = ["step1", "step2_front"]
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from jaxloco import analysis as registry
from jaxloco import specs
from jaxloco.analysis import Analysis, Param, sweep_problem
from jaxloco.errors import SpecError
from jaxloco.sim import backend
from jaxloco.sweep import ranges
from jaxloco.sweep.spec_model import (
    MAX_ROWS,
    RangeModel,
    SpecDoc,
    SweepSection,
    error,
    name_from_stem,
    read_toml,
    validate,
)

# ------------------------------------------------------------------------ the spec


@dataclass(frozen=True, eq=False)
class SweepSpec:
    """A validated sweep. Values are already checked and coerced by `Param.check`.

    fixed: every parameter that is not swept (defaults overridden by [fixed]), in the
    analysis' parameter order. swept: parameter -> its values, in [params] order.
    factors: groups of swept names combined as a product, in [params] order (a group of
    several names is zipped). Row order: the product of the factors with the last one
    varying fastest; each parameter set is repeated for every seed (seeds innermost).
    """

    analysis: Analysis
    name: str
    output: Path
    chunk_size: int
    seeds: tuple[int, ...]
    fixed: Mapping[str, Any]
    swept: Mapping[str, tuple[Any, ...]]
    factors: tuple[tuple[str, ...], ...]
    combine: str
    formats: tuple[str, ...]
    source: str

    @property
    def n_combinations(self) -> int:
        return math.prod(len(self.swept[f[0]]) for f in self.factors)

    @property
    def n_rows(self) -> int:
        return self.n_combinations * len(self.seeds)

    @property
    def n_chunks(self) -> int:
        return -(-self.n_rows // self.chunk_size)

    def content(self) -> dict[str, Any]:
        """The normalized content that decides the rows and chunks (what `hash` covers)."""
        return {
            "analysis": self.analysis.name,
            "fixed": dict(self.fixed),
            "swept": [[name, list(values)] for name, values in self.swept.items()],
            "factors": [list(f) for f in self.factors],
            "seeds": list(self.seeds),
            "chunk_size": self.chunk_size,
        }

    @property
    def hash(self) -> str:
        text = json.dumps(self.content(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()

    def with_options(
        self, *, output: str | Path | None = None, chunk_size: int | None = None, csv: bool | None = None
    ) -> SweepSpec:
        """This spec with command-line overrides applied (validated)."""
        changes: dict[str, Any] = {}
        if output is not None:
            changes["output"] = Path(output)
        if chunk_size is not None:
            if isinstance(chunk_size, bool) or not isinstance(chunk_size, int) or chunk_size < 1:
                raise SpecError(f"--chunk-size: must be an integer >= 1, got {chunk_size!r}")
            changes["chunk_size"] = chunk_size
        if csv is not None:
            formats = [f for f in self.formats if f != "csv"] + (["csv"] if csv else [])
            changes["formats"] = tuple(formats)
        return replace(self, **changes)


def load_spec(path: str | Path) -> SweepSpec:
    """Read and validate a TOML sweep spec, given by path or by a bundled spec's name
    (`jaxloco.specs`); SpecError (one line, naming the file) if wrong."""
    path = specs.resolve(path)
    return _resolve(read_toml(path), os.fspath(path), default_name=path.stem)


def spec_from_dict(d: Mapping[str, Any], source: str = "<dict>") -> SweepSpec:
    """Validate a spec given as a dict with the TOML layout ({"sweep": ..., "params": ...})."""
    if not isinstance(d, Mapping):
        raise SpecError(f"{source}: expected a mapping with a 'sweep' table, got {type(d).__name__}")
    return _resolve(plain_data(d), source, default_name="sweep")


def plain_data(value: Any) -> Any:
    """numpy scalars/arrays and tuples -> the plain types a TOML file would give."""
    if isinstance(value, Mapping):
        return {k: plain_data(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain_data(v) for v in value]
    if type(value).__module__ == "numpy":
        tolist = getattr(value, "tolist", None)
        return plain_data(tolist()) if tolist else value
    return value


# --------------------------------------------------------------------- resolution


def _resolve(doc: Mapping[str, Any], source: str, default_name: str) -> SweepSpec:
    raw: SpecDoc = validate(SpecDoc, doc, source)
    sec = raw.sweep

    def fail(key: str, problem: str) -> SpecError:
        return error(source, key, problem)

    try:
        analysis = registry.get(sec.analysis)
    except SpecError as exc:
        raise fail("sweep.analysis", str(exc)) from None

    try:
        given_fixed = {
            name: analysis.param(name, where=f"fixed.{name}").check(value, where=f"fixed.{name}")
            for name, value in raw.fixed.items()
        }
        swept: dict[str, tuple[Any, ...]] = {}
        for name, entry in raw.params.items():
            where = f"params.{name}"
            param = analysis.param(name, where=where)
            if name in raw.fixed:
                raise fail(where, f"'{name}' is also set in [fixed]; a parameter is either fixed or swept")
            problem = sweep_problem(param, analysis.executor)
            if problem:
                raise fail(where, problem)
            swept[name] = _swept_values(param, entry, where, source)
    except SpecError as exc:
        msg = str(exc)
        raise (exc if msg.startswith(f"{source}: ") else SpecError(f"{source}: {msg}")) from None

    factors = _factors(sec, swept, analysis, source)

    fixed: dict[str, Any] = {}
    for param in analysis.params:
        if param.name in swept:
            continue
        if param.name in given_fixed:
            fixed[param.name] = given_fixed[param.name]
        elif param.default is None:
            raise fail(
                f"fixed.{param.name}", f"'{param.name}' has no default; set it in [fixed] or sweep it in [params]"
            )
        else:
            fixed[param.name] = param.check(param.default, where=f"default of {analysis.name}.{param.name}")

    fixed = backend.resolved(fixed)  # "auto": the table records the simulator that runs
    name = sec.name or name_from_stem(default_name, source, "sweep.name")
    spec = SweepSpec(
        analysis=analysis,
        name=name,
        output=Path(sec.output) if sec.output else Path("results") / name,
        chunk_size=sec.chunk_size,
        seeds=tuple(sec.seeds),
        fixed=fixed,
        swept=swept,
        factors=factors,
        combine=sec.combine,
        formats=tuple(dict.fromkeys(["parquet", *sec.formats])),
        source=source,
    )
    if spec.n_rows > MAX_ROWS:
        raise fail("params", f"the sweep has {spec.n_rows:,} rows, more than the limit of {MAX_ROWS:,}")
    return spec


def _swept_values(param: Param, entry: Any, where: str, source: str) -> tuple[Any, ...]:
    if isinstance(entry, list):
        if not entry:
            raise SpecError(f"{where}: empty list; give at least one value")
        return tuple(param.check(v, where=f"{where}[{i}]") for i, v in enumerate(entry))
    if isinstance(entry, dict):
        if param.kind == "str":
            raise SpecError(
                f"{where}: a range needs a numeric parameter; '{param.name}' is a string: list its values"
                f" ({param.range_text()})"
            )
        if param.kind not in ("float", "int"):
            raise SpecError(
                f"{where}: a range needs a numeric parameter ('{param.name}' is {param.kind}); list the values"
            )
        rng: RangeModel = validate(RangeModel, entry, source, prefix=tuple(where.split(".")))
        values = _range_values(rng, where)
        if param.kind == "int":
            values = [_as_int(v) for v in values]
        return tuple(param.check(v, where=f"{where}[{i}]") for i, v in enumerate(values))
    forms = "a list of values or a range {start, stop, num} / {start, stop, step}"
    raise SpecError(f"{where}: expected {forms}, got {entry!r}; a single value belongs in [fixed]")


def _range_values(rng: RangeModel, where: str) -> list[float]:
    if rng.num is None and rng.step is None:
        raise SpecError(f"{where}: a range needs num or step")
    if rng.num is not None and rng.step is not None:
        raise SpecError(f"{where}: give num or step, not both")
    if rng.scale == "log":
        if rng.step is not None:
            raise SpecError(f'{where}.scale: "log" needs num, not step')
        for key in ("start", "stop"):
            if getattr(rng, key) <= 0:
                raise SpecError(f"{where}.{key}: log scale needs a value > 0, got {getattr(rng, key):g}")
    if rng.num is not None:
        if rng.num > MAX_ROWS:
            raise SpecError(f"{where}.num: {rng.num:,} is more than the limit of {MAX_ROWS:,}")
        make = ranges.geomspace if rng.scale == "log" else ranges.linspace
        return make(rng.start, rng.stop, rng.num)
    assert rng.step is not None
    if rng.stop < rng.start:
        raise SpecError(f"{where}: empty range (stop {rng.stop:g} < start {rng.start:g} with a positive step)")
    count, _ = ranges.arange_count(rng.start, rng.stop, rng.step)
    if count > MAX_ROWS:
        raise SpecError(f"{where}.step: the range has {count:,} values, more than the limit of {MAX_ROWS:,}")
    return ranges.arange(rng.start, rng.stop, rng.step)


def _count(n: int) -> str:
    return f"{n} value" if n == 1 else f"{n} values"


def _as_int(v: float) -> float | int:
    """A range value for an int parameter: the integer when v is one (else v, which check rejects)."""
    r = round(v)
    return int(r) if abs(v - r) <= 1e-9 * max(1.0, abs(v)) else v


def _factors(
    sec: SweepSection, swept: dict[str, tuple[Any, ...]], analysis: Analysis, source: str
) -> tuple[tuple[str, ...], ...]:
    def fail(key: str, problem: str) -> SpecError:
        return error(source, key, problem)

    names = list(swept)
    if sec.combine == "zip":
        if sec.zip is not None:
            raise fail(
                "sweep.zip", 'only allowed with combine = "product" (combine = "zip" zips every swept parameter)'
            )
        for other in names[1:]:
            if len(swept[other]) != len(swept[names[0]]):
                raise fail(
                    f"params.{other}",
                    f"has {_count(len(swept[other]))} but params.{names[0]} has {_count(len(swept[names[0]]))}; "
                    'combine = "zip" needs equal lengths',
                )
        return (tuple(names),) if names else ()

    group_of: dict[str, int] = {}
    for gi, group in enumerate(sec.zip or []):
        if not group:
            raise fail(f"sweep.zip[{gi}]", "empty group")
        for j, name in enumerate(group):
            where = f"sweep.zip[{gi}][{j}]"
            if name not in swept:
                try:
                    analysis.param(name, where=where)
                except SpecError as exc:
                    raise SpecError(f"{source}: {exc}") from None
                raise fail(where, f"'{name}' is not swept (add it to [params])")
            if name in group_of:
                raise fail(where, f"'{name}' is already in sweep.zip[{group_of[name]}]")
            group_of[name] = gi
        lengths = {name: len(swept[name]) for name in group}
        if len(set(lengths.values())) > 1:
            listed = ", ".join(f"{n}: {k}" for n, k in lengths.items())
            raise fail(f"sweep.zip[{gi}]", f"zipped parameters need equal lengths, got {listed}")

    factors: list[tuple[str, ...]] = []
    seen: set[int] = set()
    for name in names:
        gi = group_of.get(name)
        if gi is None:
            factors.append((name,))
        elif gi not in seen:
            seen.add(gi)
            factors.append(tuple(n for n in names if group_of.get(n) == gi))
    return tuple(factors)
