"""Gradient tuning: a TOML spec -> an objective's loss -> optax steps -> the loss curve and
the tuned values, compared with the initial values and the objective's references.

    spec = load_spec("snake_kv_tune")       # or spec_from_dict({...})
    result = run(spec)                     # result.curve, result.comparison, result.values()

Modules: `objective` (the registry: `Objective`, `Tunable`, `register`, `get`), `spec`
(format and validation), `transform` (bounds and log scales), `runner` (the loop),
`result` (what it returns), `output` (files), `display` (what is printed) and `handoff`
(validating tuned values with a sweep). Importing this package does not import JAX.
"""

from typing import TYPE_CHECKING

from jaxloco._lazy import lazy_attributes
from jaxloco.errors import ObjectiveError, SpecError, TuneDiverged, TuneInterrupted
from jaxloco.tune.objective import Objective, Tunable, get, names, register

if TYPE_CHECKING:
    from jaxloco.tune.result import TuneResult
    from jaxloco.tune.runner import run
    from jaxloco.tune.spec import TuneSpec, load_spec, spec_from_dict

# The names below are imported on first use (PEP 562), so that `jaxloco objectives`
# imports the registry and `jaxloco.tune.display` without numpy, pyarrow and pydantic.
_LAZY = {
    "TuneResult": "result",
    "run": "runner", "TuneSpec": "spec", "load_spec": "spec", "spec_from_dict": "spec",
}  # fmt: skip

__getattr__ = lazy_attributes(__name__, _LAZY, globals())

__all__ = [
    "Objective",
    "ObjectiveError",
    "SpecError",
    "Tunable",
    "TuneDiverged",
    "TuneInterrupted",
    "TuneResult",
    "TuneSpec",
    "get",
    "load_spec",
    "names",
    "register",
    "run",
    "spec_from_dict",
]
