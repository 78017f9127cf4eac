"""The leg-grope quadruped of Ambe & Matsuno (ROBOMECH J. 2016), Table 1, and the settings
of its simulation section, as a frozen pytree dataclass.

Frames: robot frame Sigma_R at the body centre, x_R forward, y_R left, z_R up (normal
to the body). Legs L1..L4 are numbered clockwise seen from above starting at the left
front leg (paper): L1 left-front, L2 right-front, L3 right-rear, L4 left-rear. Indices
in arrays are 0..3 for L1..L4.

Values the paper does not give, chosen here and documented:
  * hips at the body corners (+-length/2, +-width/2, 0) in Sigma_R;
  * each leg's yaw-joint zero points from the body centre through its hip (a sprawled,
    insect-like posture: the yaw joint swings the leg "from back to front");
  * link masses at the link midpoints (uniform rods), body COM at the body centre;
  * body height 0.10 m (hip plane above the ground along the ground normal);
  * the foothold layout of the gait (see `gait.py`): all feet about 0.2 m from their
    hips, the leading feet closer together than the trailing ones.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import jax
import jax.numpy as jnp
import numpy as np

G = 9.81  # gravitational acceleration [m/s^2]

# names of the physical legs 0..3 (left front, right front, right rear, left rear) in the
# MJCF and the kinematics: the literal reading of the paper's numbering. In the mirrored
# reading (`gait.DESIGNS["mirrored"]`, the simulated walk's default) the paper's L2 is
# physical leg 3 and its L4 physical leg 1.
LEG_NAMES = ("L1", "L2", "L3", "L4")


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class LegGropeParams:
    """Robot constants (Table 1) and the leg-grope walk settings (simulation section).

    Array-valued fields are pytree leaves (can be traced, swept and differentiated);
    fields marked static are Python values that shape the computation."""

    # --- Table 1 [m, kg]
    body_length: jax.Array = 0.29
    body_width: jax.Array = 0.15
    body_mass: jax.Array = 4.54
    link_lengths: jax.Array = field(default_factory=lambda: np.array([0.072, 0.109, 0.172]))
    link_masses: jax.Array = field(default_factory=lambda: np.array([0.03, 0.35, 0.25]))
    # --- chosen (see module docstring)
    body_height: jax.Array = 0.10
    # --- simulation section
    mu: jax.Array = 0.45  # static friction coefficient
    r_ref_factor: jax.Array = 0.5  # R_ref = r_ref_factor * M g cos(theta)
    a_max: jax.Array = 0.15  # body acceleration limit [m/s^2]
    v_max: jax.Array = 0.1  # body velocity limit [m/s]
    h_s: jax.Array = -2.0  # weight of the friction safety margin s (Eq. 22), h_s < 0
    h_tau: jax.Array = 1.0  # weight of the torque norm
    h_c: jax.Array = 80.0  # weight of torque continuity
    dt: float = field(default=0.015, metadata=dict(static=True))  # QP time step [s]

    @property
    def total_mass(self) -> jax.Array:
        return self.body_mass + 4.0 * jnp.sum(jnp.asarray(self.link_masses))

    def hips(self) -> jax.Array:
        """Hip (yaw joint) positions in Sigma_R, (4, 3), legs L1..L4."""
        lx = 0.5 * jnp.asarray(self.body_length)
        ly = 0.5 * jnp.asarray(self.body_width, lx.dtype)
        sx = jnp.array([1.0, 1.0, -1.0, -1.0], lx.dtype)
        sy = jnp.array([1.0, -1.0, -1.0, 1.0], lx.dtype)
        return jnp.stack([sx * lx, sy * ly, jnp.zeros(4, lx.dtype)], axis=1)

    def mount_angles(self) -> jax.Array:
        """Yaw-joint zero direction of each leg in Sigma_R [rad] (centre -> hip)."""
        h = self.hips()
        return jnp.arctan2(h[:, 1], h[:, 0])

    def with_(self, **changes) -> "LegGropeParams":
        return replace(self, **changes)

    def astype(self, dtype) -> "LegGropeParams":
        """The same robot with every array field in `dtype` (e.g. jnp.float32)."""
        return jax.tree_util.tree_map(lambda x: jnp.asarray(x, dtype), self)


def default_params() -> LegGropeParams:
    """Table 1 robot with the paper's simulation settings."""
    return LegGropeParams()
