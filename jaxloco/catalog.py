"""The catalog: what `jaxloco analyses`, `describe` and `objectives` print about the
built-in analyses and objectives, in a JSON file (`jaxloco/catalog.json`) generated from
the registries, so that those commands print without importing the robots or JAX.

The registries (`jaxloco.analysis`, `jaxloco.tune.objective`) stay the source of truth.
After changing a built-in's metadata (a `Param`, `Metric`, `Tunable`, doc, ...) regenerate
the file (tests/test_catalog.py fails until then):

    python -m jaxloco.catalog --write

Reading the catalog imports neither JAX nor MuJoCo: entries come back as the real `Param`,
`Metric` and `Tunable` dataclasses inside small `AnalysisInfo` / `ObjectiveInfo` records.
A name registered at run time, a built-in missing from the file, or a missing or
unreadable file is looked up in the live registry instead (slow, but correct).
"""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Mapping
from dataclasses import dataclass, fields
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

from jaxloco import analysis as analysis_registry
from jaxloco.analysis import Metric, Param

if TYPE_CHECKING:
    from jaxloco.analysis import Analysis
    from jaxloco.registry import Registry
    from jaxloco.tune.objective import Objective, Tunable

FORMAT = 1
DEFAULT_PATH = Path(__file__).with_name("catalog.json")
WRITE_COMMAND = "python -m jaxloco.catalog --write"


@dataclass(frozen=True)
class AnalysisInfo:
    """What the listing commands show of an analysis (an `Analysis` without its functions)."""

    name: str
    doc: str
    params: tuple[Param, ...]
    metrics: tuple[Metric, ...]
    statuses: tuple[str, ...]
    x64: bool
    executor: str


@dataclass(frozen=True)
class ObjectiveInfo:
    """What the listing commands show of an objective (an `Objective` without its loss)."""

    name: str
    doc: str
    tunables: tuple[Tunable, ...]
    settings: tuple[Param, ...]
    references: Mapping[str, Mapping[str, float]]
    x64: bool
    grad_mode: str


_UNREADABLE = (OSError, ValueError, KeyError, TypeError, AttributeError)  # a missing or malformed file


@dataclass(frozen=True)
class Catalog:
    """The packaged entries by name; objectives are decoded on first access."""

    analyses: Mapping[str, AnalysisInfo]
    objectives: Mapping[str, ObjectiveInfo]


# ---- JSON values: tuples and non-finite floats, which JSON lacks, are tagged objects ----


def encode_value(value: Any) -> Any:
    """`value` as JSON data that `decode_value` turns back into an equal value."""
    if isinstance(value, float) and not math.isfinite(value):
        return {"$float": repr(value)}  # "inf", "-inf", "nan"
    if isinstance(value, tuple):
        return {"$tuple": [encode_value(v) for v in value]}
    if isinstance(value, list):
        return [encode_value(v) for v in value]
    if isinstance(value, Mapping):
        return {str(k): encode_value(v) for k, v in value.items()}
    return value


def decode_value(data: Any) -> Any:
    if isinstance(data, list):
        return [decode_value(v) for v in data]
    if isinstance(data, dict):
        if data.keys() == {"$float"}:
            return float(data["$float"])
        if data.keys() == {"$tuple"}:
            return tuple(decode_value(v) for v in data["$tuple"])
        return {k: decode_value(v) for k, v in data.items()}
    return data


def _record_to_data(record: Any) -> dict[str, Any]:
    """Every init field of a dataclass instance (Param, Metric, Tunable), encoded."""
    return {f.name: encode_value(getattr(record, f.name)) for f in fields(record) if f.init}


def _record_from_data(cls: type, data: Mapping[str, Any]) -> Any:
    return cls(**{key: decode_value(value) for key, value in data.items()})


# ---- building (imports every built-in analysis and objective) ----


def analysis_to_data(analysis: Analysis | AnalysisInfo) -> dict[str, Any]:
    return {
        "name": analysis.name,
        "doc": analysis.doc,
        "params": [_record_to_data(p) for p in analysis.params],
        "metrics": [_record_to_data(m) for m in analysis.metrics],
        "statuses": list(analysis.statuses),
        "x64": analysis.x64,
        "executor": analysis.executor,
    }


def objective_to_data(objective: Objective | ObjectiveInfo) -> dict[str, Any]:
    return {
        "name": objective.name,
        "doc": objective.doc,
        "tunables": [_record_to_data(t) for t in objective.tunables],
        "settings": [_record_to_data(p) for p in objective.settings],
        "references": encode_value(objective.references),
        "x64": objective.x64,
        "grad_mode": objective.grad_mode,
    }


def _load_builtins(table: Mapping[str, str]) -> dict[str, Any]:
    """Each entry of a registry's built-in table ("module:attribute") as code defines it
    (a fresh import, not a run-time override), by name."""
    from jaxloco.registry import load_reference

    return {name: load_reference(target) for name, target in sorted(table.items())}


def _builtin_analyses() -> dict[str, Analysis]:
    return _load_builtins(analysis_registry.ANALYSES.builtin)


def _builtin_objectives() -> dict[str, Objective]:
    from jaxloco.tune.objective import OBJECTIVES

    return _load_builtins(OBJECTIVES.builtin)


def build() -> dict[str, Any]:
    """The catalog data of every built-in analysis and objective (imports them all)."""
    return {
        "format": FORMAT,
        "regenerate": WRITE_COMMAND,
        "analyses": {name: analysis_to_data(a) for name, a in _builtin_analyses().items()},
        "objectives": {name: objective_to_data(o) for name, o in _builtin_objectives().items()},
    }


def dumps(data: Mapping[str, Any]) -> str:
    """The catalog file's text: stable (sorted keys, indented) so that diffs stay readable."""
    return json.dumps(data, indent=1, sort_keys=True, ensure_ascii=False, allow_nan=False) + "\n"


def write(path: Path | str | None = None) -> Path:
    """Build the catalog and write it to `path` (default: the packaged `catalog.json`)."""
    target = Path(path) if path is not None else DEFAULT_PATH
    target.write_text(dumps(build()), encoding="utf-8")
    return target


# ---- reading (imports neither the robots nor JAX) ----


def _analysis_from_data(data: Mapping[str, Any]) -> AnalysisInfo:
    return AnalysisInfo(
        name=data["name"],
        doc=data["doc"],
        params=tuple(_record_from_data(Param, p) for p in data["params"]),
        metrics=tuple(_record_from_data(Metric, m) for m in data["metrics"]),
        statuses=tuple(data["statuses"]),
        x64=data["x64"],
        executor=data["executor"],
    )


def _objective_from_data(data: Mapping[str, Any]) -> ObjectiveInfo:
    from jaxloco.tune.objective import Tunable  # the tune package: no JAX either

    references = decode_value(data["references"])
    return ObjectiveInfo(
        name=data["name"],
        doc=data["doc"],
        tunables=tuple(_record_from_data(Tunable, t) for t in data["tunables"]),
        settings=tuple(_record_from_data(Param, p) for p in data["settings"]),
        references=MappingProxyType({k: MappingProxyType(v) for k, v in references.items()}),
        x64=data["x64"],
        grad_mode=data["grad_mode"],
    )


class _LazyObjectives(Mapping):
    """Objective entries decoded on first access (decoding imports the tune package)."""

    def __init__(self, raw: Mapping[str, Any]) -> None:
        self._raw = raw
        self._done: dict[str, ObjectiveInfo] = {}

    def __getitem__(self, name: str) -> ObjectiveInfo:
        if name not in self._done:
            self._done[name] = _objective_from_data(self._raw[name])
        return self._done[name]

    def __contains__(self, name: object) -> bool:
        return name in self._raw

    def __iter__(self):
        return iter(self._raw)

    def __len__(self) -> int:
        return len(self._raw)


def load(path: Path | str | None = None) -> Catalog | None:
    """The catalog in `path` (default: the packaged one), or None if it is missing,
    unreadable or of another format."""
    try:
        text = Path(path).read_text(encoding="utf-8") if path is not None else _packaged_text()
        data = json.loads(text)
        if data.get("format") != FORMAT:
            return None
        analyses = {name: _analysis_from_data(entry) for name, entry in data["analyses"].items()}
        return Catalog(analyses=analyses, objectives=_LazyObjectives(data["objectives"]))
    except _UNREADABLE:
        return None


def _packaged_text() -> str:
    from importlib import resources

    return resources.files("jaxloco").joinpath("catalog.json").read_text(encoding="utf-8")


# ---- lookups for the CLI: the catalog for built-ins, the live registry for the rest ----


def _from_catalog(name: str, registry: Registry, entries: Mapping[str, Any] | None) -> bool:
    """Whether `name` is a built-in of `registry` that is not overridden or loaded yet
    and has an entry in the catalog."""
    builtin = name in registry.builtin and not registry.is_live(name)
    return builtin and entries is not None and name in entries


def analysis(name: str, catalog: Catalog | None) -> Analysis | AnalysisInfo:
    """What to show for analysis `name`: one registered at run time (or already loaded),
    else its catalog entry, else the live registry's (SpecError naming the known ones)."""
    if _from_catalog(name, analysis_registry.ANALYSES, catalog.analyses if catalog else None):
        return catalog.analyses[name]
    return analysis_registry.get(name)


def objective(name: str, catalog: Catalog | None) -> Objective | ObjectiveInfo:
    """Like `analysis`, for the objectives of `jaxloco tune`."""
    from jaxloco.tune import objective as objective_registry

    if _from_catalog(name, objective_registry.OBJECTIVES, catalog.objectives if catalog else None):
        try:
            return catalog.objectives[name]
        except _UNREADABLE:  # decoded only now: an entry that no longer fits `Tunable`, ...
            pass
    return objective_registry.get(name)


def main(argv: list[str] | None = None) -> int:
    """`python -m jaxloco.catalog --write [PATH]`: regenerate the catalog file."""
    args = list(sys.argv[1:] if argv is None else argv)
    if not args or args[0] != "--write" or len(args) > 2:
        print(f"usage: {WRITE_COMMAND} [PATH]", file=sys.stderr)
        return 2
    target = write(args[1] if len(args) == 2 else None)
    print(f"wrote {target}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
