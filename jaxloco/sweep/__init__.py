"""Parameter sweeps: a TOML spec -> a validated grid -> batched analysis -> a Parquet table.

    spec = load_spec("sweeps/x.toml")      # or spec_from_dict({...})
    grid = expand(spec)                    # rows, in a fixed order
    result = run(spec)                     # result.table, result.path, result.summary

Modules: `spec` (format and validation), `spec_model` (its pydantic structure), `ranges`
(numeric ranges in [params]), `grid` (row order), `runner` (the driver), `chunks`
(computing one chunk: what every executor runs), `executors` (local, Ray),
`store` (output directory, atomic files, resume), `schema` (table columns),
`summary` and `display` (what is printed); its exceptions are in `jaxloco.errors`.
Importing this package does not import JAX.
"""

from typing import TYPE_CHECKING

from jaxloco._lazy import lazy_attributes
from jaxloco.errors import AnalysisError, SpecError, SweepInterrupted

if TYPE_CHECKING:
    from jaxloco.sweep.grid import Grid, expand
    from jaxloco.sweep.runner import SweepResult, run
    from jaxloco.sweep.spec import SweepSpec, load_spec, spec_from_dict

# The names below are imported on first use (PEP 562), so that `jaxloco analyses` and
# `describe` import `jaxloco.sweep.display` without numpy, pyarrow and pydantic.
_LAZY = {
    "Grid": "grid", "expand": "grid",
    "SweepResult": "runner", "run": "runner", "SweepSpec": "spec", "load_spec": "spec", "spec_from_dict": "spec",
}  # fmt: skip

__getattr__ = lazy_attributes(__name__, _LAZY, globals())

__all__ = [
    "AnalysisError",
    "Grid",
    "SpecError",
    "SweepInterrupted",
    "SweepResult",
    "SweepSpec",
    "expand",
    "load_spec",
    "run",
    "spec_from_dict",
]
