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

import math
from dataclasses import dataclass, field, replace

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco.analysis import Param
from jaxloco.parameters import ParamTable, simulation_params

G = 9.81  # gravitational acceleration [m/s^2]

# names of the physical legs 0..3 (left front, right front, right rear, left rear) in the
# MJCF and the kinematics: the literal reading of the paper's numbering. In the mirrored
# reading (`gait.DESIGNS["mirrored"]`, the simulated walk's default) the paper's L2 is
# physical leg 3 and its L4 physical leg 1.
LEG_NAMES = ("L1", "L2", "L3", "L4")

HALF_PI = 0.5 * math.pi

# Every parameter a user sets (the sweep analyses `leggrope.slope_cycle` and
# `leggrope.fragile_walk`, the fragile-walk scenario's params dict, `LegGropeParams` and
# `gait.WalkParams`), each stated once. The ranges are the force-distribution model's;
# the simulated walk narrows some of them (`sim_analysis.PARAMS`).
PARAMETERS = ParamTable("leggrope", (
    # --- terrain and walking direction
    Param("theta", 0.0, "slope inclination (positive: walking direction psi = 0 climbs)", "rad",
          lo=-HALF_PI, hi=HALF_PI, lo_open=True, hi_open=True),
    Param("psi", 0.0, "walking direction relative to the slope gradient (paper Fig. 5)", "rad",
          lo=-HALF_PI, hi=HALF_PI),
    Param("mu", 0.45, "static friction coefficient", "", lo=0.0, hi=2.0, lo_open=True),
    Param("facet_spread", 0.0, "irregular slope: facet gradient directions spread +- this (uses the seed)", "rad",
          lo=0.0, hi=HALF_PI),
    # --- the walk (simulation section)
    Param("r_ref_factor", 0.5, "grope reaction R_ref = factor * M g cos(theta)", "", lo=0.0, hi=1.0, lo_open=True),
    Param("a_max", 0.15, "body acceleration limit", "m/s^2", lo=0.0, hi=2.0, lo_open=True),
    Param("v_max", 0.1, "body speed limit", "m/s", lo=0.0, hi=1.0, lo_open=True),
    Param("h_s", -2.0, "QP weight of the safety margin s (Eq. 22), negative", "1/N", lo=-1e3, hi=0.0, hi_open=True),
    Param("h_tau", 1.0, "QP weight of the torque norm", "1/(N m)^2", lo=0.0, hi=1e4, lo_open=True),
    Param("h_c", 80.0, "QP weight of torque continuity", "1/(N m)^2", lo=0.0, hi=1e5),
    Param("stride", 0.06, "forward step of every foot per cycle", "m", lo=0.0, hi=0.12, lo_open=True),
    Param("swing_height", 0.03, "toe lift during the swing", "m", lo=0.0, hi=0.1),
    Param("normal_tol", 0.10, "tolerated normal-force excess over R_ref / grope shortfall, fraction of R_ref", "",
          lo=0.0, hi=1.0),
    Param("numbering", "mirrored", "leg numbering and footsteps (gait.CYCLE_DESIGNS): 'mirrored' walks along x_R "
          "(the paper's forward direction), 'literal' along y_R", kind="str", choices=("literal", "mirrored"),
          sweepable=False),
    # --- the A-D cycle's discretisation and QP solver
    Param("dt", 0.015, "QP time step", "s", lo=0.001, hi=0.1, sweepable=False),
    Param("n_move", 100, "steps of phase A (body move)", "", kind="int", lo=10, hi=1000, sweepable=False),
    Param("n_unload", 20, "steps of phase B (unload the groping leg)", "", kind="int", lo=2, hi=1000, sweepable=False),
    Param("n_swing", 40, "steps of phase C (swing)", "", kind="int", lo=4, hi=1000, sweepable=False),
    Param("n_load", 20, "steps of phase D (load to R_ref)", "", kind="int", lo=2, hi=1000, sweepable=False),
    Param("qp_iterations", 20, "interior-point iterations per QP", "", kind="int", lo=5, hi=200, sweepable=False),
    Param("capacity", False, "also solve max-s (slip capacity) at every step (doubles the cost)", "",
          kind="bool", sweepable=False),
    # --- the simulated walk's controller (`control.py`)
    Param("fallback_distance", 0.04, "the fallback foothold is this far from the target (gait.GaitDesign.fallback)",
          "m", lo=0.037, hi=0.08),
    Param("safe_blend", 0.4, "A' COG: this fraction from the grope COG towards the stance centroid (the literal "
          "numbering's walk was tuned at 0.25)", "", lo=0.0, hi=0.6),
    Param("swing_margin", 0.005, "A' COG: at least this far inside pi_g, before and after the swing (paper Fig. 10: "
          "inside the COG's admissible region; control.swing_cog), default (ours)", "m", lo=-0.05, hi=0.05),
    Param("twist_relief", 0.02, "A', D'-1 (four legs): toe height correction rate per M g of measured stance twist "
          "(control.twist_relief; the paper's flexible legs do this by themselves; 0: off), default (ours)", "m/s",
          lo=0.0, hi=0.5),
    Param("shear_relief", 0.1, "A', D'-1 (four legs): in-plane toe correction rate per M g of a toe's in-plane "
          "reaction beyond its share by normal load (control.shear_relief; 0: off), default (ours)", "m/s",
          lo=0.0, hi=1.0),
    Param("grope_blend", 0.1, "D'-2: the body creeps at most this fraction from the grope COG towards the foothold",
          "", lo=0.0, hi=0.5),
    Param("regrope", 1, "after a foothold collapses: 1 regropes a fallback foothold (the method, step D), 0 stops "
          "the walk (the paper's collapse experiment)", "", kind="int", lo=0, hi=1),
    # --- fragile footholds and perturbed trials
    Param("p_weak", 0.0, "probability that a target foothold is weak", "", lo=0.0, hi=1.0),
    Param("r_break_lo", 0.35, "weak footholds break at R_break ~ U(lo, hi) M g: lower end", "", lo=0.0, hi=2.0),
    Param("r_break_hi", 0.45, "weak footholds break at R_break ~ U(lo, hi) M g: upper end", "", lo=0.0, hi=2.0),
    Param("weak_leg", -1, "this leg's (0..3 = L1..L4) first target is weak for certain (-1: none)", "",
          kind="int", lo=-1, hi=3),
    Param("mu_jitter", 0.0, "perturbed trials: mu + U(-1, 1) x this, from the row's seed (mu stays >= 0.05)", "",
          lo=0.0, hi=0.5),
    Param("theta_jitter", 0.0, "perturbed trials: theta + U(-1, 1) x this, from the row's seed", "rad",
          lo=0.0, hi=0.1),
    # --- running the simulation
    Param("horizon", 30.0, "simulated time", "s", lo=1.0, hi=300.0, sweepable=False),
    *simulation_params(),  # backend, nthread
))



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
    # --- simulation section (`PARAMETERS`)
    mu: jax.Array = PARAMETERS.default("mu")
    r_ref_factor: jax.Array = PARAMETERS.default("r_ref_factor")
    a_max: jax.Array = PARAMETERS.default("a_max")
    v_max: jax.Array = PARAMETERS.default("v_max")
    h_s: jax.Array = PARAMETERS.default("h_s")
    h_tau: jax.Array = PARAMETERS.default("h_tau")
    h_c: jax.Array = PARAMETERS.default("h_c")
    dt: float = field(default=PARAMETERS.default("dt"), metadata=dict(static=True))

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
