"""Which simulator a simulated analysis runs on: native MuJoCo, MJX, or "auto".

Every simulated analysis has the parameters `backend` and `nthread`
(`jaxloco.parameters.simulation_params`, stated once rather than in each robot's table):

  * "native": MuJoCo's C engine on `mujoco.batch`, `nthread` threads (the CPU workhorse);
  * "mjx": MJX, one jitted scan sharded over the JAX devices (GPU, TPU; on CPU it runs,
    slower than native, and it is differentiable);
  * "auto": "native" when JAX sees only CPUs, "mjx" when it sees a GPU or TPU.

A sweep resolves "auto" when its spec is read (`resolve`), so the table's `backend` column
says which simulator ran, and a replay of a row runs on that one. Importing this module
does not import JAX.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Literal

Backend = Literal["native", "mjx"]
BACKENDS: tuple[str, ...] = ("native", "mjx")
CHOICES: tuple[str, ...] = (*BACKENDS, "auto")
PARAM = "backend"


def platform() -> str:
    """JAX's default platform: "cpu", "gpu" or "tpu"."""
    import jax

    return jax.default_backend()


def resolve(name: str, on: str | None = None) -> Backend:
    """The simulator `name` stands for: itself, or for "auto" "mjx" on an accelerator and
    "native" on CPUs; `on`: the platform (default: JAX's, `platform()`). ValueError (one
    line) for an unknown name."""
    if name == "auto":
        return "native" if (on or platform()) == "cpu" else "mjx"
    if name not in BACKENDS:
        raise ValueError(f"backend: expected one of {', '.join(CHOICES)}, got {name!r}")
    return name  # type: ignore[return-value]


def resolved(values: Mapping[str, Any]) -> dict[str, Any]:
    """`values` with its `backend` entry, if any, resolved (`resolve`)."""
    if PARAM not in values:
        return dict(values)
    return {**values, PARAM: resolve(str(values[PARAM]))}
