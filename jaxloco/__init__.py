"""jaxloco: JAX-differentiable, batched kinematics, stability analysis, control and
simulation of field locomotion robots.

Layers (imports go downward only): core kernels (`geometry`, `stability`, `qp`) ->
robots (`robots.<robot>`) -> applications (`sweep`, `cli`). Importing `jaxloco` is
cheap: nothing here imports JAX or MuJoCo.
"""

__version__ = "0.1.0"

__all__ = ["__version__"]
