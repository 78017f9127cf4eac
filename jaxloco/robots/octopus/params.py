"""The e-OCTOPUS of Chen et al. (ROBOMECH J. 2018): four arms on a two-crawler,
four-flipper base. Dimensions and constants with their paper references, and every value
the paper does not give (its figures are missing), chosen here and justified; and
`PARAMETERS`, every parameter a user can set (`jaxloco.parameters.ParamTable`).

Frames (paper, "Preparation: coordinate systems" and Fig. 4):
  * robot frame {R}: x forward, y left, z up; origin at the centre of the rectangle of
    the four arm bases (swing axes), at the height of the boom axes. Eqs. 4-6 put the
    left-front arm base at (m/2, n/2, 0) in {R}; in the MJCF {R} is the `chassis` body
    frame and the IMU site sits at its origin;
  * joint frame {J_i} of arm i: origin at the arm base, axes parallel to {R} (the paper
    builds every joint frame "with the same direction as {W}"), in which Eqs. 1-3 hold;
  * level frame {C} (Eqs. 10-16): origin of {R}, axes of {W} with the yaw removed.

Arm numbering (Table 2 and "Take the left front arm ... P_1"): 1 left-front (LF),
2 right-front (RF), 3 left-rear (LR), 4 right-rear (RR). Array index k = i - 1.
(The printed Eq. 8 reads as if the arms were numbered clockwise, 1 LF 2 RF 3 RR 4 LR;
Table 2 gives P3 y = +399 and P4 y = -399 at the start, so we follow Table 2; see
`kinematics.explore_terrain`.)

Attitude convention (Eqs. 12-13 as printed): A_P > 0 is nose up, A_R > 0 is left side
down. These are minus the usual z-up roll/pitch; `kinematics.attitude_from_quat` does the
conversion from the IMU quaternion.

Values chosen here (not in the text):
  * m = n = 500 mm: the arm bases at the corners of the 500 mm body (the step-climbing
    section: "500 is the length of robot body"). With m/2 = 250 mm Table 2 is symmetric
    front/rear: P1's target and P4's start are both 368 mm beyond their arm bases.
  * roller radius 50 mm; the EPRA of Eqs. 1-6 is the roller centre (the tip site).
  * base height h = 433 + 50 = 483 mm: Table 2 puts every EPRA at z = -433 mm in {R}
    while the robot stands on its crawlers, so on flat ground the boom axes are 483 mm
    above the ground.
  * l2 = 680 mm: with the arms straight up the top of the rollers is at
    h + l1 + l2 + r = 1703 mm, the 1700 mm height of Table 3. Every Table 2 point is
    then reachable with the elbow well away from both singular configurations
    (|l1 - l2| = 190 mm <= D <= l1 + l2 = 1170 mm with D in [454, 582] mm), and the boom is
    at -0.34 ... -0.53 rad in those poses (the paper lifts the front booms to -0.6 rad).
  * crawler and flipper geometry (`MAIN_*`, `FLIPPER_*`): the main crawler is the 500 mm
    body length long; flippers are 250 mm long ("Tasks setting": "the length of flippers"),
    pivot on the main crawler's end axles, in line with it.
  * masses (`MASS_*`): 100 kg in all (Table 3) with the weight "concentrated in the
    chassis" and the COG low: 210 mm below {R}, 273 mm above flat ground.
  * sigma_1..3 (terrain exploration): 50 mm (above the crawler-wheel bumps and FK error),
    450 mm (the robot climbs 400 mm steps in CLM), 450 mm (same for descending).
  * the Table 3 envelope 1800 x 1100 x 1700 mm is reproduced in `ENVELOPE_POSE`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco.analysis import Param
from jaxloco.parameters import ParamTable, simulation_params

G = 9.81  # [m/s^2]

ARM_NAMES = ("arm1", "arm2", "arm3", "arm4")  # LF, RF, LR, RR (Table 2 numbering)
ARM_LABELS = ("LF", "RF", "LR", "RR")
ARM_JOINTS = ("swing", "boom", "elbow")
ARM_SIGNS = np.array([[1.0, 1.0], [1.0, -1.0], [-1.0, 1.0], [-1.0, -1.0]])  # (sx, sy) of each base
FLIPPER_NAMES = ("flipper_fl", "flipper_fr", "flipper_rl", "flipper_rr")
FLIPPER_SIGNS = np.array(
    [[1.0, 1.0], [1.0, -1.0], [-1.0, 1.0], [-1.0, -1.0]]
)  # (front +1 / rear -1, left +1 / right -1)
CRAWLER_NAMES = ("crawler_l", "crawler_r")
# Actuator order in the MJCF (ctrl vector): crawlers [m/s], flippers [rad], arms [rad].
ACTUATOR_NAMES = CRAWLER_NAMES + FLIPPER_NAMES + tuple(f"{a}_{j}" for a in ARM_NAMES for j in ARM_JOINTS)

# --- Table 1 (D-H parameters of an arm) [m]
L1 = 0.490
D3 = 0.078
# --- chosen (module docstring)
L2 = 0.680
ARM_BASE_M = 0.500  # m: longitudinal distance between arm bases
ARM_BASE_N = 0.500  # n: lateral distance between arm bases
ROLLER_RADIUS = 0.050
# --- Table 2 [m, in {R}]; P4's target y is printed +399, a typo for -399 (P4 is the
# right-rear arm: y = -399 at the start, and the target layout is left/right symmetric).
TABLE2_INIT = np.array(
    [[0.540, 0.399, -0.433], [0.298, -0.399, -0.433], [-0.419, 0.399, -0.433], [-0.618, -0.399, -0.433]]
)
TABLE2_TARGET = np.array(
    [[0.618, 0.399, -0.433], [0.618, -0.399, -0.433], [-0.121, 0.399, -0.433], [-0.121, -0.399, -0.433]]
)
BASE_HEIGHT = -TABLE2_INIT[0, 2] + ROLLER_RADIUS  # {R} origin above flat ground [m]

# --- Table 3
TOTAL_MASS = 100.0  # [kg]
ENVELOPE = np.array([1.800, 1.100, 1.700])  # length x width x height [m]
CRAWLER_MAX_SPEED = 0.063  # [m/s]
# --- text: "Tasks setting" and "getting over obstacle"
FLIPPER_LENGTH = 0.250  # pivot to tip-wheel centre [m] ("250 mm (the length of flippers)")
FLIPPER_LIMIT = math.radians(85.0)  # flipper angle limit A_0 ("85 deg in this robot")

# --- crawlers (chosen): rows of sphere wheels, see model.py
CRAWLER_Y = 0.250  # lateral position of the main crawlers and flippers [m]
MAIN_WHEEL_RADIUS = 0.090
MAIN_AXLE_X = 0.250 - MAIN_WHEEL_RADIUS  # end axles at +-0.16 m: crawler 500 mm long
MAIN_WHEELS = 6  # per side, equally spaced between the end axles
FLIPPER_TIP_RADIUS = 0.055
FLIPPER_WHEELS = 3  # per flipper, up to the tip; the pivot wheel is the main end wheel
# Flipper angle 0: the flipper's lower tangent continues the main crawler's bottom line,
# so its centre line dips by FLIPPER_DIP below the horizontal; > 0 lifts the tip.
FLIPPER_DIP = math.asin((MAIN_WHEEL_RADIUS - FLIPPER_TIP_RADIUS) / FLIPPER_LENGTH)

# --- masses (chosen) [kg]; they add up to TOTAL_MASS
MASS_CHASSIS = 30.0  # main chassis box
MASS_BATTERY = 14.0  # low battery box
MASS_DECK = 5.0  # arm deck on top
MASS_SIDE_FRAME = 6.0  # each main crawler frame
MASS_MAIN_WHEEL = 0.5
MASS_FLIPPER_FRAME = 1.5
MASS_FLIPPER_WHEEL = 0.25
MASS_SHOULDER = 1.0  # swing link
MASS_BOOM = 2.5
MASS_FOREARM = 2.0
MASS_ROLLER = 0.5

# COG in {R} with the arms in the Table 2 start pose (`home` keyframe), from the MJCF
# (tests/test_octopus_model.py checks it). The paper assumes it fixed while moving.
COG_R = np.array([-0.005, -0.002, -0.210])

# ------------------------------------------------------------------ user parameters
# Every parameter a user can set (sweep analyses, the tune objective, the simulations'
# params dicts), each stated once: SIGMA, `clm`, `ccm`, `operator` and `scenarios` take
# their defaults from here, the analyses select theirs (with per-analysis changes where one
# needs another default, range or doc).
MAX_HEIGHT = 0.6  # [m] highest step the terrain boxes allow (`scenarios`)
TERRAINS = ("flat", "step_up", "step_down", "slope_up", "slope_down", "rough")  # `analysis`
_CODES = ", ".join(f"{i} {n}" for i, n in enumerate(TERRAINS))
PARAMETERS = ParamTable("octopus", (
    # terrain exploration (`kinematics.terrain_case`, `octopus.terrain_classification`, `octopus.sigma`)
    Param("sigma1", 0.05, "sigma_1: |z1 - z4|, |z2 - z3| below it is flat (Case 1)", "m", lo=0.0, hi=2.0, lo_open=True),
    Param("sigma2", 0.45, "sigma_2: upper bound of an upward step (Case 2)", "m", lo=0.0, hi=2.0, lo_open=True),
    Param("sigma3", 0.45, "sigma_3: upper bound of a downward step (Case 3)", "m", lo=0.0, hi=2.0, lo_open=True),
    Param("terrain", TERRAINS.index("step_up"), f"terrain type in front of the robot: {_CODES}", "", kind="int",
          choices=tuple(range(len(TERRAINS)))),
    Param("edge", 0.45, f"x in {{R}} of the step edge (front endpoints at x = {float(TABLE2_TARGET[0, 0]):g}; "
          "crawler front at 0.25)", "m", lo=0.25, hi=1.0),
    Param("noise", 0.005, "std of the sensed endpoint positions (per coordinate)", "m", lo=0.0, hi=0.1),
    Param("imu_noise", 0.0, "std of the sensed pitch and roll", "rad", lo=0.0, hi=0.2),
    Param("flat_tol", 0.02, "ground truth: a true height difference below this is flat", "m", lo=0.0, hi=0.5),
    Param("step_min", 0.05, "ground truth: a true height difference of this or more is an obstacle "
          "(between flat_tol and step_min both answers count)", "m", lo=0.0, hi=0.5),
    Param("climb_max", 0.45, "ground truth: highest step the robot can climb (paper: 0.40 m climbed in CLM)", "m",
          lo=0.0, hi=2.0),
    Param("descend_max", 0.45, "ground truth: deepest step the robot can descend", "m", lo=0.0, hi=2.0),
    Param("slope_max", math.radians(30.0), "ground truth: steepest slope the robot can climb (Table 3: 30 deg)",
          "rad", lo=0.0, hi=0.5 * math.pi),
    Param("samples", 64, "Monte-Carlo samples per row (terrain draws and sensing noise)", "", kind="int",
          lo=1, hi=4096, sweepable=False),
    # the sigma objective's sample bank (`tuning`)
    Param("tau", 0.005, "temperature of the sigmoid relaxation of each threshold test", "m", lo=0.0, hi=0.1,
          lo_open=True),
    Param("danger_weight", 4.0, "cost of a wrong autonomous class (flat, up, down) relative to a wrong "
          "'undetectable'", "", lo=0.0, hi=1000.0, lo_open=True),
    Param("seed", 0, "PRNG seed of the sample bank", "", kind="int", lo=0, hi=2**31 - 1),
    Param("terrains", ",".join(TERRAINS), "comma-separated terrain types drawn uniformly (of "
          f"{', '.join(TERRAINS)})", "", kind="str"),
    Param("height_min", 0.0, "lowest step height / slope rise / rough amplitude drawn", "m", lo=0.0, hi=0.7),
    Param("height_max", 0.6, "highest step height / slope rise / rough amplitude drawn", "m", lo=0.0, hi=0.7),
    # the step climb in MuJoCo (`octopus.step_climb`, `octopus.paper`)
    Param("kind", "step1", "terrain: one terrace, two terraces from the front, or from the side, a block "
          "(height) beside the robot's right side, or a pit (the robot on a platform of height whose edge is at "
          "distance, nothing beyond)", kind="str",
          choices=("step1", "step2_front", "step2_side", "block", "pit"), sweepable=False),
    Param("controller", "clm", "the CLM controller (crawlers, flippers and arms) or the CCM baseline (crawlers "
          "and flippers only)", kind="str", choices=("clm", "ccm"), sweepable=False),
    # terrain and physics
    Param("height", 0.4, "total step height", "m", lo=0.0, hi=MAX_HEIGHT),
    Param("distance", 0.7, "chassis origin to the first riser at t = 0", "m", lo=0.4, hi=3.0),
    Param("yaw", 0.0, "initial heading relative to the step normal", "rad", lo=-0.8, hi=0.8),
    Param("side_ratio", 0.5, "step2_side: right rise / left rise", "", lo=0.0, hi=1.0),
    Param("block_gap", 0.01, "block: gap between the robot's right side and the block", "m",
          lo=0.0, hi=1.0),
    Param("mu", 0.8, "terrain friction coefficient", "", lo=0.1, hi=2.0),
    Param("distance_jitter", 0.0, "distance + U(-1, 1) x this, from the row's seed (the simulation itself is "
          "deterministic: seeds only matter through the jitters)", "m", lo=0.0, hi=0.5),
    Param("yaw_jitter", 0.0, "yaw + U(-1, 1) x this, from the row's seed", "rad", lo=0.0, hi=0.5),
    Param("mu_jitter", 0.0, "mu + U(-1, 1) x this, from the row's seed (mu stays >= 0.1)", "", lo=0.0, hi=1.0),
    # CLM gains (`clm`)
    Param("T0", 15.0, "CLM: front flipper torque threshold T0 (flipper rule Cases 1-3); default ours, the "
          "paper gives none", "N m", lo=1.0, hi=80.0),
    Param("flip_delta_a", 0.02, "CLM: Delta_A, front flipper step of the torque rule; default ours",
          "rad/period", lo=0.001, hi=0.1),
    Param("flip_delta_b", 0.01, "CLM: Delta_B, front flipper step of the torque rule; default ours",
          "rad/period", lo=0.001, hi=0.1),
    Param("delta_e", 0.006, "CLM: Delta_E, boom step of the climb / release (the level lift moves the "
          "EPRAs Delta_E l1 per period); default ours", "rad/period", lo=0.0005, hi=0.05),
    Param("delta_f", 0.01, "CLM: Delta_F, flipper step of the climb / release; default ours",
          "rad/period", lo=0.001, hi=0.1),
    Param("lift_speed", 0.1, "octopus.climb_lift: the body's rise per second wanted in the CLIMB (the COG's); "
          "default (ours), the paper gives none", "m/s", lo=0.01, hi=0.3),
    Param("clm_speed", 0.03, "CLM: crawler speed (default ours; the crawlers reach 63 mm/s, Table 3)",
          "m/s", lo=0.005, hi=0.063),
    # the paper's method is the default (since 7 Dec 2026; it does not get over a step in our simulation yet:
    # docs/octopus.md); our level lift is the named option climb_paper = 0
    Param("climb_paper", 1.0, "CLM climb: 1 = the paper's Eqs. 28-29 (booms and front flippers "
          "turn down, crawlers drive; the default); 0 = our level lift (a named option, not the paper's method)",
          "", lo=0.0, hi=1.0),
    Param("flip_encoder", 1.0, "paper climb reading: 1 = A' of Eq. 29 is the flipper encoder "
          "(\"obtained\"), 0 = the last command", "", lo=0.0, hi=1.0),
    Param("climb_yield", 1.0, "paper climb reading: 1 = the front flippers' torque rule (Case 2) keeps "
          "running in CLIMB", "", lo=0.0, hi=1.0),
    Param("climb_rear_flippers", 0.0, "paper climb reading: 1 = Eq. 29 turns the rear "
          "flippers too, 0 = the front ones (A of 'Crawler controls')", "", lo=0.0, hi=1.0),
    Param("climb_common_axis", 0.0, "paper climb reading: 1 = Eq. 28's +Delta_E turns every boom about the "
          "authors' common axis (the transfer's A_B: +0.6 rear, -0.6 front), so the front booms turn down and the "
          "rear ones up; 0 = every boom down", "", lo=0.0, hi=1.0),
    Param("climb_per_side", 1.0, "paper climb: 1 = each side's arms and front flipper follow Eqs. 28-29 with "
          "that side's H and step height (Fig. 17: the sides 'adapt the terrain separately'); 0 = both sides by "
          "Eq. 9's H_EST", "", lo=0.0, hi=1.0),
    Param("s_from_touch", 0.0, "paper climb reading: 1 = S (Eq. 18) from the front flippers' "
          "touch-down on the step top, 0 = from the CLIMB start", "", lo=0.0, hi=1.0),
    Param("prepare_rear_init", 1.0, "PREPARE places the rear arms at their Table 2 start "
          "points (1, ours) or targets (0)", "", lo=0.0, hi=1.0),
    Param("crawl_max_h", 0.0, "CLM: steps up to this H_EST are climbed by crawlers and flippers, "
          "arms carried (CRAWL: ours, a named option, not the paper's method; 0 = the arms climb every step, "
          "the default)", "m", lo=0.0, hi=MAX_HEIGHT),
    Param("operator_gain", 0.0, "operator steering (not the CLM: it cannot "
          "measure the yaw): track speed difference per rad of heading error while driving straight; 0 = no "
          "operator, the paper's rows", "m/s per rad", lo=0.0, hi=1.0),
    # the CCM baseline
    Param("speed", CRAWLER_MAX_SPEED, "CCM: commanded crawler speed", "m/s", lo=0.005, hi=0.063),
    # run
    Param("horizon", 90.0, "simulated time", "s", lo=1.0, hi=600.0, sweepable=False),
    *simulation_params(),  # backend, nthread
    # the paper's experiments (`octopus.paper`)
    Param("task", "step1_clm", "the paper's experiment", kind="str"),
))

# --- terrain exploration thresholds sigma_1..3 [m] (chosen; "can be set according to
# actual condition"): PARAMETERS' sigma1..3
SIGMA = np.array([PARAMETERS.default(f"sigma{k}") for k in (1, 2, 3)])

# Table 3 envelope pose: flippers level; front arms straight up; rear arms straight,
# raised ENVELOPE_REAR_RAISE above the horizontal and pointing backwards, splayed
# outwards by ENVELOPE_REAR_SPLAY. The text has no figure of the pose behind Table 3;
# this one reproduces 1800 x 1100 x 1700 mm (tests/test_octopus_model.py) with the
# dimensions above (the front arms set the height, the rear arms length and width).
ENVELOPE_REAR_RAISE = 0.46  # [rad]
ENVELOPE_REAR_SPLAY = 0.24  # [rad]
ENVELOPE_POSE = np.array(
    [
        [0.0, -0.5 * math.pi, 0.0],
        [0.0, -0.5 * math.pi, 0.0],
        [math.pi - ENVELOPE_REAR_SPLAY, -ENVELOPE_REAR_RAISE, 0.0],
        [-math.pi + ENVELOPE_REAR_SPLAY, -ENVELOPE_REAR_RAISE, 0.0],
    ]
)


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class OctopusParams:
    """Constants used by the kinematics and estimators, as a pytree (every field is a
    leaf: it can be traced, swept and differentiated). SI units; frames in the module
    docstring."""

    l1: jax.Array = L1  # boom length (Table 1) [m]
    l2: jax.Array = L2  # forearm length to the roller centre (chosen) [m]
    d3: jax.Array = D3  # lateral elbow offset (Table 1) [m]
    m: jax.Array = ARM_BASE_M  # arm base spacing along x_R (Eqs. 4-6) [m]
    n: jax.Array = ARM_BASE_N  # arm base spacing along y_R (Eqs. 4-6) [m]
    roller_radius: jax.Array = ROLLER_RADIUS  # [m]
    cog: jax.Array = field(default_factory=lambda: COG_R.copy())  # COG in {R} [m]
    sigma: jax.Array = field(default_factory=lambda: SIGMA.copy())  # sigma_1..3 [m]

    def arm_bases(self) -> jax.Array:
        """Arm base (swing axis / boom axis intersection) positions in {R}, (4, 3), arms
        1..4 (Eqs. 4-6 generalised: (+-m/2, +-n/2, 0))."""
        half = jnp.stack([0.5 * jnp.asarray(self.m), 0.5 * jnp.asarray(self.n)])
        xy = jnp.asarray(ARM_SIGNS, half.dtype) * half
        return jnp.concatenate([xy, jnp.zeros((4, 1), half.dtype)], axis=1)

    def with_(self, **changes) -> OctopusParams:
        return replace(self, **changes)

    def astype(self, dtype) -> OctopusParams:
        """The same robot with every field in `dtype` (e.g. jnp.float32)."""
        return jax.tree_util.tree_map(lambda x: jnp.asarray(x, dtype), self)


def default_params() -> OctopusParams:
    return OctopusParams()
