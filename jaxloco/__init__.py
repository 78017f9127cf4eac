"""jaxloco: JAX-differentiable, batched kinematics, stability analysis, control and
simulation of field locomotion robots.

Layers (imports go downward only): core kernels (`geometry`, `stability`, `qp`,
`qp_ipm`, `qp_kernel`, `linalg`, `batching`) -> simulation (`sim`) -> robots (`robots`, one package per paper) ->
applications (`sweep`, `tune`, `render`, `cli`). Importing `jaxloco` is cheap: nothing
here imports JAX or MuJoCo.

Modules: `analysis` (what a sweep analysis is, and the analysis registry), `parameters`
(a robot's parameters, each stated once), `registry`
(the one registry behind analyses, objectives and replays), `errors` (every exception
jaxloco raises on purpose), `catalog` (what the CLI prints about the built-ins, without
importing them), `check` (`jaxloco check`), `cli`, `info` (versions and environment),
`runtime` (process-level JAX settings), `paths` (probing user paths), `plots`
(workbench plots), `notebook` (what the notebooks share), `terminal` (output that fits
the terminal), `_lazy` (package attributes imported on first use). Packages: `sim`,
`robots`, `sweep`, `tune`, `render`, `specs` (the bundled specs).
"""

__version__ = "0.1.0"

__all__ = ["__version__"]
