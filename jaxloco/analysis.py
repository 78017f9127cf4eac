"""The registry of analyses that `jaxloco sweep` can run.

An *analysis* is a batched, jittable function from parameter values to metrics, plus
the description of its parameters (name, unit, range, default) and metrics. The sweep
layer only talks to this interface; robots register their analyses here.

Contract of `Analysis.make_batch_fn(fixed)`:
  * `fixed` maps every parameter that is *not* swept to a plain Python value (already
    validated with `Param.check`).
  * It returns `fn(swept, keys)` where `swept` maps each swept parameter name to an
    array of shape (B,) and `keys` is a (B, 2) uint32 array of PRNG keys (one per row,
    from the row's seed). `fn` is pure and jit-compatible; the caller jits it.
  * A string parameter (kind "str") can be swept only when it has `choices` and only by a
    host analysis (JAX arrays cannot hold strings): `swept[name]` is then a numpy unicode
    array (dtype "<U..") of the row's choices. See `sweep_problem`.
  * `fn` returns a dict with one (B,) array per metric in `Analysis.metrics` plus
    `"status"`: an int array indexing `Analysis.statuses` (0 means "ok").
  * executor "jax" (default): the runner jits `fn` and shards the batch over the JAX
    devices. executor "host": `fn` is called as it is with numpy arrays (it runs its own
    batched engine, e.g. the native MuJoCo backend of `jaxloco.sim`) once per chunk.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

from jaxloco.errors import SpecError
from jaxloco.registry import Registry, robot_entries

ParamKind = Literal["float", "int", "bool", "str"]


@dataclass(frozen=True)
class Param:
    """One input of an analysis.

    lo/hi bound the value (inclusive unless lo_open/hi_open). `sweepable=False` marks a
    parameter that changes array shapes or compiled structure: it may be set in a spec's
    fixed section but not swept. A string parameter is swept only with `choices` (a
    categorical one, e.g. a task name) and by a host analysis (`sweep_problem`).
    """

    name: str
    default: Any
    doc: str
    unit: str = ""
    kind: ParamKind = "float"
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    choices: tuple[Any, ...] | None = None
    sweepable: bool = True

    def range_text(self) -> str:
        if self.choices is not None:
            return "one of " + ", ".join(repr(c) for c in self.choices)
        if self.lo is None and self.hi is None:
            return "any"
        left = "(" if self.lo_open else "["
        right = ")" if self.hi_open else "]"
        lo = "-inf" if self.lo is None else f"{self.lo:g}"
        hi = "inf" if self.hi is None else f"{self.hi:g}"
        return f"{left}{lo}, {hi}{right}"

    def check(self, value: Any, where: str | None = None) -> Any:
        """Return `value` coerced to this parameter's kind, or raise SpecError (one line)."""
        label = where or self.name
        if self.kind == "bool":
            if not isinstance(value, bool):
                raise SpecError(f"{label}: expected true or false, got {value!r}")
            return value
        if self.kind == "str":
            if not isinstance(value, str):
                raise SpecError(f"{label}: expected a string, got {value!r}")
            out: Any = value
        elif self.kind == "int":
            if isinstance(value, bool) or not isinstance(value, int):
                raise SpecError(f"{label}: expected an integer, got {value!r}")
            out = int(value)
        else:
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise SpecError(f"{label}: expected a number, got {value!r}")
            out = float(value)
            if not math.isfinite(out):
                raise SpecError(f"{label}: expected a finite number, got {value!r}")
        if self.choices is not None and out not in self.choices:
            raise SpecError(f"{label}: {out!r} is not {self.range_text()}")
        if self.kind in ("int", "float"):
            bad_lo = self.lo is not None and (out <= self.lo if self.lo_open else out < self.lo)
            bad_hi = self.hi is not None and (out >= self.hi if self.hi_open else out > self.hi)
            if bad_lo or bad_hi:
                unit = f" {self.unit}" if self.unit else ""
                raise SpecError(f"{label}: {out:g}{unit} is outside {self.range_text()}")
        return out


def sweep_problem(param: Param, executor: str) -> str | None:
    """Why `param` cannot be swept by an analysis with `executor` ("jax", "host"), or None.

    Never swept: sweepable=False; a string without choices (free-form text is no axis);
    a string of a JAX analysis (its batch function is traced, and JAX takes no strings).
    """
    name = param.name
    if not param.sweepable:
        return f"'{name}' cannot be swept (it changes the compiled program); set it in [fixed]"
    if param.kind != "str":
        return None
    if param.choices is None:
        return f"'{name}' is a string parameter without choices; a swept string needs choices; set it in [fixed]"
    if executor != "host":
        return (
            f"'{name}' is a string parameter and this analysis runs under JAX (executor '{executor}'),"
            " which cannot take strings; set it in [fixed]"
        )
    return None


@dataclass(frozen=True)
class Metric:
    """One output column of an analysis (per parameter set)."""

    name: str
    doc: str
    unit: str = ""
    kind: Literal["float", "int", "bool"] = "float"


SummaryFn = Callable[[Any], "Summary"]


@dataclass(frozen=True)
class Summary:
    """A short human table: a title, column names and rows of already formatted cells."""

    title: str
    columns: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    notes: tuple[str, ...] = ()


def mean_worst(values: Any, worst: Literal["max", "min"] = "max", digits: int = 2) -> str:
    """A summary cell 'mean (worst)' over the finite values (worst: the largest or the
    smallest); '-' if there is none."""
    import numpy as np

    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    if not v.size:
        return "-"
    w = v.max() if worst == "max" else v.min()
    return f"{v.mean():.{digits}f} ({w:.{digits}f})"


@dataclass(frozen=True)
class Analysis:
    name: str
    doc: str
    params: tuple[Param, ...]
    metrics: tuple[Metric, ...]
    make_batch_fn: Callable[[Mapping[str, Any]], Callable[..., dict[str, Any]]]
    statuses: tuple[str, ...] = ("ok",)
    summarize: SummaryFn | None = None  # pyarrow.Table -> Summary
    x64: bool = True  # run in float64 (the CLI configures JAX accordingly)
    executor: Literal["jax", "host"] = "jax"
    _by_name: dict[str, Param] = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        names = [p.name for p in self.params]
        if len(set(names)) != len(names):
            raise ValueError(f"analysis {self.name}: duplicate parameter names")
        if not self.statuses or self.statuses[0] != "ok":
            raise ValueError(f"analysis {self.name}: statuses[0] must be 'ok'")
        self._by_name.update({p.name: p for p in self.params})

    def param(self, name: str, where: str | None = None) -> Param:
        try:
            return self._by_name[name]
        except KeyError:
            known = ", ".join(sorted(self._by_name))
            raise SpecError(
                f"{where or name}: unknown parameter '{name}' for analysis '{self.name}' (known: {known})"
            ) from None

    def defaults(self) -> dict[str, Any]:
        return {p.name: p.default for p in self.params}


# Built-in analyses come from the robots' entries modules (jaxloco.registry).
ANALYSES: Registry[Analysis] = Registry(
    "analysis", lambda: robot_entries("ANALYSES"), lambda entry: isinstance(entry, Analysis)
)


def register(analysis: Analysis) -> Analysis:
    """Add an analysis (e.g. from a plugin or a test); returns it."""
    return ANALYSES.register(analysis.name, analysis)


def names() -> list[str]:
    return ANALYSES.names()


def get(name: str) -> Analysis:
    """The analysis called `name`; SpecError naming the known ones if there is none."""
    return ANALYSES.get(name)


def is_builtin(name: str) -> bool:
    """Whether `name` is one of jaxloco's own analyses (importable anywhere by name)."""
    return name in ANALYSES.builtin
