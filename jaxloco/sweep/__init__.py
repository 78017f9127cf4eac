"""Parameter sweeps: a TOML spec -> a validated grid -> batched analysis -> a Parquet table.

    spec = load_spec("sweeps/x.toml")      # or spec_from_dict({...})
    grid = expand(spec)                    # rows, in a fixed order
    result = run(spec)                     # result.table, result.path, result.summary

Modules: `spec` (format and validation), `grid` (row order), `runner` (chunks and JAX),
`store` (output directory, atomic files, resume), `schema` (table columns),
`summary` and `display` (what is printed). Importing this package does not import JAX.
"""

from jaxloco.analysis import SpecError
from jaxloco.sweep.errors import AnalysisError, SweepInterrupted
from jaxloco.sweep.grid import Grid, expand
from jaxloco.sweep.runner import SweepResult, run
from jaxloco.sweep.spec import SweepSpec, load_spec, spec_from_dict

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
