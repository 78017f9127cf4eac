"""Gradient tuning: a TOML spec -> an objective's loss -> optax steps -> the loss curve and
the tuned values, compared with the initial values and the objective's references.

    spec = load_spec("sweeps/snake_kv_tune.toml")       # or spec_from_dict({...})
    result = run(spec)                     # result.curve, result.comparison, result.values()

Modules: `objective` (the registry: `Objective`, `Tunable`, `register`, `get`), `spec`
(format and validation), `transform` (bounds and log scales), `runner` (the loop),
`output` (files) and `display` (what is printed). Importing this package does not import JAX.
"""

from jaxloco.analysis import SpecError
from jaxloco.tune.objective import Objective, Tunable, get, names, register
from jaxloco.tune.runner import (
    ObjectiveError,
    TuneDiverged,
    TuneInterrupted,
    TuneResult,
    run,
)
from jaxloco.tune.spec import TuneSpec, load_spec, spec_from_dict

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
