"""A robot's parameters, each stated once.

A robot keeps ONE `ParamTable`: every parameter a user can set (name, default, unit,
range, doc, sweepable), whichever analysis, scenario or objective uses it. From it come

  * the defaults of the robot's parameter pytree (`table.default("mu")` as the field's
    default),
  * the `Param`s of each sweep analysis (`table.select("theta", "mu", ...)`, in the
    analysis' order, with per-analysis changes where an analysis needs another default
    or range, e.g. `table.select(..., horizon={"default": 150.0})`),
  * the `Tunable`s of its tune objectives (`table.tunable("k_eta", scale="log")`: the same
    default, doc, unit and bounds).

So a default or a bound changes in one place, and a doc reads the same in `jaxloco
describe` and `jaxloco objectives`. Importing this module does not import JAX.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

from jaxloco.analysis import Param
from jaxloco.sim.backend import CHOICES, PARAM

if TYPE_CHECKING:
    from jaxloco.tune.objective import Tunable


@dataclass(frozen=True)
class ParamTable:
    """The parameters of one robot by name (see the module docstring)."""

    robot: str
    params: tuple[Param, ...]
    _by_name: dict[str, Param] = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        for p in self.params:
            if p.name in self._by_name:
                raise ValueError(f"{self.robot} parameters: '{p.name}' is stated twice")
            self._by_name[p.name] = p

    def __getitem__(self, name: str) -> Param:
        try:
            return self._by_name[name]
        except KeyError:
            raise KeyError(f"{self.robot} parameters: no parameter '{name}'") from None

    def __contains__(self, name: object) -> bool:
        return name in self._by_name

    def names(self) -> tuple[str, ...]:
        return tuple(self._by_name)

    def default(self, name: str) -> Any:
        """The default value of parameter `name`."""
        return self[name].default

    def defaults(self, names: Iterable[str] | None = None) -> dict[str, Any]:
        """name -> default of `names` (default: every parameter)."""
        return {n: self[n].default for n in (self.names() if names is None else names)}

    def select(self, *names: str, **changes: Mapping[str, Any]) -> tuple[Param, ...]:
        """The `Param`s `names`, in that order, with `changes[name]` (field -> value, e.g.
        {"default": 150.0, "sweepable": False}) applied to those an analysis uses
        differently."""
        unknown = set(changes) - set(names)
        if unknown:
            raise ValueError(f"{self.robot} parameters: changes for unselected {sorted(unknown)}")
        return tuple(replace(self[n], **changes.get(n, {})) for n in names)

    def tunable(self, name: str, **changes: Any) -> Tunable:
        """The `Tunable` of parameter `name`: its default, doc, unit and bounds, with
        `changes` (e.g. scale="log", or tighter lo/hi for the optimiser)."""
        from jaxloco.tune.objective import Tunable

        p = self[name]
        if p.kind != "float":
            raise ValueError(f"{self.robot} parameters: '{name}' is {p.kind}; only a float can be tuned")
        base = {"default": float(p.default), "doc": p.doc, "unit": p.unit, "lo": p.lo, "hi": p.hi}
        return Tunable(name=name, **{**base, **changes})


def simulation_params(default: str = "auto") -> tuple[Param, Param]:
    """The `backend` and `nthread` parameters every simulated analysis has (the same in
    every robot's table; `jaxloco.sim.backend`)."""
    return (
        Param(PARAM, default, "simulator: native MuJoCo (mujoco.batch on the CPU cores), MJX (one jitted scan over "
              "the JAX devices; differentiable) or auto (MJX on a GPU or TPU, else native); the table records the "
              "one that ran", kind="str", choices=CHOICES, sweepable=False),
        Param("nthread", 0, "physics threads of the native simulator (0: all cores)", "", kind="int", lo=0, hi=1024,
              sweepable=False),
    )
