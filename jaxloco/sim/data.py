"""The simulator data a scenario may read, the same from every backend.

`SimData` holds, for one simulation, the MuJoCo state and the derived fields that the
controllers, observations and metrics of jaxloco use. Both backends fill it from the
same MjData fields with the same timing convention as `mj_step`: after a physics step,
`qpos`, `qvel`, `time` and the mocap poses are the new state, while the derived fields
(sensors, frames, actuator forces) describe the state before the last substep.

Frames and units: world frame (z up), SI units; quaternions are (w, x, y, z); rotation
matrices are (3, 3) with columns the axes of the local frame in the world.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

Array = jax.Array


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class SimData:
    """One simulation's state and derived fields (arrays; a leading batch axis when batched)."""

    time: Array  # () [s]
    qpos: Array  # (nq,)
    qvel: Array  # (nv,)
    ctrl: Array  # (nu,) the controls applied during the last step
    actuator_force: Array  # (nu,) [N or N m]
    sensordata: Array  # (nsensordata,)
    xpos: Array  # (nbody, 3) body frame origins
    xquat: Array  # (nbody, 4)
    site_xpos: Array  # (nsite, 3)
    site_xmat: Array  # (nsite, 3, 3)
    subtree_com: Array  # (nbody, 3) centre of mass of each body's subtree
    mocap_pos: Array  # (nmocap, 3)
    mocap_quat: Array  # (nmocap, 4)


FIELDS: tuple[str, ...] = tuple(f.name for f in fields(SimData))
# fields that are part of the MuJoCo state (written by the rollout, not derived)
STATE_FIELDS = ("time", "qpos", "qvel", "ctrl", "mocap_pos", "mocap_quat")


def from_mjx(d: Any) -> SimData:
    """SimData of an `mujoco.mjx.Data` (unbatched or batched)."""
    lead = d.qpos.shape[:-1]
    return SimData(
        time=d.time,
        qpos=d.qpos,
        qvel=d.qvel,
        ctrl=d.ctrl,
        actuator_force=d.actuator_force,
        sensordata=d.sensordata,
        xpos=d.xpos,
        xquat=d.xquat,
        site_xpos=d.site_xpos,
        site_xmat=jnp.reshape(d.site_xmat, (*lead, -1, 3, 3)),
        subtree_com=d.subtree_com,
        mocap_pos=d.mocap_pos,
        mocap_quat=d.mocap_quat,
    )


def bind_native(batch: Any) -> dict[str, np.ndarray]:
    """Live (nsim, ...) arrays of a `mujoco.batch.Batch` for every SimData field."""
    return {name: batch.bind(name) for name in FIELDS}


def from_native(bound: dict[str, np.ndarray]) -> SimData:
    """A batched SimData (numpy copies) of the arrays from `bind_native`."""
    out = {name: np.array(bound[name]) for name in FIELDS}
    n = out["qpos"].shape[0]
    out["site_xmat"] = out["site_xmat"].reshape(n, -1, 3, 3)
    return SimData(**out)


def sensor_slice(model: Any, name: str) -> slice:
    """Where sensor `name` lies in `sensordata` (static)."""
    try:
        s = model.sensor(name)
    except KeyError:
        raise KeyError(f"the model has no sensor named '{name}'") from None
    adr, dim = int(s.adr[0]), int(s.dim[0])
    return slice(adr, adr + dim)


def is_finite(data: SimData) -> Array:
    """Whether the state of one simulation is finite (qpos and qvel)."""
    return jnp.all(jnp.isfinite(data.qpos)) & jnp.all(jnp.isfinite(data.qvel))
