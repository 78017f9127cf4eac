"""One registry for what jaxloco looks up by name: analyses, tune objectives and replays.

Built-in entries are "module:attribute" references, imported on first use, so listing
the names imports no robot code. They come from each robot's `entries` module
(`jaxloco/robots/<robot>/entries.py`: one place per robot for its analyses, objectives
and replays). Plugins and tests add entries at run time with `register`, which wins over
a built-in entry of the same name.

    from jaxloco.analysis import ANALYSES       # also tune.objective.OBJECTIVES, render.replay.REPLAYS
    ANALYSES.names()                            # sorted names, nothing imported
    ANALYSES.get("octopus.paper")               # imports the module; SpecError (one line) if unknown
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any, Generic, TypeVar

from jaxloco.errors import SpecError

T = TypeVar("T")

ROBOTS = ("leggrope", "octopus", "titan", "snake")  # packages under jaxloco.robots with an entries module


def robot_entries(table: str) -> dict[str, str]:
    """The union of one table (`ANALYSES`, `OBJECTIVES`, `REPLAYS` or `NO_REPLAY`) over the
    robots' entries modules (light modules: strings only)."""
    out: dict[str, str] = {}
    for robot in ROBOTS:
        module = importlib.import_module(f"jaxloco.robots.{robot}.entries")
        for name, ref in getattr(module, table, {}).items():
            if name in out:
                raise RuntimeError(f"{table}: '{name}' is declared twice (jaxloco.robots.{robot}.entries)")
            out[name] = ref
    return out


def load_reference(ref: str) -> Any:
    """The object a "module:attribute" reference names."""
    module, _, attr = ref.partition(":")
    return getattr(importlib.import_module(module), attr)


class Registry(Generic[T]):
    """Named entries of one kind. `builtin` gives the lazy references (called once, on
    first use); `accepts` tells whether a loaded object is an entry of this kind."""

    def __init__(self, kind: str, builtin: Callable[[], Mapping[str, str]],
                 accepts: Callable[[Any], bool] = lambda _: True) -> None:
        self.kind = kind
        self._builtin_fn = builtin
        self._builtin: dict[str, str] | None = None
        self._accepts = accepts
        self._loaded: dict[str, T] = {}
        self._registered: dict[str, T] = {}

    @property
    def builtin(self) -> dict[str, str]:
        """name -> "module:attribute" of the built-in entries."""
        if self._builtin is None:
            self._builtin = dict(self._builtin_fn())
        return self._builtin

    def register(self, name: str, entry: T) -> T:
        """Add (or replace) an entry at run time (plugins, tests); returns it."""
        self._registered[name] = entry
        return entry

    def is_live(self, name: str) -> bool:
        """Whether `name` was registered at run time or its built-in module is loaded
        already (what a catalog of the built-ins cannot stand in for)."""
        return name in self._registered or name in self._loaded

    def names(self) -> list[str]:
        return sorted(set(self.builtin) | set(self._registered))

    def __contains__(self, name: object) -> bool:
        return name in self._registered or name in self.builtin

    def get(self, name: str) -> T:
        """The entry called `name`; SpecError (one line) naming the known ones if there is
        none, or if its module cannot be loaded."""
        if name in self._registered:
            return self._registered[name]
        if name in self._loaded:
            return self._loaded[name]
        if name not in self.builtin:
            raise SpecError(f"unknown {self.kind} '{name}' (known: {', '.join(self.names())})")
        ref = self.builtin[name]
        try:
            entry = load_reference(ref)
        except (ImportError, AttributeError) as exc:
            raise SpecError(f"{self.kind} '{name}' cannot be loaded ({type(exc).__name__}: {exc})") from exc
        if not self._accepts(entry):
            raise SpecError(f"{self.kind} '{name}': {ref} is a {type(entry).__name__}, not a {self.kind}")
        self._loaded[name] = entry
        return entry
