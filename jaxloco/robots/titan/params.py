"""TITAN XI (Hodoshima et al., J. Robot. Mechatron. 19(1), 2007): dimensions, gait
constants and the values the paper does not give (its figures are missing), each with
its reference or the reason for the chosen value.

Frames and units: SI, radians.
  * body frame Sigma_b: origin at the COG, x_b forward, y_b left, z_b up (normal to the
    slope when standing on it); the body never yaws in this gait (crab gait, Sec. 4.4);
  * map frame: x, y in the map (base) plane, z normal to it. On flat ground the map
    frame is the world frame; on a slope it is the slope frame (x up the fall line,
    y across, z normal to the slope), see `maps.py`.

Leg numbering (array index): 0 LF, 1 RF, 2 LR, 3 RR. The paper's role names f, r,
f-bar, r-bar are assigned per walking direction by `gait.leg_roles`.

Paper values:
  * Table 1: size 4.8 x 5.0 x 3.0 m, leg length 3.7 m, mass 7,000 kg, power 41.9 kW.
    We read "4.8 x 5.0 x 3.0" as length (x_b) x width (y_b) x height, the envelope of
    the robot standing in its neutral pose, feet included.
  * Sec. 7 / 8.3 / 8.4: frames 0.2 m and 0.3 m square in section on 2.0 m and 3.0 m
    grids; test slope 30 deg with 0.2 m frames every 1.5 m.

Chosen values (not in the text):
  * leg pivots (vertical rotation axes) at the corners of a 2.2 x 2.4 m rectangle,
    (+-1.1, +-1.2, 0) in Sigma_b; the neutral foot at 1.0 m forward/back and 1.0 m
    outward of its pivot, so the neutral stance is 4.2 x 4.4 m between foot centres and
    with 0.30 m foot pads the envelope is 4.8 x 5.0 m (Table 1).
  * fan-shaped reachable area (Fig. 3): annular sector about the pivot, radius
    R_in = 0.6 m .. R_out = 2.3 m, opening R_theta = 90 deg centred on the diagonal
    through the neutral foot (45 deg outward). With the 3.7 m leg and the pivot about
    2.2 m above the ground the outer radius leaves the leg about 0.6 m of extension.
  * L_std = 0.5 m (stroke 2 L_std = 1.0 m, so 1.0 m per cycle), W_std = 1.0 m (COG
    zigzag +-0.5 m about the foot centre line). With H_g = 1.5 m the standard gait has
    NESM = 0.085 m on flat ground (tests check it in closed form). S_NE^c = 0.03 m leaves
    0.055 m of it for terrain adaptation. With 0.05 m the planner deadlocked far
    more often on the Sec. 7 / 8.4 frame maps (after a shortened step no foothold keeps
    the next diagonal clear of the contour): 8 random starts x 5 cycles on each of the
    0.2 m / 2 m, 0.3 m / 3 m and slope maps failed 39 of 120 cycles with 0.05 m and 2
    of 120 with 0.03 m (held cycles after a deadlock count).
  * grid maps with 0.1 m cells (half the narrowest frame), foot pad radius 0.15 m,
    swing clearance 0.15 m above the highest point under the return path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco.analysis import Param
from jaxloco.parameters import ParamTable, simulation_params

G = 9.81  # [m/s^2]

LEG_NAMES = ("LF", "RF", "LR", "RR")
LEG_SIGNS = np.array(
    [[1.0, 1.0], [1.0, -1.0], [-1.0, 1.0], [-1.0, -1.0]]
)  # (front +1, left +1)

# --- Table 1
ENVELOPE = np.array([4.8, 5.0, 3.0])  # length x width x height [m]
LEG_LENGTH = 3.7  # [m]
MASS = 7000.0  # [kg]
POWER = 41.9e3  # [W]

# --- chosen geometry (module docstring)
PIVOT_X = 1.1  # [m] pivot x offset from the COG, Sigma_b
PIVOT_Y = 1.2  # [m]
PIVOTS = np.concatenate(
    [LEG_SIGNS * np.array([PIVOT_X, PIVOT_Y]), np.zeros((4, 1))], axis=1
)  # (4, 3)
NEUTRAL_REACH = 1.0  # [m] neutral foot offset from the pivot along x and y (outward)
NEUTRAL_FEET = np.concatenate(
    [
        LEG_SIGNS * np.array([PIVOT_X + NEUTRAL_REACH, PIVOT_Y + NEUTRAL_REACH]),
        np.zeros((4, 1)),
    ],
    axis=1,
)  # (4, 3), in Sigma_b at z = 0
FOOT_RADIUS = 0.15  # [m] foot pad radius
R_IN = 0.6  # [m] inner radius of the reachable area (Fig. 3)
R_OUT = 2.3  # [m] outer radius (Fig. 3)
R_THETA = math.radians(90.0)  # [rad] opening angle of the reachable fan (Fig. 3)
LEG_AXIS_ANGLES = np.arctan2(
    LEG_SIGNS[:, 1], LEG_SIGNS[:, 0]
)  # fan centre directions [rad]
PIVOT_HEIGHT = (
    2.2  # [m] pivot above the ground in the neutral pose (model side may refine)
)

# --- gait (Sections 5-6; chosen values)
L_STD = 0.5  # [m] standard COG longitudinal shift per half cycle
W_STD = 1.0  # [m] standard COG lateral shift per half cycle (|W_std|)
STRIDE_EXPONENT = 1.5  # k of the directional stride L_std / max(|cos|, |sin|)^k (ours)
S_NE_C = 0.03  # [m] critical NE stability margin S_NE^c (module docstring)
H_G = 1.5  # [m] COG height above the virtual contact plane (Sec. 6.3)
DW = 0.1  # [m] lateral increment of modifications (a), (b) and Sec. 5.5
N_W = 5  # lateral trials: |W| = W_std + i DW, i < N_W ("a certain value", Sec. 5.2.3)
N_W_DOWN = 3  # (added) then narrower: |W| = W_std - k DW, k = 1 .. N_W_DOWN (gait.trial_lateral)
N_L = 6  # longitudinal trials: |L| = L_max (N_L - j) / N_L, j < N_L (modification (a)-2)
SWING_CLEARANCE = 0.15  # [m] above the highest point under the return path (Sec. 6.4.1)
SWING_MIN_LIFT = 0.2  # [m] minimum lift above the virtual plane
SWING_HEIGHT = 0.5  # [m] the executor's foot lift above the higher of lift-off and touchdown, default (ours)
UNEVEN_MAX = (
    0.1  # [m] height range under a foot pad that makes a cell forbidden (Sec. 8.2.1)
)

# --- grid maps and foothold search (Sec. 5.3, 8.2.1)
CELL = 0.1  # [m] grid cell size
SEARCH_HALF_ROWS = 8  # rows -1..-8 and +1..+8 about I_u (Sec. 5.3, step 3)
SEARCH_HALF_COLS = 8  # points 0, +-1 .. +-8 along each row (Sec. 5.3, step 2)
SEARCH_STEP = CELL  # [m] spacing of the search points
LOOKAHEAD_HALF = (
    3  # r-bar landings tried by the D_f look-ahead: (2 k + 1)^2 points, 2 cells apart
)

# --- frames (Sec. 7, 8.3, 8.4) [m]
FRAME_SMALL = 0.2
FRAME_LARGE = 0.3
GRID_SMALL = 2.0
GRID_LARGE = 3.0
SLOPE_ANGLE = math.radians(30.0)
SLOPE_FRAME = 0.2
SLOPE_GRID = 1.5


# Every parameter a user sets (the sweep analyses `titan.stride` and `titan.walk`, the
# `titan.stride` tune objective, the footstep executor scenario's params dict
# `scenarios.PARAM_DEFAULTS` and `TitanParams`), each stated once; the paper's and the
# chosen values above are their defaults. The ranges are the grid-map planner's
# (`titan.stride`); the simulated walk and the tuning narrow some of them.
PARAMETERS = ParamTable("titan", (
    # --- the gait (Sections 4-6)
    Param("l_std", L_STD, "L_std: standard COG longitudinal shift per half cycle (stroke 2 L_std)", "m",
          lo=0.0, hi=1.0, lo_open=True),
    Param("w_std", W_STD, "W_std: standard COG lateral shift per half cycle (zigzag +-W_std / 2)", "m",
          lo=0.0, hi=2.0),
    Param("s_ne_c", S_NE_C, "S_NE^c: critical NE stability margin of every planned step", "m", lo=0.0, hi=0.3),
    # --- terrain (Sec. 7, 8.3, 8.4)
    Param("frame_size", FRAME_SMALL, "square section (width = height) of the frames; 0 = flat ground", "m",
          lo=0.0, hi=0.3),
    Param("frame_interval", GRID_SMALL, "frame grid spacing (centre lines at (k + 1/2) interval in x and y)", "m",
          lo=1.0, hi=5.0),
    Param("frame_size_b", 0.0, "second field's frame section in a mixed field (mix_block > 0)", "m", lo=0.0, hi=0.3),
    Param("frame_interval_b", GRID_LARGE, "second field's frame grid spacing in a mixed field", "m", lo=1.0, hi=5.0),
    Param("mix_block", 0.0, "side of the checkerboard blocks alternating the two fields (maps.mixed_frame_map); "
          "0 = one field", "m", lo=0.0, hi=50.0),
    Param("slope", 0.0, "slope angle of the map frame about the world y axis (Sec. 8.4: 30 deg)", "rad",
          lo=0.0, hi=0.7),
    Param("direction", 0.0, "map-frame walking direction (0 = +x, up the fall line on a slope); every heading plans "
          "(gait.directional_stride); start_x and the map must leave room for the walk", "rad",
          lo=-2 * math.pi, hi=2 * math.pi),
    Param("start_x", 3.0, "map x of the start COG (y: the map's centre line)", "m", lo=0.0, hi=100.0),
    Param("tether", 1.0, "fraction of the slope-parallel gravity the tethers cancel (Sec. 8.1)", "", lo=0.0, hi=1.0),
    Param("mu", 0.6, "friction coefficient of the terrain", "", lo=0.05, hi=2.0),
    # --- the grid-map planner's sweep rows and their smooth objective
    Param("softmin_tau", 0.005, "temperature tau of the soft-min NESM (log-sum-exp) and of the objective's sigmoid",
          "m", lo=0.0, hi=0.1, lo_open=True),
    Param("n_cycles", 4, "gait cycles planned per row (6 steps each)", "", kind="int", lo=1, hi=64, sweepable=False),
    Param("map_nx", 160, "grid map cells along x", "", kind="int", lo=60, hi=1000, sweepable=False),
    Param("map_ny", 100, "grid map cells along y (the start COG is at y = map_ny cell / 2)", "", kind="int",
          lo=60, hi=1000, sweepable=False),
    Param("cell", CELL, "grid map cell size", "m", lo=0.02, hi=0.2, sweepable=False),
    # --- the tuning's loss (`tuning.py`)
    Param("w_margin", 1.0, "weight of the margin term: reference distances (1 m/cycle) per softmin_tau of "
          "soft-min NESM below S_NE^c", "", lo=0.0, hi=1e3),
    Param("n_offsets", 1, "frame-grid phases the loss averages over (1: the sweep row alone; flat ground: 1)",
          "", kind="int", lo=1, hi=16, sweepable=False),
    Param("horizon", 10.0, "titan.body_gain: simulated time of the MJX rollout (settle_time, then the plan's first "
          "steps of step_time each)", "s", lo=0.5, hi=40.0),
    # --- the simulated walk (`sim_analysis.py`)
    Param("field", "grid", "terrain: 'grid' (Sec. 7 / 8.4 frame grids, frame_size / frame_interval / slope) or "
          "'long' (the Sec. 8.3 dummy-frame field walk.LONG_FIELD, 0.2 m beams every 1.5 m, walked along +x)",
          kind="str", choices=("grid", "long")),
    Param("map", "survey", "planning map: 'survey' (a total-station survey with survey_noise, Sec. 8.2.1) or "
          "'exact' (the true beams; grid field only)", kind="str", choices=("survey", "exact")),
    Param("survey_noise", 0.005, "std of each surveyed coordinate (Sec. 8.2.1: +-5 mm), from the row's seed", "m",
          lo=0.0, hi=0.05),
    Param("start_jitter", 0.5, "perturbed trials: the start COG moves by U(-1, 1) x this in x and y, from the row's "
          "seed", "m", lo=0.0, hi=2.0),
    Param("nesm_tol", 0.0, "success allowance of the simulated min NESM below S_NE^c (0: the paper's criterion as it "
          "stands)", "m", lo=0.0, hi=0.05),
    *simulation_params(),  # backend, nthread
    # --- the footstep executor scenario's params dict (`scenarios.PARAM_DEFAULTS`, one
    # value per simulation; no analysis sweeps them but body_gain, so no other range is stated)
    Param("theta", 0.0, "scenario: inclination of the terrain plane (the analyses' slope)", "rad"),
    Param("spacing", 2.0, "scenario: frame grid spacing (the analyses' frame_interval)", "m"),
    Param("beam_height", 0.0, "scenario: frame protrusion (0: plain ground)", "m"),
    Param("heading", 0.0, "scenario: body yaw about the plane normal", "rad"),
    Param("step_time", 3.0, "scenario: duration of each step (swing or body shift)", "s"),
    Param("settle_time", 1.0, "scenario: standing before the first step", "s"),
    Param("swing_height", SWING_HEIGHT, "scenario: the executor's foot lift above the higher of lift-off and "
          "touchdown, default (ours)", "m"),
    Param("contact_force", 0.05, "scenario: a touch above this fraction of M g is a contact"),
    Param("body_gain", 3.0, "scenario: integral gain of the body position and attitude correction "
          "(control.executor_step); the loop rings from ~25 /s (gain x control period ~1) and falls over at 50 /s",
          "1/s", lo=0.0, hi=20.0),
    Param("anchor_feet", 1.0, "scenario: 1 re-references the foot targets to the measured feet at each step "
          "(control.anchor_to_feet)"),
    Param("support_relative", 1.0, "scenario: 1 lets the COG target follow the supporting feet's slip "
          "(control.support_shift)"),
    Param("load_feedforward", 1.0, "scenario: 1 pre-deflects the servos by the static foot loads "
          "(control.load_feedforward)"),
    Param("mass_feedforward", 1.0, "scenario: 1 moves the body against the legs' mass (control.body_for_com); "
          "0: integral correction only"),
    Param("touchdown_tol", 0.1, "scenario: success needs every touchdown error below this", "m"),
    Param("path_tol", 0.1, "scenario: success needs every path deviation at a cycle end below this", "m"),
))


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class TitanParams:
    """Gait constants as a pytree: every field is a leaf (traceable, sweepable,
    vmappable). Geometry arrays are in Sigma_b; SI units."""

    l_std: jax.Array = PARAMETERS.default("l_std")  # [m]
    w_std: jax.Array = PARAMETERS.default("w_std")  # [m]
    s_ne_c: jax.Array = PARAMETERS.default("s_ne_c")  # [m]
    h_g: jax.Array = H_G  # [m]
    dw: jax.Array = DW  # [m]
    r_in: jax.Array = R_IN  # [m]
    r_out: jax.Array = R_OUT  # [m]
    r_theta: jax.Array = R_THETA  # [rad]
    foot_radius: jax.Array = FOOT_RADIUS  # [m]
    swing_clearance: jax.Array = SWING_CLEARANCE  # [m]
    swing_min_lift: jax.Array = SWING_MIN_LIFT  # [m]
    search_step: jax.Array = SEARCH_STEP  # [m]
    stride_exponent: jax.Array = STRIDE_EXPONENT  # L_std(psi) = L_std / m^k (gait.directional_stride)
    tether: jax.Array = PARAMETERS.default("tether")  # fraction of the slope-parallel gravity offset by the tethers

    def pivots(self) -> jax.Array:
        """Leg pivots in Sigma_b, (4, 3)."""
        return jnp.asarray(PIVOTS, jnp.asarray(self.l_std).dtype)

    def neutral_feet(self) -> jax.Array:
        """Neutral foot positions in Sigma_b (z = 0 plane), (4, 3)."""
        return jnp.asarray(NEUTRAL_FEET, jnp.asarray(self.l_std).dtype)

    def with_(self, **changes) -> TitanParams:
        return replace(self, **changes)

    def astype(self, dtype) -> TitanParams:
        return jax.tree_util.tree_map(lambda x: jnp.asarray(x, dtype), self)


def default_params() -> TitanParams:
    return TitanParams()
