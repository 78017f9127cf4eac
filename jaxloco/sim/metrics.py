"""Metrics of recorded rollouts (one simulation; vmap over the batch). Pure JAX.

Time series come as (T, ...) arrays sampled every record period; `valid` (T,) masks the
samples that count (e.g. before a divergence). World frame, z up; angles in radians,
forces in newtons, lengths in metres.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxloco import stability
from jaxloco.sim.terrain import quat_z_axis

Array = jax.Array


def quat_to_rpy(q: Array) -> Array:
    """Roll, pitch, yaw (3,) [rad] of a unit quaternion (w, x, y, z): R = Rz(yaw) Ry(pitch) Rx(roll),
    as an IMU reports attitude."""
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    roll = jnp.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = jnp.arcsin(jnp.clip(2.0 * (w * y - z * x), -1.0, 1.0))
    yaw = jnp.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return jnp.stack([roll, pitch, yaw], axis=-1)


def tilt_change(quats: Array, reference: Array) -> Array:
    """Angle (T,) [rad] between each attitude's z axis and the reference attitude's z
    axis: the attitude change an IMU sees, independent of heading."""
    z_ref = quat_z_axis(reference)
    z = quat_z_axis(quats)
    return jnp.arccos(jnp.clip(z @ z_ref, -1.0, 1.0))


def masked_max(x: Array, valid: Array, empty: float = -jnp.inf) -> Array:
    v = jnp.broadcast_to(valid, x.shape) if valid.ndim < x.ndim else valid
    return jnp.max(jnp.where(v, x, empty))


def masked_min(x: Array, valid: Array, empty: float = jnp.inf) -> Array:
    v = jnp.broadcast_to(valid, x.shape) if valid.ndim < x.ndim else valid
    return jnp.min(jnp.where(v, x, empty))


def attitude_extremes(rpy: Array, valid: Array) -> dict[str, Array]:
    """Extremes of roll and pitch (T, 3 rpy) and their largest change from the first
    sample [rad]."""
    d = rpy[:, :2] - rpy[:1, :2]
    vv = valid[:, None]
    return {
        "max_abs_roll": masked_max(jnp.abs(rpy[:, 0]), valid, 0.0),
        "max_abs_pitch": masked_max(jnp.abs(rpy[:, 1]), valid, 0.0),
        "min_roll": masked_min(rpy[:, 0], valid, 0.0),
        "max_roll": masked_max(rpy[:, 0], valid, 0.0),
        "min_pitch": masked_min(rpy[:, 1], valid, 0.0),
        "max_pitch": masked_max(rpy[:, 1], valid, 0.0),
        "max_attitude_change": jnp.max(jnp.where(vv, jnp.abs(d), 0.0)),
    }


def path_length(points: Array, valid: Array) -> Array:
    """Length [m] of the polyline through the valid samples (T, 3) (e.g. the COG path)."""
    seg = jnp.linalg.norm(points[1:] - points[:-1], axis=-1)
    return jnp.sum(jnp.where(valid[1:] & valid[:-1], seg, 0.0))


def force_ratio(forces: Array, bound: Array, mask: Array) -> Array:
    """Largest force / bound over the masked samples (T, N) (0 when none)."""
    return masked_max(forces / bound, mask, 0.0)


def support_margins(cog: Array, contacts: Array, mask: Array, kind: str = "static") -> Array:
    """Stability margin (T,) [m] of the COG (T, 3) over the actual contacts (T, N, 3)
    with mask (T, N): "static" (support-polygon margin) or "nesm" (normalized energy
    stability margin, a height), from the core kernels."""
    fn = {"static": stability.static_margin, "nesm": stability.ne_stability_margin}[kind]
    return jax.vmap(fn)(cog, contacts, mask)


def first_time(flags: Array, times: Array) -> Array:
    """Time of the first True sample, nan if none."""
    idx = jnp.argmax(flags)
    return jnp.where(jnp.any(flags), times[idx], jnp.nan)
