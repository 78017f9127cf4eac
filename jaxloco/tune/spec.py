"""Tune specs: a TOML file (or a dict) -> a validated, resolved `TuneSpec`.

Structure is checked with pydantic (the sweep spec's models and messages), meaning
against the objective registry. Every user mistake raises `SpecError` with one line:
`<source>: <key>: <problem>`.

Spec format::

    [tune]
    objective = "snake.kv"         # required (see `jaxloco objectives`)
    name = "..."                   # letters, digits, _ - . (default: the file stem, other
                                   # characters replaced by _; "tune" for a dict)
    output = "results/..."         # default: results/<name>, relative to the working directory
    optimizer = "adam"             # adam, sgd or adamw (optax)
    learning_rate = 0.05           # > 0 and <= 10, in the optimised (unconstrained) coordinates
    steps = 100                    # optimizer updates, 1..1,000,000
    params = ["a", "b"]            # the tunables to optimise (the others stay at [init])
    clip_norm = 1.0                # optional: clip the gradient's global norm (> 0 and <= 1e6)
    formats = ["parquet", "csv"]   # parquet is always written; drop "csv" to skip the CSVs

    [init]                         # starting values of tunables (default: their defaults);
                                   # a tunable not in params keeps this value throughout
    [settings]                     # the objective's fixed settings (default: their defaults)

    [validate]                     # optional: `jaxloco tune --validate` hands the compared
    sweep = "other_sweep.toml"     #   sets to this sweep spec (path relative to this file)
    map = {a = "a"}                #   tunable -> sweep parameter (default: equal names)
    labels = ["initial", "tuned"]  #   which rows of tuned.parquet (default: all)
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BeforeValidator, Field

from jaxloco import paths, specs
from jaxloco.errors import SpecError
from jaxloco.sweep.spec import plain_data
from jaxloco.sweep.spec_model import (
    NonEmptyStr,
    PlainName,
    StrictModel,
    bounded,
    error,
    name_from_stem,
    read_toml,
    validate,
)
from jaxloco.tune import objective as registry
from jaxloco.tune.objective import Objective

OPTIMIZERS = ("adam", "sgd", "adamw")
MAX_STEPS = 1_000_000
MAX_LEARNING_RATE = 10.0  # in the unconstrained coordinates; the shipped specs use 0.05..0.15
MAX_CLIP_NORM = 1e6


def _fspath(v: Any) -> Any:
    return os.fspath(v) if isinstance(v, os.PathLike) else v


class TuneSection(StrictModel):
    objective: NonEmptyStr
    name: PlainName | None = None
    output: Annotated[NonEmptyStr, BeforeValidator(_fspath)] | None = None
    optimizer: Literal["adam", "sgd", "adamw"] = "adam"
    learning_rate: Annotated[float, bounded(0, MAX_LEARNING_RATE, lo_open=True)] = 0.05
    steps: Annotated[int, bounded(1, MAX_STEPS)] = 100
    params: list[NonEmptyStr]
    clip_norm: Annotated[float, bounded(0, MAX_CLIP_NORM, lo_open=True)] | None = None
    formats: list[Literal["parquet", "csv"]] = ["parquet", "csv"]


class ValidateSection(StrictModel):
    sweep: Annotated[NonEmptyStr, BeforeValidator(_fspath)]
    map: dict[str, NonEmptyStr] | None = None
    labels: list[NonEmptyStr] | None = Field(None, min_length=1)


class TuneDoc(StrictModel):
    tune: TuneSection
    init: dict[str, Any] = {}
    settings: dict[str, Any] = {}
    validation: ValidateSection | None = Field(None, alias="validate")


@dataclass(frozen=True)
class Validation:
    """Where `jaxloco tune --validate` sends the compared sets: a sweep spec (resolved
    path), the mapping tunable -> sweep parameter (None: equal names) and the labels."""

    sweep: Path
    mapping: Mapping[str, str] | None = None
    labels: tuple[str, ...] | None = None


@dataclass(frozen=True, eq=False)
class TuneSpec:
    """A validated tuning run. `init` holds every tunable's starting value and `settings`
    every setting, in the objective's order, already checked."""

    objective: Objective
    name: str
    output: Path
    optimizer: str
    learning_rate: float
    steps: int
    params: tuple[str, ...]
    clip_norm: float | None
    init: Mapping[str, float]
    settings: Mapping[str, Any]
    formats: tuple[str, ...]
    source: str
    validation: Validation | None = None

    def content(self) -> dict[str, Any]:
        """What decides the run (recorded in the output files' metadata)."""
        return {
            "objective": self.objective.name,
            "optimizer": self.optimizer,
            "learning_rate": self.learning_rate,
            "steps": self.steps,
            "params": list(self.params),
            "clip_norm": self.clip_norm,
            "init": dict(self.init),
            "settings": {k: v if isinstance(v, (str, int, float, bool)) else repr(v) for k, v in self.settings.items()},
        }

    def with_options(self, *, output: str | Path | None = None, steps: int | None = None) -> TuneSpec:
        """This spec with command-line overrides applied (validated)."""
        changes: dict[str, Any] = {}
        if output is not None:
            changes["output"] = Path(output)
        if steps is not None:
            if isinstance(steps, bool) or not isinstance(steps, int) or not 1 <= steps <= MAX_STEPS:
                raise SpecError(f"--steps: must be an integer >= 1 and <= {MAX_STEPS:,}, got {steps!r}")
            changes["steps"] = steps
        return replace(self, **changes)


def load_spec(path: str | Path) -> TuneSpec:
    """Read and validate a TOML tune spec, given by path or by a bundled spec's name
    (`jaxloco.specs`); SpecError (one line, naming the file) if wrong."""
    path = specs.resolve(path)
    return _resolve(read_toml(path), os.fspath(path), default_name=path.stem)


def spec_from_dict(d: Mapping[str, Any], source: str = "<dict>") -> TuneSpec:
    """Validate a spec given as a dict with the TOML layout ({"tune": ..., "init": ...})."""
    if not isinstance(d, Mapping):
        raise SpecError(f"{source}: expected a mapping with a 'tune' table, got {type(d).__name__}")
    return _resolve(plain_data(d), source, default_name="tune")


def _resolve(doc: Mapping[str, Any], source: str, default_name: str) -> TuneSpec:
    raw: TuneDoc = validate(TuneDoc, doc, source)
    sec = raw.tune
    try:
        objective = registry.get(sec.objective)
    except SpecError as exc:
        raise error(source, "tune.objective", str(exc)) from None
    try:
        if not sec.params:
            raise SpecError("tune.params: empty list; name at least one tunable to optimise")
        for i, name in enumerate(sec.params):
            objective.tunable(name, where=f"tune.params[{i}]")
            if name in sec.params[:i]:
                raise SpecError(f"tune.params[{i}]: '{name}' is listed twice")
        given = {
            name: objective.tunable(name, where=f"init.{name}").check(value, where=f"init.{name}")
            for name, value in raw.init.items()
        }
        init = {t.name: given.get(t.name, t.default) for t in objective.tunables}
        chosen = {
            name: objective.setting(name, where=f"settings.{name}").check(value, where=f"settings.{name}")
            for name, value in raw.settings.items()
        }
        settings: dict[str, Any] = {}
        for p in objective.settings:
            if p.name in chosen:
                settings[p.name] = chosen[p.name]
            elif p.default is None:
                raise SpecError(f"settings.{p.name}: '{p.name}' has no default; set it in [settings]")
            else:
                settings[p.name] = p.check(p.default, where=f"default of {objective.name}.{p.name}")
    except SpecError as exc:
        raise SpecError(f"{source}: {exc}") from None

    validation = None
    if raw.validation is not None:
        validation = _validation(raw.validation, objective, source)
    name = sec.name or name_from_stem(default_name, source, "tune.name")
    return TuneSpec(
        objective=objective,
        name=name,
        output=Path(sec.output) if sec.output else Path("results") / name,
        optimizer=sec.optimizer,
        learning_rate=sec.learning_rate,
        steps=sec.steps,
        params=tuple(sec.params),
        clip_norm=sec.clip_norm,
        init=init,
        settings=settings,
        formats=tuple(dict.fromkeys(["parquet", *sec.formats])),
        source=source,
        validation=validation,
    )


def _validation(sec: ValidateSection, objective: Objective, source: str) -> Validation:
    """Resolve [validate]: the sweep path relative to the tune spec's directory (the working
    directory for a dict), else a bundled spec of that name, checked to load, and the
    mapping's names checked both ways."""
    from jaxloco.sweep.spec import load_spec as load_sweep

    path = Path(sec.sweep)
    if not path.is_absolute() and source != "<dict>":
        path = Path(source).parent / path
    if not paths.is_file(path, where=f"{source}: validate.sweep"):
        if not specs.is_plain_name(sec.sweep):
            raise error(source, "validate.sweep", f"no sweep spec at {path}")
        try:
            path = specs.path(sec.sweep)
        except SpecError as exc:
            raise error(source, "validate.sweep", f"no sweep spec at {path}; {exc}") from None
    sweep = load_sweep(path)
    mapping = dict(sec.map) if sec.map is not None else None
    if mapping is not None:
        for tunable, param in mapping.items():
            try:
                objective.tunable(tunable, where=f"validate.map.{tunable}")
                sweep.analysis.param(param, where=f"validate.map.{tunable}")
            except SpecError as exc:
                raise SpecError(f"{source}: {exc}") from None
    elif not any(t.name in {p.name for p in sweep.analysis.params} for t in objective.tunables):
        raise error(source, "validate.map", f"no tunable is a parameter of '{sweep.analysis.name}'; give map")
    if sec.labels is not None:
        known = ["initial", "tuned", *objective.references]
        for i, label in enumerate(sec.labels):
            if label not in known:
                raise error(source, f"validate.labels[{i}]", f"'{label}' is not one of {', '.join(known)}")
    return Validation(path, mapping, tuple(sec.labels) if sec.labels is not None else None)

