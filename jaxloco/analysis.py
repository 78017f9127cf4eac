"""The registry of analyses that `jaxloco sweep` can run, and the one contract they follow.

An *analysis* describes its parameters (name, unit, range, default) and metrics, and
computes the metrics of parameter values in one of two ways:

  * a JAX analysis gives `row(values, key) -> metrics`: the metrics of ONE row. `values`
    maps every parameter, swept and fixed, already merged and validated: sweepable
    numbers as scalar arrays (float in the run's precision, int32, bool), the others
    (`sweepable=False`, and strings) as plain Python values, fixed for the sweep, which
    may shape the program (horizons, step counts, a design name). `key` is the row's
    PRNG key. It returns one scalar array per metric in `Analysis.metrics` plus
    `"status"`, an int indexing `Analysis.statuses` (0 means "ok"). The framework merges
    the values, vmaps `row`, jits it once per sweep, shards the batch over the JAX
    devices and splits the sweep into chunks.
  * a simulated analysis gives `simulate(values, keys, simulator) -> metrics` for a
    batch of B rows: `values` as above but every sweepable parameter a (B,) numpy
    column (a string one: a numpy unicode array of its choices), `keys` (B, 2) uint32.
    It builds its scenarios and per-simulation parameters and runs them with
    `simulator.run(scenario, params)` (`jaxloco.sim.rollout.Simulator`). The common case,
    one scenario per sweep and one simulation per row, is data: `Simulation(scenario,
    params, metrics)`, whose scenario the framework builds once per set of plain values
    and caches by value. The framework
    owns the simulator: the backend (the analysis' `backend` parameter, else native
    MuJoCo), the physics threads (its `nthread` parameter) and, for a replay, the
    recording of every simulated state. It returns (B,) numpy arrays, one per metric,
    plus "status". A simulation's rows may be grouped, split or left out as the
    analysis needs (e.g. three pushes per row, or a plan per row, grouped by terrain).

`Analysis.batch_fn(fixed)` is the one place that turns either form into the function the
sweep runs on each chunk, `fn(swept, keys)` with swept: name -> (B,) column of each swept
parameter. A string parameter (kind "str") can be swept only with `choices` and only by a
simulated analysis (JAX arrays cannot hold strings); see `sweep_problem`.
"""

from __future__ import annotations

import functools
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


RowFn = Callable[[Mapping[str, Any], Any], Mapping[str, Any]]
SimulateFn = Callable[[Mapping[str, Any], Any, Any], Mapping[str, Any]]
BatchFn = Callable[[Mapping[str, Any], Any], dict[str, Any]]


@dataclass(frozen=True)
class Analysis:
    """A sweep analysis: exactly one of `row` (JAX) or `simulate` (simulated); see the
    module docstring for both contracts."""

    name: str
    doc: str
    params: tuple[Param, ...]
    metrics: tuple[Metric, ...]
    row: RowFn | None = None
    simulate: SimulateFn | None = None
    statuses: tuple[str, ...] = ("ok",)
    summarize: SummaryFn | None = None  # pyarrow.Table -> Summary
    x64: bool = True  # run in float64 (the CLI configures JAX accordingly)
    _by_name: dict[str, Param] = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        names = [p.name for p in self.params]
        if len(set(names)) != len(names):
            raise ValueError(f"analysis {self.name}: duplicate parameter names")
        if not self.statuses or self.statuses[0] != "ok":
            raise ValueError(f"analysis {self.name}: statuses[0] must be 'ok'")
        if (self.row is None) == (self.simulate is None):
            raise ValueError(f"analysis {self.name}: give exactly one of row (JAX) and simulate (simulated)")
        self._by_name.update({p.name: p for p in self.params})

    @property
    def executor(self) -> Literal["jax", "host"]:
        """"jax": the runner jits the batch and shards it over the JAX devices; "host": the
        batch runs as it is, once per chunk (its simulator uses every core itself)."""
        return "jax" if self.row is not None else "host"

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

    def batch_fn(self, fixed: Mapping[str, Any], simulator: Any = None) -> BatchFn:
        """The function a sweep runs on each chunk: `fn(swept, keys) -> metrics`, swept:
        name -> (B,) column of each swept parameter, keys: (B, 2) uint32, metrics: name
        -> (B,) array (every metric and "status"). `fixed` gives every other parameter
        (validated with `Param.check`). A JAX analysis' function is pure and jittable
        (the caller jits it); a simulated one runs on `simulator` (default: one made from
        the `backend` and `nthread` parameters, `simulator_for`)."""
        if self.row is not None:
            return _row_batch(self, fixed)
        return _simulated_batch(self, fixed, simulator)


def _is_column(p: Param) -> bool:
    """Whether a parameter reaches `row` / `simulate` as a per-row value (else a plain
    Python value, the same for the whole sweep)."""
    return p.sweepable and (p.kind != "str" or p.choices is not None)


def static_values(analysis: Analysis, fixed: Mapping[str, Any]) -> dict[str, Any]:
    """The parameters that stay plain Python values (not sweepable, or free text)."""
    return {p.name: fixed[p.name] for p in analysis.params if not _is_column(p)}


def _array_params(analysis: Analysis) -> list[Param]:
    return [p for p in analysis.params if _is_column(p) and p.kind != "str"]


def _dtypes() -> dict[str, Any]:
    """The array dtype of each numeric parameter kind (floats in the run's precision)."""
    import jax.numpy as jnp

    return {"float": jnp.result_type(float), "int": jnp.int32, "bool": jnp.bool_}


def row_arrays(analysis: Analysis, values: Mapping[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """(arrays, static) of one row as `row` gets them: the sweepable numbers as scalar
    arrays, the rest plain. For replays and notebooks that call a JAX analysis' own
    functions on one row: `jax.jit(lambda a: f({**static, **a}))(arrays)`."""
    import jax.numpy as jnp

    kinds = _dtypes()
    arrays = {p.name: jnp.asarray(values[p.name], kinds[p.kind]) for p in _array_params(analysis)}
    return arrays, static_values(analysis, values)


def _row_batch(analysis: Analysis, fixed: Mapping[str, Any]) -> BatchFn:
    """vmap of `analysis.row` over the rows: every sweepable parameter a (B,) column, the
    fixed ones broadcast (so that a fixed and a swept value give the same program)."""
    import jax
    import jax.numpy as jnp

    static = static_values(analysis, fixed)
    columns = _array_params(analysis)
    row = analysis.row

    def batch(swept: Mapping[str, Any], keys: Any) -> dict[str, Any]:
        n = keys.shape[0]
        kinds = _dtypes()
        values = {
            p.name: jnp.asarray(swept[p.name], kinds[p.kind]) if p.name in swept
            else jnp.full(n, fixed[p.name], kinds[p.kind])
            for p in columns
        }
        return jax.vmap(lambda v, k: dict(row({**static, **v}, k)))(values, keys)

    return batch


def _simulated_batch(analysis: Analysis, fixed: Mapping[str, Any], simulator: Any) -> BatchFn:
    """`analysis.simulate` on numpy columns of the rows (fixed values broadcast)."""
    import numpy as np

    from jaxloco.sim.backend import resolved
    from jaxloco.sim.rollout import simulator_for

    fixed = resolved(fixed)  # "auto" -> the backend that runs, as the simulate function sees it
    static = static_values(analysis, fixed)
    columns = [p.name for p in analysis.params if _is_column(p)]
    sim = simulator if simulator is not None else simulator_for(fixed)
    simulate = analysis.simulate

    def batch(swept: Mapping[str, Any], keys: Any) -> dict[str, Any]:
        n = np.shape(keys)[0]
        values = {name: np.asarray(swept[name]) if name in swept else np.full(n, fixed[name]) for name in columns}
        return dict(simulate({**static, **values}, np.asarray(keys, np.uint32), sim))

    return batch


@dataclass(frozen=True)
class Simulation:
    """A simulated analysis as data, for the common case of one scenario per sweep:
    `Analysis(simulate=Simulation(scenario, params, metrics))`.

      * scenario(plain) -> Scenario, from the plain values only (horizons, kinds: not the
        per-row columns); the framework keeps one per set of plain values (cached by
        value), so its compiled rollout serves every chunk and every replay;
      * params(values, keys) -> the per-simulation params dict (one simulation per row,
        the rows' (B, 2) PRNG keys added as "key" unless given);
      * metrics(values, result) -> metrics and "status" from the `RolloutResult`.

    An analysis whose rows need several simulations, several scenarios or host-side
    planning writes `simulate` itself (e.g. `snake.contact`, `titan.walk`)."""

    scenario: Callable[[Mapping[str, Any]], Any]
    params: Callable[[Mapping[str, Any], Any], Mapping[str, Any]]
    metrics: Callable[[Mapping[str, Any], Any], Mapping[str, Any]]

    def __call__(self, values: Mapping[str, Any], keys: Any, simulator: Any) -> dict[str, Any]:
        import numpy as np

        plain = tuple(sorted((k, v) for k, v in values.items() if not isinstance(v, np.ndarray)))
        params = dict(self.params(values, keys))
        params.setdefault("key", keys)
        return dict(self.metrics(values, simulator.run(_scenario_by_value(self.scenario, plain), params)))


@functools.lru_cache(maxsize=16)
def _scenario_by_value(make: Callable[[Mapping[str, Any]], Any], plain: tuple[tuple[str, Any], ...]) -> Any:
    """`make(plain values)`, one scenario per set of plain values (the 16 most recent)."""
    return make(dict(plain))


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
