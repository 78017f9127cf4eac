"""The registry of objectives that `jaxloco tune` can minimise by gradient descent.

An *objective* is a differentiable scalar loss of a few named scalar parameters (the
*tunables*), plus fixed, non-differentiated *settings* (`jaxloco.analysis.Param`, e.g. a
horizon or a terrain name) that are chosen once per run. Robots register theirs here,
like analyses in `jaxloco.analysis`.

Contract of `Objective.make_loss(settings)`:
  * `settings` maps every setting name to a plain Python value (checked with `Param.check`).
  * It returns `loss_fn(values) -> (loss, aux)`: `values` maps *every* tunable name to a
    scalar array (float64 when `x64`, else float32); `loss` is a scalar array and `aux` a
    dict of scalar arrays (metrics recorded next to the loss, e.g. tracking error, energy).
    `loss_fn` is pure and jit-compatible; the runner jits `value_and_grad(loss_fn)` once
    (forward mode, `jax.jacfwd`, when `Objective.grad_mode` is "forward").
  * Raising `SpecError` from `make_loss` reports a bad combination of settings.

How a tunable is optimised: the optimizer works on an unconstrained coordinate `u`.
`scale="log"` optimises `log(value)` (value > 0). Bounds map `u` into the open interval:
both bounds by a sigmoid, one bound by a softplus (for a log-scale tunable the bounds
apply to `log(value)`). So a bounded value never leaves (lo, hi), and it must start
strictly inside. Importing this module does not import JAX.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Literal

from jaxloco.analysis import Param
from jaxloco.errors import SpecError
from jaxloco.registry import Registry, robot_entries

LossFn = Callable[[dict[str, Any]], tuple[Any, dict[str, Any]]]


@dataclass(frozen=True)
class Tunable:
    """One scalar parameter that gradient descent may change (see the module doc for lo/hi/scale)."""

    name: str
    default: float
    doc: str
    unit: str = ""
    lo: float | None = None
    hi: float | None = None
    scale: Literal["linear", "log"] = "linear"

    def as_param(self) -> Param:
        """The `Param` that checks a value of this tunable: a float strictly inside its bounds
        (and > 0 on a log scale)."""
        lo = self.lo
        if self.scale == "log" and (lo is None or lo < 0):
            lo = 0.0
        return Param(self.name, self.default, self.doc, unit=self.unit, lo=lo, hi=self.hi, lo_open=True, hi_open=True)

    def check(self, value: Any, where: str | None = None) -> float:
        """`value` as a float, or SpecError (one line) when it is not a valid starting value."""
        return self.as_param().check(value, where=where)

    def range_text(self) -> str:
        return self.as_param().range_text()


@dataclass(frozen=True)
class Objective:
    """A tunable loss; see the module doc for the contract of `make_loss`.

    references: named hand-set values (e.g. {"paper": {...}}) that `jaxloco tune` evaluates
    with the same loss for comparison; a reference may name only some tunables (the others
    take the run's initial values). x64: run in float64 (the runner configures JAX).
    grad_mode: how the runner differentiates the loss: "reverse" (`jax.value_and_grad`,
    the default) or "forward" (`jax.jacfwd`, one tangent per *tuned* tunable: for losses
    that reverse mode cannot differentiate, e.g. an MJX rollout whose constraint solver
    runs a `while_loop`, see `jaxloco.sim.mjx`).
    """

    name: str
    doc: str
    tunables: tuple[Tunable, ...]
    settings: tuple[Param, ...]
    make_loss: Callable[[Mapping[str, Any]], LossFn]
    references: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    x64: bool = True
    grad_mode: Literal["reverse", "forward"] = "reverse"
    _tunables: dict[str, Tunable] = field(default_factory=dict, init=False, repr=False, compare=False)
    _settings: dict[str, Param] = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        names = [t.name for t in self.tunables] + [p.name for p in self.settings]
        if not self.tunables:
            raise ValueError(f"objective {self.name}: no tunables")
        if len(set(names)) != len(names):
            raise ValueError(f"objective {self.name}: duplicate tunable/setting names")
        self._tunables.update({t.name: t for t in self.tunables})
        self._settings.update({p.name: p for p in self.settings})
        if self.grad_mode not in ("reverse", "forward"):
            raise ValueError(f"objective {self.name}: grad_mode must be 'reverse' or 'forward'")
        for t in self.tunables:
            if t.scale not in ("linear", "log"):
                raise ValueError(f"objective {self.name}: tunable {t.name}: scale must be 'linear' or 'log'")
            if t.lo is not None and t.hi is not None and not t.lo < t.hi:
                raise ValueError(f"objective {self.name}: tunable {t.name}: needs lo < hi")
            if t.scale == "log" and t.hi is not None and t.hi <= 0:
                raise ValueError(f"objective {self.name}: tunable {t.name}: a log scale needs hi > 0")
            try:
                t.check(t.default, where=f"default of {self.name}.{t.name}")
            except SpecError as exc:
                raise ValueError(f"objective {self.name}: {exc}") from None
        frozen = {}
        for label, values in self.references.items():
            for key, value in values.items():
                if key not in self._tunables:
                    raise ValueError(f"objective {self.name}: reference {label!r}: unknown tunable '{key}'")
                if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                    raise ValueError(f"objective {self.name}: reference {label!r}: {key} = {value!r} is not a number")
            frozen[label] = MappingProxyType({k: float(v) for k, v in values.items()})
        object.__setattr__(self, "references", MappingProxyType(frozen))

    def tunable(self, name: str, where: str | None = None) -> Tunable:
        return self._lookup(self._tunables, "tunable", name, where)

    def setting(self, name: str, where: str | None = None) -> Param:
        return self._lookup(self._settings, "setting", name, where)

    def _lookup(self, table: Mapping[str, Any], kind: str, name: str, where: str | None) -> Any:
        try:
            return table[name]
        except KeyError:
            known = ", ".join(table) or "none"
            raise SpecError(
                f"{where or name}: unknown {kind} '{name}' for objective '{self.name}' (known: {known})"
            ) from None


# Built-in objectives come from the robots' entries modules (jaxloco.registry).
OBJECTIVES: Registry[Objective] = Registry(
    "objective", lambda: robot_entries("OBJECTIVES"), lambda entry: isinstance(entry, Objective)
)


def register(objective: Objective) -> Objective:
    """Add an objective (e.g. from a plugin or a test); returns it."""
    return OBJECTIVES.register(objective.name, objective)


def names() -> list[str]:
    return OBJECTIVES.names()


def get(name: str) -> Objective:
    """The objective called `name`; SpecError naming the known ones if there is none or it
    cannot be loaded."""
    return OBJECTIVES.get(name)
