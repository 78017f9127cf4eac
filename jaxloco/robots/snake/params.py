"""T² Snake-3 with the Omni-gripper (Tanaka et al., IEEE T-RO 35(1), 2019): Table I
dimensions, the joint / wheel layout of Sec. II-A and IV-A, the modes of Table II and
the values the paper does not give, each with the reason for the chosen value; and
`PARAMETERS`, every parameter a user can set (`jaxloco.parameters.ParamTable`).

Frames and units: SI, radians. The world is the paper's O-xyz with the ground the
plane z = 0. Every link frame has x forward (towards the head), y left (along the
wheel axles of a straight robot), z up.

Paper values:
  * Table I: n = 9 modules, link length l = 90.5 mm, module length L = 181 mm (= 2 l),
    total size H x W x L = 175 x 175 x 1729 mm, wheel radius r = 50 mm, pitch range
    |psi| <= 113 deg, yaw range |theta| <= 65 deg, total mass 10 kg.
  * Sec. II-A: yaw and pitch joints alternate, theta_1, psi_1, ..., psi_{n-1}, theta_n
    (n = 9 yaw, n - 1 = 8 pitch joints; psi_b = [psi_{n_h/2+1} .. psi_{n-1}] has
    n_b - 1 entries, so the last joint is the yaw joint theta_n); a pair of wheels is
    coaxial with each pitch joint, one active and one passive (Fig. 4(b)).
  * Sec. IV-C3, IV-C6: n_h = 6 (head part theta_1..psi_3), so n_b = n - n_h/2 = 6
    (theta_4..theta_9); the SCP is the n_h-th joint psi_3 (m = 1), target 110 deg.
  * Sec. V-A: initial joint angles phi = [0, -0.8, 0, -1.1, 0, 1.9, 0, ..., 0].
  * Sec. IV-B: Omni-gripper 50 mm diameter, 90 mm long, 87 g.
  * Table II: 7 wheel pairs on the base part; modes 1-6 (grounded mask below).

Chosen values (not in the text):
  * 17 joints give 18 links of length l each, joint to joint (module = yaw + pitch
    joint = 2 l = L). Link 1 is the head: the head frame w_h is at its front end, l
    ahead of theta_1. The gripper (in operation, Fig. 4(f); its two rotational joints
    on the head are fixed, gripper pointing forward along the head's x) puts the
    controlled point w, the gripper tip, GRIPPER_TIP = 100 mm ahead of the head frame
    (90 mm gripper + 10 mm mount). Then gripper tip to tail end = 18 l + 100 mm =
    1729 mm, Table I's total length.
  * Wheel pairs: Eq. 2 has n_b + 1 = 7 side-slip rows for the base part and Table II
    numbers 7 base pairs, one per rigid segment of the (flat) base between its yaw
    joints. The pitch joints psi_3..psi_8 give six; the seventh is a tail pair on the
    last link, axle TAIL_AXLE = l - r behind theta_9 so that the wheels end flush with
    the tail (they stay inside the 1729 mm). Base pair 1 is at psi_3 (the head end of
    the base: Sec. IV-C5 "the wheel of the head of the base part"), pair 7 at the tail.
    The head part has pairs at psi_1 and psi_2 (in the model, ignored by the kinematic
    model as the paper says: "active wheels of the head part are ignored").
  * Active wheel on the left (+y) of each pair, passive on the right (Fig. 4(b) shows
    one of each, the side is not given).
  * Track widths (Sec. IV-A: "we increase the lengths between the wheels of the first,
    third, and fifth pairs on the base part ... and batteries are relocated from the
    head and tail to the generated spaces"; "batteries are installed for each passive
    wheel"). Two readings: (a) the distance between the two wheels *of* pairs 1, 3, 5
    (their track) is larger, the batteries sit between the link and the passive wheel;
    (b) the distance between pairs 1-2, 3-4, 5-6 along the body is longer. We take (a):
    (b) contradicts Table I, whose modules are all L = 181 mm long and whose 1729 mm
    total length is already 9 L + the 90 mm gripper + 10 mm (`test_snake_model`
    checks both); under (b) the three longer gaps would have to fit in those 10 mm.
    So base pairs 1, 3, 5 (pairs 3, 5, 7 here, WIDE_PAIRS) have their wheel centres at
    +-WIDE_WHEEL_Y = +-77.5 mm (wheel width 20 mm: outer faces 175 mm apart, Table I's
    width); the other pairs at +-NARROW_WHEEL_Y = +-67.5 mm (outer faces 155 mm apart),
    default (ours: the paper gives no number). A BATTERY_MASS = 0.2 kg box, default
    (ours), 18 mm thick, sits in the 20 mm between the link and each wide pair's passive
    wheel. The 175 mm height (camera, stored gripper) is not modelled: links are boxes
    95 x 80 mm (W x H, ours) in section centred on the axle line, 10 mm ground clearance
    when flat, 10 mm inside the narrow pairs' wheels. (A narrower track, 57.5 mm, left
    the narrow pairs beside a wide one hovering 2-3 mm above the ground in the zigzag of
    Sec. V-B; see scenarios.CONTACT_TOL.)
  * Masses (10 kg, Table I): gripper 87 g (Sec. IV-B), 18 wheels of 0.1 kg, three
    batteries of 0.2 kg, links 2..18 0.415 kg each, the head link the rest (0.458 kg,
    it carries the gripper's two joints), default (ours) but the total and the
    gripper.
  * Joint sign conventions: a positive yaw angle theta_i turns the front (head side)
    link to the left relative to the rear one; a positive pitch angle psi_i raises the
    front link (psi_3 = +110 deg raises the head part, Sec. IV-C3 and Fig. 4(a)).
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

# --- Table I
N_MODULES = 9  # n: number of modules = number of yaw joints
LINK_LENGTH = 0.0905  # l [m]
MODULE_LENGTH = 0.181  # L [m] = 2 l
SIZE_HWL = (0.175, 0.175, 1.729)  # total size H x W x L [m]
WHEEL_RADIUS = 0.050  # r [m]
PITCH_LIMIT = math.radians(113.0)  # |psi_i| <= 113 deg
YAW_LIMIT = math.radians(65.0)  # |theta_i| <= 65 deg
MASS = 10.0  # [kg]

# --- joint layout (Sec. II-A)
N_YAW = N_MODULES  # theta_1 .. theta_9
N_PITCH = N_MODULES - 1  # psi_1 .. psi_8
N_JOINTS = N_YAW + N_PITCH  # 17, alternating theta_1, psi_1, ..., psi_8, theta_9
N_LINKS = N_JOINTS + 1  # 18, link 1 = head
# joint k (0-based, head to tail) is a yaw joint for even k, a pitch joint for odd k
JOINT_IS_PITCH = np.array([k % 2 == 1 for k in range(N_JOINTS)])
JOINT_NAMES = tuple(
    f"psi{k // 2 + 1}" if k % 2 else f"theta{k // 2 + 1}" for k in range(N_JOINTS)
)

# --- head / base split (Sec. II-A, IV-C3, IV-C6)
N_H = 6  # n_h: joints of the head part (theta_1, psi_1, ..., theta_3, psi_3)
N_B = N_YAW - N_H // 2  # n_b = 6 yaw joints of the base part (theta_4 .. theta_9)
N_PHI = N_H + N_B  # 12: phi = [phi_h, phi_b]
# index of each phi entry in the 17-joint list (psi_b = psi_4..psi_8 are not in phi)
PHI_JOINTS = np.concatenate(
    [np.arange(N_H), N_H + 2 * np.arange(N_B)]
)  # [0..5, 6, 8, 10, 12, 14, 16]
PSI_B_JOINTS = N_H + 1 + 2 * np.arange(N_B - 1)  # [7, 9, 11, 13, 15]
SCP_INDEX = N_H - 1  # the SCP psi_{n_h/2} = psi_3 is phi[5] (Sec. IV-C3), m = 1
SCP_TARGET = math.radians(110.0)  # [rad] psi_3 target (Sec. IV-C3)
INITIAL_PHI = np.array([0.0, -0.8, 0.0, -1.1, 0.0, 1.9] + [0.0] * N_B)  # Sec. V-A [rad]

# --- wheels (chosen layout, module docstring)
N_PAIRS_BASE = N_B + 1  # 7 pairs on the base part (Table II)
N_W = N_PAIRS_BASE  # n_w: active wheels of the base part, one per pair
N_PAIRS = N_PITCH + 1  # 9 pairs: psi_1 .. psi_8 and the tail
# link (1-based) carrying each pair: the link behind the pitch joint, the tail link
PAIR_LINKS = np.array([2 * k + 3 for k in range(N_PITCH)] + [N_LINKS])
TAIL_AXLE = LINK_LENGTH - WHEEL_RADIUS  # [m] tail axle behind theta_9
PAIR_OFFSETS = np.array(
    [0.0] * N_PITCH + [-TAIL_AXLE]
)  # axle x in the carrying link's frame [m]
BASE_PAIRS = np.arange(N_PITCH - N_PAIRS_BASE + 1, N_PAIRS)  # pairs 2..8 (0-based)
WIDE_WHEEL_Y = 0.0775  # [m] wheel centre from the axle midpoint, pairs WIDE_PAIRS (Table I width)
NARROW_WHEEL_Y = 0.0675  # [m] the other pairs, default (ours)
WIDE_PAIRS = BASE_PAIRS[[0, 2, 4]]  # base pairs 1, 3, 5 (Sec. IV-A): pairs 3, 5, 7 here (0-based 2, 4, 6)
PAIR_WHEEL_Y = np.where(np.isin(np.arange(N_PAIRS), WIDE_PAIRS), WIDE_WHEEL_Y, NARROW_WHEEL_Y)  # (9,) [m]
WHEEL_Y = WIDE_WHEEL_Y  # [m] the widest track: the robot's half width less half a wheel
WHEEL_HALF_WIDTH = 0.010  # [m]
ACTIVE_SIDE = 1.0  # +1: the active wheel is the left one

# --- gripper (Sec. IV-B) and body
GRIPPER_TIP = 0.100  # [m] tip ahead of the head frame along the head x
GRIPPER_LENGTH = 0.090  # [m]
GRIPPER_RADIUS = 0.025  # [m]
GRIPPER_MASS = 0.087  # [kg]
WHEEL_MASS = 0.1  # [kg]
LINK_HALF_Y = 0.0475  # [m] half the links' width, default (ours)
BATTERY_MASS = 0.2  # [kg] one per wide pair, on its passive side, default (ours)
BATTERY_HALF = (0.025, 0.009, 0.030)  # battery box half sizes [m], between the link and the passive wheel
BATTERY_Y = LINK_HALF_Y + BATTERY_HALF[1]  # [m] battery centre from the axle midpoint, passive side
LINK_MASS = 0.415  # [kg] links 2..18
HEAD_MASS = (MASS - GRIPPER_MASS - 2 * N_PAIRS * WHEEL_MASS - len(WIDE_PAIRS) * BATTERY_MASS
             - (N_LINKS - 1) * LINK_MASS)
# = 0.458 kg: link 1 with the gripper's two rotational joints (Fig. 4(e), (f))
LINK_HALF = (0.5 * LINK_LENGTH, LINK_HALF_Y, 0.040)  # link box half sizes [m]

# --- Table II: modes (rows sigma = 1..6) x base wheel pairs 1..7, True = grounded
MODES = np.array(
    [
        [1, 1, 0, 1, 1, 0, 1],
        [1, 1, 1, 1, 1, 0, 0],
        [1, 1, 1, 1, 0, 0, 1],
        [1, 1, 1, 0, 0, 1, 1],
        [1, 1, 0, 0, 1, 1, 1],
        [1, 0, 0, 1, 1, 1, 1],
    ],
    dtype=bool,
)
N_MODES = MODES.shape[0]


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class SnakeParams:
    """Dimensions used by `kinematics` as a pytree (every field is a leaf: traceable,
    vmappable for sweeps). SI units."""

    link_length: jax.Array = LINK_LENGTH  # l [m]
    wheel_radius: jax.Array = WHEEL_RADIUS  # r [m]
    gripper_tip: jax.Array = GRIPPER_TIP  # [m]
    tail_axle: jax.Array = TAIL_AXLE  # [m]
    # (9,) [m] each pair's wheel centres from its axle midpoint (PAIR_WHEEL_Y)
    wheel_y: jax.Array = field(default_factory=lambda: PAIR_WHEEL_Y.copy())

    def with_(self, **changes) -> SnakeParams:
        return replace(self, **changes)

    def astype(self, dtype) -> SnakeParams:
        return jax.tree_util.tree_map(lambda x: jnp.asarray(x, dtype), self)


def default_params() -> SnakeParams:
    return SnakeParams()


# ------------------------------------------------------------------ user parameters
# Every parameter a user can set (sweep analyses, tune objectives, the simulations'
# params dicts), each stated once: `control`, `kinsim`, `experiments`, `sim_control`,
# `scenarios` and `operator` take their defaults from here, the analyses select theirs
# (with per-analysis changes where one needs another default, range or doc).
# Categorical parameters take their choices from the analysis' own data at the select.
PARAMETERS = ParamTable("snake", (
    # joint-limit avoidance (`control`, `snake.kv`); K_V of Sec. V-B, Figs. 8-10:
    # diag(15, 0.015, 15, 0.015, 15, 0.015, 9.6, ..., 0.3)
    Param("kv_head_yaw", 15.0, "K_V weight of the head yaw joints theta_1..theta_3", "", lo=0.0, hi=1e4),
    Param("kv_head_pitch", 0.015, "K_V weight of the head pitch joints psi_1..psi_3", "", lo=0.0, hi=1e4),
    Param("kv_base", 9.6, "K_V weight of theta_4, the head end of the base part", "", lo=0.0, hi=1e4),
    # each base weight is half the one ahead of it (tail-wards)
    Param("kv_ratio", 0.5, "K_V ratio from one base joint to the next towards the tail "
          "(0.5: the weights double from the tail to the head, as the paper's)", "", lo=0.0, hi=4.0, lo_open=True),
    Param("k_eta", 0.1, "null-space gain k_eta of Eq. 14", "", lo=0.0, hi=100.0),
    # W of Eq. 13's weighted pseudo-inverse: the paper gives none; ours is diag(l^2, r^2) (`control`)
    Param("w_wheel", 1.0, "weight of the wheels in W relative to ours (r^2; the joints' stay l^2): > 1 makes "
          "the wheels dearer, so the redundancy moves more joints and less base (default (ours): 1)", "",
          lo=0.0, hi=1e4, lo_open=True),
    Param("gain", 1.0, "task gain K (the same on the 7 controlled variables) of Eq. 13", "1/s",
          lo=0.0, hi=50.0, lo_open=True),
    Param("delta_t", 1.0, "Delta T: period of the mode switching", "s", lo=0.02, hi=30.0),
    Param("mode_order", 0, "switching order: 0 = 2,3,4,5,6 (paper, tail to head), 1 = 6,5,4,3,2, "
          "2 = 2,4,6,3,5", kind="int", choices=(0, 1, 2)),
    Param("switch_at", 2.0, "operator's command of the switching state (fixing state before)", "s",
          lo=0.0, hi=1e3),
    Param("a2", 0.0, "Eq. 20 weight of 1/||d|| (distances of P_G from the support polygon's sides); 0 = Eq. 19",
          "m", lo=0.0, hi=1e3),
    Param("amplitude", 1.1, "zigzag amplitude of the base yaw joints at t = 0 (limit 1.134)",
          "rad", lo=0.0, hi=YAW_LIMIT),
    # Dynamixel MX-106R, 45 rpm at 12 V
    Param("joint_speed_max", 4.7, "servo speed limit of the joints", "rad/s", lo=0.0, hi=100.0, lo_open=True),
    Param("recover_ratio", 0.7, "recovered once every base joint is below this fraction of its limit", "",
          lo=0.0, hi=1.0, lo_open=True, hi_open=True),
    Param("w_limit", 1.0, "loss weight of the time near the limits against the head error", "", lo=0.0, hi=1e3),
    Param("horizon", 30.0, "simulated time", "s", lo=0.1, hi=600.0, sweepable=False),
    Param("dt", 0.02, "control period (explicit Euler step of the kinematic plant)", "s", lo=1e-4, hi=0.2,
          sweepable=False),
    Param("feedback", False, "use the plant's w and phi (true) or the paper's feedforward estimate (false)",
          kind="bool", sweepable=False),
    # the reach (`snake.reach`, `snake.reach_gain`)
    Param("gain_k", 1.0, "task-space gain K of Eq. 13 (the same on the 7 controlled variables)", "1/s",
          lo=0.0, hi=100.0, lo_open=True),
    Param("d_x", 0.0, "target displacement of the gripper tip along world x", "m", lo=-0.3, hi=0.3),
    Param("d_y", 0.0, "target displacement of the gripper tip along world y", "m", lo=-0.3, hi=0.3),
    Param("d_z", 0.03, "target displacement of the gripper tip along world z", "m", lo=-0.3, hi=0.3),
    Param("t_start", 0.1, "the target starts to move at this time (after the settling)", "s", lo=0.0, hi=60.0),
    Param("settle_tol", 0.005, "settle_time: the tip error must stay within this", "m", lo=0.0, hi=1.0,
          lo_open=True),
    Param("w_effort", 1e-3, "loss weight of the mean squared commanded joint speed [per rad^2/s^2]", "",
          lo=0.0, hi=1e3),
    Param("ground", "box", "box: the snake scenario's ground (every geom collides); plane: the MJX tuning's "
          "model (plane ground, wheels collide)", kind="str", sweepable=False),
    # the MuJoCo experiments (`snake.table3`, `snake.contact`, `snake.operations`)
    Param("target", "x", "the component of w_h changed (Table III row): x 0.2 m, y 0.1 m, z -0.1 m, "
          "alpha pi/2, beta -pi/6, gamma pi/4", kind="str"),
    Param("ramp", 4.0, "duration of the target's change (default (ours): the paper gives none)", "s",
          lo=0.5, hi=30.0, sweepable=False),
    Param("posture", "ii", "the paper's posture (Tables IV-V)", kind="str"),
    # default (ours) fitted to Table IV: the paper measured "by controlling the position of the head" (Sec. V-C)
    # under its feedforward control, so the largest force is the servos' stiffness (the head part's model.KP, from
    # Table III) times this command through the posture. The paper does not give it; `python
    # benchmarks/snake_contact_overshoot.py` runs Table IV's six postures (one trial each) for 10-17.5 mm: RMS log
    # error over its 18 means 0.45 / 0.38 / 0.37 / 0.41 at 10 / 12.5 / 15 / 17.5 mm on the rigid base, 0.37 / 0.25 /
    # 0.22 / 0.25 on the twisting base with the L bent at the tail (the defaults since 8 Dec 2026), so 15 mm
    # (docs/snake.md).
    Param("overshoot", 0.015, "how far past the plate's face the head target is driven (default (ours), fitted to "
          "Table IV: contact.OVERSHOOT)", "m", lo=0.0, hi=0.5),
    Param("hold", 3.0, "time the target is held in the plate after the ramp", "s", lo=0.0, hi=30.0,
          sweepable=False),
    # the L of Tables IV-V's L-shaped base: which two base yaw joints turn by 45 deg each (the paper's Fig. 12(b),
    # missing from our copy, shows it). "middle": theta_6, theta_7; "tail": theta_8, theta_9 (default (ours) since
    # 8 Dec 2026: `contact.L_BEND`)
    Param("l_bend", "tail", "where the L-shaped base of Tables IV-V bends: middle (theta_6 = theta_7 = 45 deg) or "
          "tail (theta_8 = theta_9 = 45 deg, default (ours))", kind="str", choices=("middle", "tail"),
          sweepable=False),
    # a tyre's sideways give (docs/snake.md, Table V): 0 is MuJoCo's hard friction, the model's default
    Param("wheel_creep", 0.0, "time constant of the wheel-floor friction (MuJoCo solreffriction on an elliptic "
          "cone: the wheels creep under a side load, a tyre's give); 0: hard friction, default (ours); native "
          "MuJoCo only", "s", lo=0.0, hi=2.0, sweepable=False),
    # the base's twist at its first joint (docs/snake.md, Tables IV-V): 0 is the model's rigid base
    Param("twist_compliance", 0.0, "compliance of each of the passive hinges about the base links' long axes behind "
          "theta_4 .. theta_9 (the base twists at its joints: link 7 and the raised head part roll on pair 3's wheels "
          "when pushed across the base); 0: a rigid base, default (ours)", "rad/(N m)", lo=0.0, hi=10.0,
          sweepable=False),
    Param("operation", "pick", "the operation (Sec. V-D): pick (a T-joint pipe), valve (a gate valve), door (a "
          "door with a knob)", kind="str"),
    # the teleoperator (`operator`; off in a simulation's params dict unless set)
    Param("operator_gain", 1.0, "the operator's joystick correction of the seen tip position error, 0: none "
          "(default (ours))", "1/s", lo=0.0, hi=20.0),
    Param("operator_enter", 0.97, "a base yaw joint at this fraction of its limit: the operator stops the script "
          "and commands the switching state (> 1: never; default (ours))", "", lo=0.5, hi=2.0),
    Param("operator_exit", 0.8, "... until every base yaw joint is below this fraction (default (ours))", "",
          lo=0.0, hi=1.0),
    # one mode (Delta T = 1 s): the paper switches "until the robot becomes operable" (Sec. IV-C5). Until 7 Dec
    # 2026 a whole cycle of the modes 2..6 (5 s): the longer switching turned link 7 off the door's pull
    # (docs/snake.md, "Opening the door"); 0-4 s give the same door
    Param("operator_min_switch", 1.0, "... and at least this long (default (ours))", "s", lo=0.0, hi=60.0),
    # perturbed trials (`trials`) and the scenario
    Param("mu", 1.0, "floor friction coefficient (default (ours))", "", lo=0.05, hi=3.0),
    Param("mu_jitter", 0.1, "mu + U(-1, 1) x this, from the row's seed (default (ours))", "", lo=0.0, hi=1.0),
    Param("heading_jitter", 0.05, "initial heading U(-1, 1) x this, from the row's seed (default (ours))", "rad",
          lo=0.0, hi=3.2),
    Param("place_jitter", 0.005, "the robot's start shifted by U(-1, 1) x this in x and y, from the row's seed "
          "(default (ours))", "m", lo=0.0, hi=0.05),
    # the head part's servos, the MuJoCo model's `model.KP`, `model.KV` (the evidence from Table III and Fig. 7(a)
    # is in model.py's docstring)
    Param("head_kp", 200.0, "stiffness of the head part's six servos (model.py: chosen from Table III)",
          "N m/rad", lo=1.0, hi=1e4),
    Param("head_kv", 1.3, "damping of the head part's six servos", "N m s/rad", lo=0.0, hi=1e3),
    # run
    Param("settle", 2.0, "settling on the servos before the paper's clock starts", "s", lo=0.0, hi=20.0,
          sweepable=False),
    *simulation_params(),  # backend, nthread
))
