"""The e-OCTOPUS of Chen et al. (ROBOMECH J. 2018): four arms on a two-crawler,
four-flipper base. Dimensions and constants with their paper references, and every value
the paper does not give (its figures are missing), chosen here and justified.

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

# --- terrain exploration thresholds sigma_1..3 [m] (chosen; "can be set according to
# actual condition")
SIGMA = np.array([0.05, 0.45, 0.45])

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
