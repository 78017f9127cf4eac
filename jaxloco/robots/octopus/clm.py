"""The compound locomotion mode (CLM) controller of OCTOPUS (paper, "Control system design
for CLM" and "Arms and crawlers control in getting over obstacle", Figs. 7, 9, 14): the
crawlers drive, the front flippers follow the terrain by their torque, and the four arms
walk beside the crawlers in a crawl gait, grope the terrain and lift the body over steps.
Pure JAX, one simulation, fixed shapes, 50 Hz; every switch is a mask (`jnp.where`,
`jnp.select`); the rollout vmaps it. It composes the rules of `clm_rules` and the
kinematics of `kinematics`, and senses only what the real robot senses: joint angles and
torques, the IMU roll and pitch (never the yaw: the real robot cannot measure it; a
test turns the IMU heading and sees the same actions), the crawler encoders (travel).
Never the terrain parameters. Every gain is a params entry (`PARAM_DEFAULTS`); every value
the paper does not give is a default (ours). Steering a drifting course is the operator's
job (the system is semi-autonomous), modelled apart in `operator`, off by default.

Structure: the state is `ClmState`, a pytree of NamedTuples (the robot phase, step
detection, crawlers and flippers; `ArmState` the arms and the crawl gait, `ApproachState`
the PREPARE approach, `ClimbState`, `CrawlState`). One period (`clm_step`) wires
module-level pure functions, one per concern, each testable alone: `measure` (the
sensors), `approach_step` and `crawler_drive` (the crawlers), `terrain_pitch` and
`support_arms` (Eqs. 22-27), `arm_transfer` (Eqs. 19-21 and the collision stop),
`detect_step`, `gait_sequence`, `front_flipper_rule`, `crawler_stall`, `climb_step` (the
level lift or `paper_climb_step`), `release_step` (or `paper_release_step`), `crawl_step`
(`_crawl_step`), `carry_step` (DONE), `arm_commands`, `flipper_commands`,
`phase_transition`, `enter_phase` and `climb_progress`. `make_controller` returns
`Controller(clm_init, clm_step)`.

Where this differs from the paper (the open gap, measured in docs/octopus.md): the
default CLIMB is the paper's, Eqs. 28-29 (`climb_paper` = 1, `paper_climb_step`,
`paper_release_step`; the default since 7 Dec 2026, our level lift before), but in our
simulation it has not yet climbed a step of 200, 300 or 400 mm in any of about 850 gain / reading /
PREPARE-posture combinations: the booms lift the nose to the pitch that booms alone
give (0.54 rad on 400 mm; the paper's is 0.60, closed form in docs/octopus.md), the
front arm rollers roll back to the edge, and the robot stalls leaning on the edge with
its main crawler slipping. Our level lift (`climb_paper` = 0) and CRAWL (`crawl_max_h` >
0) are named options, not the paper's method.

Robot phases (`PHASE_NAMES`; Fig. 9 a-h and the phases A-F of Fig. 14):
  WALK 0 (Fig. 9a-c, Fig. 14 A-C): crawlers at `clm_speed`; front flippers
    by the torque rule (`clm_rules.flipper_rule`, Cases 1-3: T0, flip_delta_a, A0,
    flip_delta_b), rear flippers 0. Arms: the support arms hold their ground contacts
    (Eqs. 22-27, `predict_contacts` with the crawler-encoder travel, then inverse
    kinematics; an arm whose hold would leave its joint range holds its last command,
    its roller rolling along: HOLD_RANGE_TOL); one arm at a time transfers
    (`transfer_step`, Eqs. 19-21: lift to A_B, swing to A_S, over the target, lower until
    contact) to its Table 2 target, in
    `CRAWL_ORDER` (RR, RF, LR, LF) with `gait_pause` between transfers: at least three
    arms support the robot at any time (while any arm is IDLE the crawlers wait). Where a
    transfer stopped is classified by `arm_stop_case` (delta_c, delta_d).
    Step detection: a front arm stops above its target (dz > delta_d: STOP_ON_OBSTACLE, or
    STOP_BLOCKED short of the target on a step top near the edge) ->
    the other front arm transfers next (the rear arms wait, Fig. 14 C); both front arms
    on it and H_EST (Eq. 9, `explore_terrain` on the contact points) > sigma1 -> the step
    is confirmed, the gait stops and the crawlers drive on until a front flipper touches
    the riser (flipper rule Case 2; with stop_on_touch = 0: Case 3, A' > A0) or the
    encoders stall (`stall_s`) -> PREPARE, or CRAWL if H_EST <= crawl_max_h.
  PREPARE 1 (Fig. 9d, Fig. 14 D: "RR arm adjusting its posture for climbing"): crawlers
    stopped, front flippers up to A0. On a high step (H_EST > approach_min_h; an
    addition) the robot then approaches and squares up: each crawler drives on until the
    riser blocks it (its raised front flipper pressed back, flipper torque beyond
    approach_tau, or its encoder stalled), a blocked side stops while the other one
    drives on, the arms rolling along with their commands held; both sides blocked (or
    approach_max driven) -> squared. (Without it, at
    400 mm the first flipper touch left the crawler fronts about 0.15 m short of the
    riser, and the lifted front flippers did not reach the top: 0/8.) Then the rear arms
    (RR, then LR) are transferred to their Table 2 *start* points on the ground (farther
    back than the targets: from there the rear rollers reached the riser before the body
    had travelled L); the front arms stay on the step top. Both placed -> CLIMB.
  CLIMB 2 (Fig. 9e, Fig. 14 E), `climb_paper` = 1 (the paper's): Eqs. 28-29 as printed
    (`paper_climb_step`): every boom +delta_e and the front flippers -delta_f per period,
    crawlers driving, EPRAs not held, while H < H_EST or S < L; H the COG height above
    the rear EPRAs' ground (Eqs. 10-17, `kinematics.cog_height`), S (Eq. 18) from the
    crawler encoders since the CLIMB began ("when the robot starts to climb the obstacle,
    S equals 0"), L = settle_distance (0.3 m). H > H_EST and S > L -> RELEASE
    (`paper_release_step`: booms back to the start pose's angles, flippers to 0).
    Per side (`climb_per_side` = 1, Fig. 17: the sides "adapt the terrain separately"):
    each side's H (the COG above its rear EPRA) against the step height under it
    (`h_est_side`); a side that is up holds its booms and front flipper while the other
    goes on, and the RELEASE waits for both.
    `climb_paper` = 0 (the default for now, ours): Eq. 28 in task space: the pushing arms lower their EPRAs
    by delta_e * l1 per period along the world vertical (inverse kinematics), lifting the
    body level (front / rear and left / right arms take turns to stay within level_band),
    while the front crawler ends are below the step top (from the front EPRAs resting on
    it: the reading of "H < H_EST" that lets the crawlers onto the step). Eq. 29: the
    flippers turn down by delta_f once the front is lifted (front to flip_min, onto the
    step top; rear to rear_flip_min; with rear_flip_late = 0 the rear ones at once). The crawlers drive once the
    front is lifted. S (Eq. 18, crawler encoders) starts when the front flippers touch down on the
    step top (torque beyond T0) at minus their reach: S is the front flipper pivots'
    distance past the edge (Fig. 5). H - H(CLIMB start) > H_EST and S > L (0.3 m) and the
    pitch below release_pitch -> RELEASE.
  RELEASE 3 (Fig. 9f-h, Fig. 14 F): crawlers stopped; every EPRA rises by delta_e * l1
    per period (body down evenly onto the crawlers) until back at the Table 2 height in
    {R} (the authors' "theta_2' > 0"); flippers +delta_f while A' < 0. All done -> DONE.
  DONE 4: the arms go to a carrying pose (booms up first), the crawlers drive on; after
    `done_distance`, or blocked (encoders stalled `stall_s`) -> WALK with every arm IDLE:
    the arms are placed again one at a time (crawlers waiting), so that the next terrace
    is met the same way. Blocked right after a CRAWL climb -> CRAWL again (the next
    terrace of a staircase).
  CRAWL 5 (an addition): a confirmed step no higher than crawl_max_h (0.25 m, the
    flipper length: the paper, "Tasks setting": OCTOPUS "can climb the step which height
    is lower than 250 mm without using arms") is climbed by the crawlers and flippers
    with the arms carried, as the CCM baseline does (`_crawl_step`: front flippers up,
    down onto the edge while driving at crawl_speed, rear flippers push, level) -> DONE.
    Why: on a two-terrace step (terraces TERRACE_DEPTH = 0.8 m deep, shorter than the
    robot with its flippers) the arm climb of the second riser placed the rear arms down
    the first edge, and the robot rolled back off the terrace (0/8); the paper's "two
    edges provide additional support" is the crawlers spanning both risers. The arms
    still grope and measure every riser (H_EST) and decide how it is climbed.

Arm phases (per arm, `ARM_PHASE_NAMES`): the transfer phases of `clm_rules` (LIFT, SWING,
OVER, LOWER), PLACED = in support, IDLE = holding its last command, waiting for a
transfer.

Readings resolved here (the paper's text is ambiguous or not physically consistent):
  * theta' and A' in the rules are the previous *commands*, not the encoders: the joints
    are position servos that lag and sag under load; feeding the encoders back makes a
    held joint drift. The encoders give the EPRAs (forward kinematics) for the contact
    points, H_EST, H, the stop cases and the contact signal.
  * the "down arm" period ends on contact: the torque-based collision signal
    (`collision`, a joint torque rising by more than collision_threshold in a period),
    or the boom / elbow held more than contact_lag short of the command of two periods
    before (a blocked arm), or the torque rule below (a roller meeting the ground at a
    slant rolls on, so neither fires), or the boom at its joint limit (deep pit). In
    SWING and OVER
    a boom or elbow torque beyond collision_torque for collision_periods periods (80 N m
    and 2; free motion reaches 45 N m, a torque *rise* is no signal there: single jumps of
    35 N m per period in free air), in LIFT the same with that joint standing still,
    stops the arm where it is: PLACED, its command the measured angles ("all of the
    joints in that arm stopped in this sample period"), its contact where the encoders
    put the EPRA, its stop case from there. The joints aim
    transfer_press below the target, so the roller meets the ground before the command
    stops, and past the target angles the boom creeps down by Delta_B per period.
  * A_B, A_S: our joint zeros differ from the authors' (see `clm_rules.transfer_step`):
    A_B = lift_boom (rear) / lift_boom_front (front arms, higher: their rollers must
    pass over a 400 mm step top), or lift_min above the current boom if that is already
    higher; A_S from inverse kinematics of the target; the target is passed over from
    clearance_front / clearance_rear above it.
  * the level lift (climb_paper = 0, ours): Eq. 28 turns only the booms; with the
    elbows held the EPRAs sweep arcs and, once the robot pitches, the front rollers roll
    back off the step top. The level lift moves the EPRAs straight down in the world
    instead (the boom's Delta_E at the boom end, delta_e * l1) and lifts level.
  * T_P of Eqs. 22-27: the terrain pitch of the contact points (Eq. 7) while the terrain
    reads flat (Case 1), else the robot's pitch (T_P - R_P = 0): across a step edge Eq. 7
    gives the slope of the edge, not of the ground the crawlers run on.
  * A0: Case 3 needs A' > A0, so A0 is a little below the 85 deg joint limit.
  * step confirmed = both front arms on an obstacle and H_EST > sigma1 (terrain Case 2
    needs the rear arms too, but a rear arm may be in transfer; its stored contact is
    used).
  * the support arms aim at their contact points (press = 0): pressing them 10 mm below
    unloaded the tracks unevenly and turned the robot by 0.16 rad on flat ground.
  * no heading hold: the paper assumes the yaw does not change, and ours does turn when
    one front flipper meets the riser first; the PREPARE approach squares the robot up
    against the riser with the encoders and flipper torques instead.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco.robots.octopus import clm_rules, kinematics, model, params
from jaxloco.sim.scenario import Controller

Array = jax.Array

WALK, PREPARE, CLIMB, RELEASE, DONE, CRAWL = 0, 1, 2, 3, 4, 5
PHASE_NAMES = ("walk", "prepare", "climb", "release", "done", "crawl")
# CRAWL sub-phases: front flippers up (arms to the carrying pose), front flippers down
# onto the edge while driving, rear flippers push, level on the top
RAISE, LOWER_F, PUSH, LEVEL = 0, 1, 2, 3
IDLE = 5  # arm phase after clm_rules.PLACED (4): holding, waiting for a transfer
ARM_PHASE_NAMES = (*clm_rules.TRANSFER_PHASES, "idle")
CONTROL_DT = 0.02  # [s] 50 Hz
FRONT = np.array([True, True, False, False])  # arms 1..4 (LF, RF, LR, RR)
LEFT = np.array([True, False, True, False])
SIDE = np.array([0, 1, 0, 1])  # the side (0 left, 1 right) of arms LF, RF, LR, RR and flippers fl, fr, rl, rr
FRONT4 = np.array([True, True, False, False])  # flippers fl, fr, rl, rr
TABLE2_Z = float(params.TABLE2_TARGET[0, 2])
# the front main crawler axles in {R} [m]
FRONT_AXLES = np.array(
    [[params.MAIN_AXLE_X, s * params.CRAWLER_Y, params.MAIN_WHEEL_RADIUS - params.BASE_HEIGHT] for s in (1.0, -1.0)]
)
CRAWL_ORDER = np.array(clm_rules.CRAWL_ORDER)
N_PREPARE = 2
PREPARE_ORDER = np.array([3, 2])  # PREPARE transfers the rear arms only (RR, then LR)

_P = params.PARAMETERS  # the user parameters among these (a sweep may set them)
PARAM_DEFAULTS: dict[str, float] = {
    "clm_speed": _P.default("clm_speed"),  # [m/s] crawler speed in CLM (slower than CCM: the arms must follow)
    # front flipper torque rule (Cases 1-3)
    "T0": _P.default("T0"),  # [N m] torque threshold
    "flip_delta_a": _P.default("flip_delta_a"),  # [rad/period] Delta_A
    "A0": math.radians(82.0),  # [rad] flipper limit A0 (just below the 85 deg joint limit)
    "flip_delta_b": _P.default("flip_delta_b"),  # [rad/period] Delta_B
    "stop_on_touch": 1.0,  # 1: a confirmed step stops the crawlers at the first front flipper touch
    # (Case 2) instead of waiting for Case 3; the flippers are then raised to A0 in PREPARE
    "touch_rise": 0.15,  # [rad] flipper yield that counts as touching the riser
    "front_start": 0.5,  # [rad] front flipper angle while walking ("a suitable angle")
    # arm transfer (Eqs. 19-21)
    "K": 0.04,  # boom gain per period
    "delta_a": 0.03,  # [rad/period] swing step
    "delta_b": 0.02,  # [rad/period] elbow / boom step
    "lift_boom": -0.6,  # [rad] A_B of the rear arms (boom raised)
    "lift_boom_front": -1.2,  # [rad] A_B of the front arms: their rollers must pass over a 400 mm step top
    "lift_min": 0.15,  # [rad] the boom turns up at least this much in LIFT
    "clearance_front": 0.47,  # [m] the front EPRAs pass this far above their target
    "clearance_rear": 0.2,  # [m] the rear ones
    "collision_threshold": 50.0,  # [N m] joint torque rise in one period = contact (LOWER)
    "collision_torque": 80.0,  # [N m] |boom or elbow torque| above this for collision_periods = collision in
    # SWING, OVER, and in LIFT with the joint still (below); a contact in LOWER
    # (`python benchmarks/octopus_collision_torque.py`)
    "collision_still": 0.005,  # [rad] ... (LIFT) the joint moved less than this in a period
    "collision_periods": 2.0,  # periods in a row
    "collision_lift": 0.05,  # [rad] ... in LIFT once the boom has risen this much (default (ours))
    # arm stop Case 3, a deep pit (no ground at the boom's limit): a new target this much nearer the
    # body, at most pit_backoff_max in all; the crawlers stop (the operator's call)
    "pit_backoff": 0.15,  # [m] default (ours)
    "pit_backoff_max": 0.45,  # [m] default (ours)
    "contact_lag": 0.04,  # [rad] boom / elbow behind its command = blocked (LOWER only)
    "transfer_press": 0.05,  # [m] a transfer aims this far below its target
    "carry_elbow": 1.6,  # [rad] elbow of the carrying pose after the release
    "done_distance": 0.4,  # [m] driven on the top with the arms carried before walking again
    "gait_pause": 0.3,  # [s] between two transfers
    "press": 0.0,  # [m] support arms aim this far below their contact points (> 0 loads the
    # arms, but unloads the tracks unevenly: 10 mm turned the robot by 0.16 rad on flat ground)
    # arm stop cases
    "delta_c": 0.08,  # [m]
    "delta_d": 0.05,  # [m]
    # terrain exploration
    "sigma1": _P.default("sigma1"),  # [m]
    "stall_s": 1.0,  # [s] crawlers below a third of the command this long = stalled
    # climbing (Eqs. 28-29)
    "delta_e": _P.default("delta_e"),  # [rad/period] boom step (the EPRA moves Delta_E l1 per period)
    "delta_f": _P.default("delta_f"),  # [rad/period] flipper step
    "settle_distance": 0.3,  # [m] L = 0.6 x 500 mm
    # 1: CLIMB by Eqs. 28-29 as printed (the paper's, the default; not yet climbing in our simulation, see the
    # module docstring); 0: our level lift (a named option)
    "climb_paper": _P.default("climb_paper"),
    # 1: PREPARE places the rear arms at their Table 2 start points (ours, the level lift's choice); 0: at
    # their Table 2 targets (near under the rear boom axes)
    "prepare_rear_init": _P.default("prepare_rear_init"),
    # paper climb: 1 = A' of Eq. 29 is the measured flipper angle ("obtained"); 0 = the last command
    "flip_encoder": _P.default("flip_encoder"),
    # paper climb: 1 = the front flippers' torque rule (Case 2) keeps running in CLIMB
    "climb_yield": _P.default("climb_yield"),
    # paper climb: 1 = S (Eq. 18) starts when the front flippers touch down on the step top (the level lift's
    # reading); 0 = at the CLIMB start
    "s_from_touch": _P.default("s_from_touch"),
    # paper climb: 1 = Eq. 29 turns the rear flippers too; 0 = the front ones (A is the front flipper command
    # of "Crawler controls")
    "climb_rear_flippers": _P.default("climb_rear_flippers"),
    # paper climb: 1 = Eq. 28's +Delta_E on the authors' common boom axis (front booms down, rear ones up);
    # 0 = every boom down
    "climb_common_axis": _P.default("climb_common_axis"),
    # paper climb: 1 = each side's arms and front flipper follow Eqs. 28-29 with that side's H and H_EST (the
    # paper's Fig. 17: "adapt the terrain separately"); 0 = both sides by Eq. 9's H_EST and Eqs. 10-17's H
    "climb_per_side": _P.default("climb_per_side"),
    # CRAWL (an addition, see the module docstring): low steps climbed by crawlers and flippers
    "crawl_max_h": _P.default("crawl_max_h"),  # [m] confirmed steps up to this height (paper: < 250 mm w/o arms)
    "crawl_speed": _P.default("speed"),  # [m/s] crawler speed in CRAWL (the CCM baseline's)
    "crawl_front_up": 1.2,  # [rad] front flippers raised onto the edge first
    "crawl_rate": 0.3,  # [rad/s] flipper rate in CRAWL
    "crawl_rear_push": -0.6,  # [rad] rear flippers push the tail up
    "crawl_pitch_push": 0.3,  # [rad] nose-up pitch that starts the rear push
    "crawl_pitch_rise": 0.1,  # [rad] ... or this with the front flippers down
    "crawl_pitch_level": 0.05,  # [rad] after the push, back below this: on top
    "crawl_level_s": 2.0,  # [s] the rear flippers keep pushing this long once level
    "release_pitch": 0.35,  # [rad] nose-up pitch below which the robot counts as on top
    "front_clearance": 0.03,  # [m] the arms lift until the crawler fronts clear the step top by this
    "level_band": 0.05,  # [rad] pitch / roll band of the level lift
    "rear_flip_min": -0.8,  # [rad] the rear flippers turn down to this
    "flip_min": -0.6,  # [rad] the front flippers turn down to this angle at most
    "rear_flip_late": 1.0,  # 1: the rear flippers, too, wait until the front is lifted (turning down
    # with their tips on the ground they pushed the robot back ~7 cm from the riser); 0: at once
    # PREPARE approach (an addition, see the module docstring): with the front flippers at
    # A0 each crawler drives on until it is blocked by the riser (square-up)
    "approach": 1.0,  # 1: approach and square up before the rear arms are placed; 0: off
    "approach_min_h": 0.35,  # [m] ... on steps with H_EST above this only (see `approach_step`)
    "approach_stall_s": 0.6,  # [s] a crawler below a third of clm_speed this long = at the riser
    "approach_max": 0.35,  # [m] the approach ends after this travel (encoders) in any case
    "approach_tau": 6.0,  # [N m] a raised front flipper pressed by the riser: |torque| above this ...
    "approach_touch_s": 0.1,  # [s] ... this long = that crawler is at the riser
}

_KP = params.default_params()
BOOM_MAX = model.ARM_RANGE[1][1]
ARM_LO = np.array([r[0] for r in model.ARM_RANGE])
ARM_HI = np.array([r[1] for r in model.ARM_RANGE])
# [rad] a support arm's hold may lie this far outside the joint range and is clipped
# (an encoder reads a few mrad past a limit under load); beyond it the arm holds its last
# command (`support_arms`). Ours
HOLD_RANGE_TOL = 0.02
# [rad] the most a support arm's hold may move a joint command in one period, default (ours). Measured
# (7 Dec 2026, 4 runs of 150 s on each paper task, every period): the first hold after LOWER (from the
# command aimed transfer_press below the ground) moves it by up to 0.41 (0.45 in earlier runs), the
# second by up to 0.14, later ones by at most 0.023; the other branch of the inverse kinematics is >= 2 away
HOLD_JUMP = 1.0
FLIPPER_MAX = params.FLIPPER_LIMIT
HOME_BOOM = model.home_arm_angles()[:, 1]  # boom angles of the start pose (the authors' zero)


def start_pose() -> tuple[np.ndarray, np.ndarray]:
    """The CLM start pose: arms (4, 3) in the Table 2 initial pose (rollers on the
    ground), flippers (4,) [rad] (front ones at `front_start`)."""
    flips = np.array([PARAM_DEFAULTS["front_start"]] * 2 + [0.0, 0.0])
    return model.home_arm_angles(), flips


def _tips_moved(q: Array, move: Array, dz_level: Array, a_p: Array, a_r: Array) -> Array:
    """Arm joints (4, 3) that move the EPRAs of the arms with `move` (4,) by dz_level [m]
    along the vertical of the level frame {C} (inverse kinematics from the current
    commands `q`); the others, and any out of reach, keep `q`."""
    tips = kinematics.arm_tips(_KP, q)
    d_r = kinematics.level_rotation(a_p, a_r).T @ jnp.stack([0.0 * dz_level, 0.0 * dz_level, dz_level])
    q_new, reach = kinematics.inverse_kinematics_all(_KP, tips + d_r)
    ok = move & (reach > 0.005)
    return jnp.where(ok[:, None], q_new, q)


def paper_climb_step(p, q_cmd: Array, flip_cmd: Array, flip_q: Array, flip_tau: Array, on_top: Array
                     ) -> tuple[Array, Array]:
    """One period of the paper's CLIMB (Eqs. 28-29, first branches; `climb_paper` = 1):
    arm commands (4, 3) and flipper commands (4,) [rad]. `on_top`: () for the whole robot
    or (2,) per side (left, right: `SIDE`), the sides adapting separately (Fig. 17).

    While not `on_top` (H < H_EST or S < L), every boom turns down by Delta_E (theta_2 =
    theta_2' + Delta_E, theta' the last command; elbows and swings held: "we do not try to
    keep the position of the endpoint of arms consistent") and the front flippers by
    Delta_F (A = A' - Delta_F). Readings (switchable, see PARAM_DEFAULTS):
      * A is the *front* flipper command of "Crawler controls" (the rear flippers hold;
        `climb_rear_flippers` = 1 turns them too);
      * A' is the angle "obtained ... in the last sampling period", the encoder
        (`flip_encoder`): a flipper pressed on the terrain pushes with the servo torque of
        Delta_F instead of winding its command to the joint limit;
      * the crawler rule of the front flippers keeps running (`climb_yield`): with |T'| >
        T0 they yield by Delta_A against the torque (Case 2);
      * "+Delta_E" on the authors' common boom axis (`climb_common_axis`, see
        `_authors_boom_sign`): the front booms turn down and the rear ones up. Not the
        default: the text says every boom turns down, and H is measured from the rear
        EPRAs, which this reading lifts (docs/octopus.md, 6 Dec 2026).
    Once on top, the commands hold: a side on top waits for the other (with both up the
    RELEASE takes over)."""
    dt = q_cmd.dtype
    up = jnp.broadcast_to(on_top, (2,))[jnp.asarray(SIDE)]  # (4,) per arm, and per flipper
    q = q_cmd.at[:, 1].add(jnp.where(up, 0.0, p["delta_e"] * _authors_boom_sign(p, dt)))
    turn = jnp.asarray(FRONT4) | (p["climb_rear_flippers"] > 0)
    prev = jnp.where(p["flip_encoder"] > 0, flip_q.astype(dt), flip_cmd)
    yielding = (p["climb_yield"] > 0) & (jnp.abs(flip_tau) > p["T0"])
    give = jnp.where(yielding, -p["flip_delta_a"] * jnp.sign(flip_tau), 0.0).astype(dt)
    flip = jnp.where(turn & ~up, prev - p["delta_f"] + give, flip_cmd)
    return q, jnp.clip(flip, -FLIPPER_MAX, FLIPPER_MAX)


def paper_release_step(p, q_cmd: Array, flip_cmd: Array) -> tuple[Array, Array, Array]:
    """One period of the paper's RELEASE (Eqs. 28-29, second branches): the booms turn back
    up by Delta_E while theta_2' > 0 and the flippers by Delta_F while A' < 0. The authors'
    joint zero is the start pose ("Fig. 11a shows robot's original state, every joint's
    angle of robot is zero"), so "theta_2' > 0" reads: below the start pose's boom angle
    (`HOME_BOOM`). Returns arm commands (4, 3), flipper commands (4,) and whether every
    boom and flipper is back."""
    dt = q_cmd.dtype
    home = jnp.asarray(HOME_BOOM, dt)
    sign = _authors_boom_sign(p, dt)
    boom = q_cmd[:, 1]
    authors = sign * (boom - home)  # theta_2' in the authors' frame (zero at the start pose)
    released = jnp.where(authors > p["delta_e"], boom - sign * p["delta_e"], home)
    q = q_cmd.at[:, 1].set(jnp.where(authors > 0.0, released, boom))
    flip = jnp.where(flip_cmd < 0.0, jnp.minimum(flip_cmd + p["delta_f"], 0.0), flip_cmd)
    back = jnp.all(authors <= 1e-6) & jnp.all(flip_cmd >= 0.0)
    return q, flip, back


def _authors_boom_sign(p, dtype) -> Array:
    """(4,) +-1: a boom's angle in the authors' frame over ours (ours: > 0 turns every
    boom down). `climb_common_axis` = 1: every boom turns about one common axis (the
    authors build every joint frame "with the same direction as {W}"; their transfer
    lifts the rear booms to A_B = +0.6 rad and the front ones to -0.6), so the rear
    booms' sign is flipped and Eq. 28's +Delta_E turns them up; 0: every boom down."""
    rear = jnp.asarray(~FRONT) & (p["climb_common_axis"] > 0)
    return jnp.where(rear, -1.0, 1.0).astype(dtype)


def _crawl_step(p, st: CrawlState, q_cmd: Array, flip: Array, pitch: Array, t: Array, stalled: Array,
                control_dt: float) -> tuple[Array, Array, Array, Array]:
    """One period of CRAWL (a low step climbed by crawlers and flippers, as the CCM
    baseline does, `ccm`): RAISE the front flippers to crawl_front_up while the arms go to
    the carrying pose (crawlers stopped); LOWER_F them onto the edge at crawl_rate while
    driving (the tracks on the edge pull the nose up); PUSH with the rear flippers once
    the nose-up pitch passes crawl_pitch_push, or crawl_pitch_rise with the front flippers
    down (a low riser pitches the robot less: at 200 mm it stayed at 0.23 rad, the tracks
    slipping on the edge); LEVEL once it falls back below crawl_pitch_level, the rear
    flippers pushing on for crawl_level_s. Crawlers stalled in LOWER_F or PUSH (`stalled`;
    on a shallow terrace the front meets the next riser while the tail is still on the
    last edge, pitched): RAISE again, the rear flippers holding, and climb on (groping
    with the arms there, pitched on an edge, tipped the robot over: 5 of 8 runs).
    `q_cmd`: the last arm commands (4, 3), `flip`: the last flipper commands (4,) [rad],
    `pitch` A_P [rad], `t` the time [s]. Returns the flipper commands, the next
    sub-phase, its start time and whether CRAWL is over."""
    sub, t0 = st.sub, st.t_sub
    booms_up = jnp.all(q_cmd[:, 1] <= p["lift_boom_front"] + 1e-3)
    raised = jnp.all(flip[:2] >= p["crawl_front_up"] - 1e-6) & booms_up
    nxt = jnp.where((sub == RAISE) & raised, LOWER_F, sub)
    down = jnp.all(flip[:2] <= 0.05)
    nxt = jnp.where((sub == LOWER_F) & ((pitch > p["crawl_pitch_push"]) | (down & (pitch > p["crawl_pitch_rise"]))),
                    PUSH, nxt)
    nxt = jnp.where((sub == PUSH) & (pitch < p["crawl_pitch_level"]), LEVEL, nxt)
    nxt = jnp.where(((sub == LOWER_F) | (sub == PUSH)) & stalled, RAISE, nxt)
    over = (sub == LEVEL) & (t - t0 > p["crawl_level_s"])
    front = jnp.where(sub == RAISE, p["crawl_front_up"], 0.0)
    rear = jnp.where((sub == PUSH) | (sub == LEVEL), p["crawl_rear_push"], jnp.where(sub == RAISE, flip[2:], 0.0))
    target = jnp.concatenate([jnp.stack([front, front]), jnp.broadcast_to(rear, (2,))]).astype(flip.dtype)
    rate = p["crawl_rate"] * control_dt
    flip_n = flip + jnp.clip(target - flip, -rate, rate)
    t_n = jnp.where(nxt != sub, t, t0)
    return flip_n, nxt, t_n, over


# ---------------------------------------------------------------------------------------
# The controller state (a pytree of NamedTuples: fixed shapes, vmap/jit-able)


class ArmState(NamedTuple):
    """The four arms (rows LF, RF, LR, RR: `FRONT`, `LEFT`) and the crawl gait. Joint
    angles (swing, boom, elbow) [rad]; points in the robot frame {R} [m]."""

    arm_phase: Array  # (4,) int32: clm_rules.LIFT..clm_rules.LOWER in transfer, clm_rules.PLACED in support, IDLE
    ptr: Array  # () int32: index into CRAWL_ORDER of the next transfer
    active: Array  # () int32: the transferring arm, -1 none
    pause: Array  # () [s] since the last transfer ended
    placed_n: Array  # () int32: transfers done in PREPARE (PREPARE_ORDER)
    contacts: Array  # (4, 3) [m] contact points in {R} (held on the ground by the support arms)
    stop_case: Array  # (4,) int32: where each arm's last transfer stopped (`clm_rules.arm_stop_case`)
    on_step: Array  # (4,) bool: a front arm stopped on an obstacle (clm_rules.STOP_ON_OBSTACLE)
    q_cmd: Array  # (4, 3) [rad] the last arm commands (theta' of the rules)
    q_cmd2: Array  # (4, 3) [rad] the arm commands of the period before
    lift_to: Array  # (4,) [rad] the boom angle the current LIFT aims at (A_B)
    lift_from: Array  # (4,) [rad] the boom command when the current LIFT began
    tau_prev: Array  # (4, 3) [N m] the arm joint torques of the last period (collision signal)
    q_prev: Array  # (4, 3) [rad] the arm joint encoders of the last period
    backoff: Array  # (4,) [m] each arm's target moved toward the body after deep pits (Case 3)
    hit_n: Array  # (4,) int32: consecutive periods of a transfer with a boom / elbow torque above
    # collision_torque (in LIFT: while that joint stands still): the collision stop of LIFT, SWING, OVER


class ApproachState(NamedTuple):
    """The PREPARE approach (square-up against the riser; sides (left, right))."""

    side_stall: Array  # (2,) [s] each crawler stalled (below a third of clm_speed)
    side_touch: Array  # (2,) [s] each raised front flipper pressed (|torque| > approach_tau)
    blocked: Array  # (2,) bool: that crawler is at the riser
    squared: Array  # () bool: the approach is over (both at the riser, or skipped)
    approached: Array  # () [m] travel in the approach (crawler encoders)


class ClimbState(NamedTuple):
    """CLIMB bookkeeping."""

    h0: Array  # () [m] the COG height H (Eqs. 10-17) when CLIMB began
    touched: Array  # () bool: the front flippers are down on the step top (S counts from there)
    front_up: Array  # () bool: the front crawler ends cleared the step top (the crawlers drive)


class CrawlState(NamedTuple):
    """CRAWL (a low step climbed by the crawlers and flippers, arms carried)."""

    sub: Array  # () int32: the sub-phase (RAISE, LOWER_F, PUSH, LEVEL)
    t_sub: Array  # () [s] the time the sub-phase began
    crawled_last: Array  # () bool: the last step was climbed in CRAWL


class ClmState(NamedTuple):
    """The CLM controller state of one simulation (`clm_init`, `clm_step`)."""

    # robot phase (WALK .. CRAWL, `PHASE_NAMES`) and the time it began [s]
    phase: Array  # () int32
    t_phase: Array  # () [s]
    # step detection: a step confirmed by the front arms, its height H_EST (Eq. 9) [m]
    confirmed: Array  # () bool
    h_est: Array  # () [m]
    h_est_side: Array  # (2,) [m] the step height under the left and right sides (`kinematics.side_step_heights`)
    # crawlers and flippers
    flip: Array  # (4,) [rad] the last flipper commands (fl, fr, rl, rr)
    flip_case: Array  # (2,) int32: the front flippers' torque rule case (`clm_rules.flipper_rule`)
    stall: Array  # () [s] the crawlers below a third of clm_speed
    travel: Array  # () [m] crawler-encoder travel: S (Eq. 18) in CLIMB, the drive on the top in DONE
    climbed: Array  # () int32: climbs finished (RELEASE or CRAWL -> DONE)
    pit: Array  # () bool: a pit ahead (Case 3: an arm found no ground within reach, or a front arm stopped
    # in a pit): the crawlers stay stopped in WALK
    arms: ArmState
    approach: ApproachState
    climb: ClimbState
    crawl: CrawlState


class Sensed(NamedTuple):
    """What the CLM senses in one period (`measure`), in the controller's float dtype: joint
    encoders and torques, the IMU pitch and roll (never the yaw), the crawler encoders."""

    time: Array  # () [s]
    q: Array  # (4, 3) [rad] arm joint encoders (swing, boom, elbow)
    tau: Array  # (4, 3) [N m] arm joint torques
    tips: Array  # (4, 3) [m] the EPRAs (roller centres) in {R}, forward kinematics of q
    pitch: Array  # () A_P [rad], nose up > 0
    roll: Array  # () A_R [rad], left side down > 0
    flip_q: Array  # (4,) [rad] flipper encoders (fl, fr, rl, rr)
    flip_tau: Array  # (4,) [N m] flipper torques
    track_v: Array  # (2,) [m/s] crawler encoder speeds (left, right)
    v: Array  # () [m/s] their mean


class Phases(NamedTuple):
    """The robot phase as masks (() bool each)."""

    walk: Array
    prepare: Array
    climb: Array
    release: Array
    done: Array
    crawl: Array


class Transfer(NamedTuple):
    """One period of the arm transfers (`arm_transfer`), before the gait sequencing."""

    cmd: Array  # (4, 3) [rad] transfer commands (Eqs. 19-21; used for the transferring arm)
    arm_phase: Array  # (4,) the arm phases, the transferring arm's advanced
    transferring: Array  # (4,) bool: the active arm, in LIFT..LOWER
    just_placed: Array  # (4,) bool: the active arm's transfer ended this period
    contacts: Array  # (4, 3) [m] contact points in {R}, a just placed arm's at its EPRA
    stop_case: Array  # (4,) where each arm's last transfer stopped
    on_step: Array  # (4,) bool: front arms stopped on an obstacle
    lift: Array  # (4,) [rad] A_B of the LIFT (boom angle)
    lift_from: Array  # (4,) [rad] the boom command when the LIFT began (a pit's new LIFT: now)
    hit_n: Array  # (4,) int32: the collision counter (`ArmState.hit_n`)
    deep: Array  # (4,) bool: a pit at the arm's target (Case 3): its LOWER reached the boom limit without
    # contact, or (front arms) it stopped delta_d below the target; the arm lifts again for a nearer one
    backoff: Array  # (4,) [m] targets moved toward the body (`ArmState.backoff`)


class Climb(NamedTuple):
    """One period of CLIMB (`climb_step`)."""

    q: Array  # (4, 3) [rad] arm commands
    flip: Array  # (4,) [rad] flipper commands
    over: Array  # () bool: the release condition (-> RELEASE while in CLIMB)
    front_low: Array  # () bool: the front crawler ends below the step top (+ front_clearance)


class Transition(NamedTuple):
    """The phase transition of one period (`phase_transition`)."""

    phase: Array  # () the next robot phase
    changed: Array  # () bool
    finished: Array  # () bool: a climb ended (RELEASE or CRAWL over) -> DONE
    crawled: Array  # () bool: ... and it was a CRAWL climb
    rewalk: Array  # () bool: DONE -> WALK


# ---------------------------------------------------------------------------------------
# One concern per function


def measure(obs) -> Sensed:
    """The sensor readings of an observation (scenarios' `observe`) in the controller's
    float dtype; the arm EPRAs in {R} by forward kinematics, the attitude from the IMU
    quaternion without its yaw."""
    dt = jnp.result_type(float)
    q = obs["arm_q"].reshape(4, 3).astype(dt)
    att = kinematics.attitude_from_quat(obs["quat"].astype(dt))
    return Sensed(
        time=obs["time"],
        q=q,
        tau=obs["arm_tau"].reshape(4, 3).astype(dt),
        tips=kinematics.arm_tips(_KP, q),
        pitch=att[0],
        roll=att[1],
        flip_q=obs["flipper_q"].astype(dt),
        flip_tau=obs["flipper_tau"].astype(dt),
        track_v=obs["track_speed"].astype(dt),
        v=jnp.mean(obs["track_speed"]).astype(dt),
    )


def phase_masks(phase: Array) -> Phases:
    """The robot phase () int32 as one mask per phase."""
    return Phases(phase == WALK, phase == PREPARE, phase == CLIMB, phase == RELEASE, phase == DONE, phase == CRAWL)


def clm_init(p, obs) -> ClmState:
    """The state at the start: WALK, every arm in support (PLACED) at its EPRA, the arm
    commands at the encoders, the front flippers at front_start."""
    sense = measure(obs)
    q, tips = sense.q, sense.tips
    dt = q.dtype
    flips = jnp.stack([p["front_start"], p["front_start"], 0.0 * p["front_start"], 0.0 * p["front_start"]])
    arms = ArmState(
        arm_phase=jnp.full((4,), clm_rules.PLACED, jnp.int32),
        ptr=jnp.zeros((), jnp.int32),
        active=jnp.asarray(-1, jnp.int32),
        pause=jnp.zeros((), dt),
        placed_n=jnp.zeros((), jnp.int32),
        contacts=tips,
        stop_case=jnp.zeros((4,), jnp.int32),
        on_step=jnp.zeros((4,), bool),
        q_cmd=q,
        q_cmd2=q,
        lift_to=q[:, 1],
        lift_from=q[:, 1],
        tau_prev=sense.tau,
        q_prev=q,
        backoff=jnp.zeros((4,), dt),
        hit_n=jnp.zeros((4,), jnp.int32),
    )
    approach = ApproachState(
        side_stall=jnp.zeros((2,), dt),
        side_touch=jnp.zeros((2,), dt),
        blocked=jnp.zeros((2,), bool),
        squared=jnp.asarray(False),
        approached=jnp.zeros((), dt),
    )
    climb = ClimbState(h0=jnp.zeros((), dt), touched=jnp.asarray(False), front_up=jnp.asarray(False))
    crawl = CrawlState(sub=jnp.asarray(RAISE, jnp.int32), t_sub=jnp.zeros((), dt), crawled_last=jnp.asarray(False))
    return ClmState(
        phase=jnp.asarray(WALK, jnp.int32),
        t_phase=jnp.zeros((), dt),
        confirmed=jnp.asarray(False),
        h_est=jnp.zeros((), dt),
        h_est_side=jnp.zeros((2,), dt),
        flip=flips.astype(dt),
        flip_case=jnp.zeros((2,), jnp.int32),
        stall=jnp.zeros((), dt),
        travel=jnp.zeros((), dt),
        climbed=jnp.zeros((), jnp.int32),
        pit=jnp.asarray(False),
        arms=arms,
        approach=approach,
        climb=climb,
        crawl=crawl,
    )


def approach_step(p, st: ApproachState, flip_cmd: Array, h_est: Array, sense: Sensed, prepare: Array,
                  control_dt: float) -> tuple[ApproachState, Array]:
    """The PREPARE approach (an addition): once the front flippers are up at A0 (command
    and encoders; clear of the riser), each crawler drives on until the riser blocks it:
    its raised front flipper pressed back (|flipper torque| > approach_tau for
    approach_touch_s [s], the paper's touch signal) or its encoder stalled (below a third
    of clm_speed for approach_stall_s). A blocked side stops and the other drives on, so
    the robot turns about the blocked corner until both fronts are at the riser (square
    up: the yaw failure, one flipper meeting the riser first, needs the lagging side to
    catch up, which a heading hold refuses); both blocked or approach_max [m] driven ->
    squared. Only on high steps (h_est > approach_min_h): on 200 / 300 mm steps the first
    touch stops the robot close enough, and driving on to the riser made the later climb
    lose its grip (300 mm: 0/8 with, 4/8 without); elsewhere PREPARE is squared at once.
    Returns the approach state and whether the robot is approaching this period."""
    dt = st.approached.dtype
    flips_up = jnp.all(flip_cmd[:2] >= p["A0"] - 1e-6) & jnp.all(sense.flip_q[:2] >= p["A0"] - 0.02)
    use_approach = (p["approach"] > 0) & (h_est > p["approach_min_h"])
    approaching = prepare & ~st.squared & flips_up & use_approach
    side_v = sense.track_v
    side_stall = jnp.where(approaching & (side_v < p["clm_speed"] / 3.0), st.side_stall + control_dt, 0.0)
    f_press = jnp.abs(sense.flip_tau[:2]) > p["approach_tau"]
    side_touch = jnp.where(approaching & f_press, st.side_touch + control_dt, 0.0)
    blocked = approaching & (st.blocked | (side_stall > p["approach_stall_s"]) | (side_touch > p["approach_touch_s"]))
    approached = jnp.where(approaching, st.approached + jnp.mean(side_v) * control_dt, 0.0)
    squared = st.squared | (prepare & ~use_approach) | (
        approaching & (jnp.all(blocked) | (approached > p["approach_max"])))
    squared = squared & prepare
    new = ApproachState(side_stall.astype(dt), side_touch.astype(dt), blocked, squared, approached.astype(dt))
    return new, approaching


def crawler_drive(p, s: ClmState, ph: Phases, approaching: Array, approach: ApproachState
                  ) -> tuple[Array, Array, Array]:
    """The crawler commands [m/s]: both crawlers drive at clm_speed in WALK unless an arm
    is IDLE, in CLIMB once the front is up (the paper's climb: at once), in DONE, in CRAWL
    past RAISE (at crawl_speed); in the PREPARE approach each side drives until blocked.
    A deep pit found by an arm (`ClmState.pit`) stops them in WALK for good: the paper
    leaves what follows to the operator. Returns whether the crawlers drive (both), their
    speed, and the approach's (left, right) speeds."""
    any_idle = jnp.any(s.arms.arm_phase == IDLE)
    drive = ((ph.walk & ~any_idle & ~s.pit) | (ph.climb & (s.climb.front_up | (p["climb_paper"] > 0))) | ph.done
             | (approaching & ~approach.squared) | (ph.crawl & (s.crawl.sub > RAISE)))
    v_cmd = jnp.where(drive, jnp.where(ph.crawl, p["crawl_speed"], p["clm_speed"]), 0.0)
    v_side = jnp.where(approaching & ~approach.squared & ~approach.blocked, p["clm_speed"], 0.0)
    return drive, v_cmd, v_side


def terrain_pitch(contacts: Array, pitch: Array, roll: Array) -> Array:
    """T_P of Eqs. 22-27 [rad]: the terrain pitch of the contact points (4, 3) in {R}
    (Eq. 7) while the terrain reads flat (Case 1), else the robot's pitch (T_P - R_P = 0:
    across a step edge Eq. 7 gives the slope of the edge, not of the ground the crawlers
    run on)."""
    est = kinematics.explore_terrain(_KP, contacts, pitch, roll)
    return jnp.where(est.case == kinematics.CASE_FLAT, est.pitch, pitch)


def support_arms(p, arms: ArmState, moved: Array, t_p: Array, pitch: Array) -> tuple[Array, Array]:
    """The support arms (PLACED) hold their ground contacts while the crawlers carry the
    body `moved` [m] on (Eqs. 22-27, `clm_rules.predict_contacts`: a ground-fixed point moves by
    -moved (cos a, 0, sin a) in {R}, a = t_p - pitch), then inverse kinematics, aiming
    `press` [m] below the contacts. Returns the contact points (4, 3) in {R} (the other
    arms' unchanged) and the joint commands (4, 3) [rad] that hold them (out of reach,
    beyond the joint range by more than HOLD_RANGE_TOL, or more than HOLD_JUMP from the
    last command, another branch of the inverse kinematics: the last command)."""
    support = arms.arm_phase == clm_rules.PLACED
    contacts = jnp.where(support[:, None], clm_rules.predict_contacts(arms.contacts, moved, t_p, pitch), arms.contacts)
    press = jnp.stack([jnp.zeros_like(p["press"]), jnp.zeros_like(p["press"]), p["press"]])
    q_hold, reach = kinematics.inverse_kinematics_all(_KP, contacts - press)
    # out of reach, or only beyond the joint range: the last command. Clipped instead, a
    # boom at its limit stays there and the elbow alone chases the contact, pressing the
    # roller down (an arm riding the 500 mm block lifted the robot's side off the floor)
    in_range = jnp.all((q_hold >= ARM_LO - HOLD_RANGE_TOL) & (q_hold <= ARM_HI + HOLD_RANGE_TOL), axis=-1)
    # and where the closed form's branch (the arm reaching away from its swing axis) is
    # not the arm's: a roller pushed under its swing axis is reached by the swing turned
    # about pi, a step no servo makes in a period (a block run, 7 Dec 2026: the command
    # jumped by 2.8 rad, the arm whipped round and threw the robot off the floor)
    continuous = jnp.all(jnp.abs(q_hold - arms.q_cmd) <= HOLD_JUMP, axis=-1)
    q_hold = jnp.where(((reach > 0.005) & in_range & continuous)[:, None], q_hold, arms.q_cmd)
    return contacts, q_hold


def transfer_targets(p, prepare: Array, h_est: Array, dt, backoff: Array) -> tuple[Array, Array, Array]:
    """Where the arms transfer to, in {R} [m]: the Table 2 targets; in PREPARE the front
    arms' on the step top (z + h_est) and the rear arms' at their Table 2 *start* points,
    farther back (from the Table 2 targets the rear rollers reached the riser before the
    body had travelled L). Returns the targets (4, 3), the joint angles (4, 3) [rad]
    transfer_press below them (so that the roller meets the ground before the command
    stops: the servo then lags, contact) and clearance_front / clearance_rear above them.
    `backoff` (4,) [m] moves the targets toward the body along x (after deep pits)."""
    front = jnp.asarray(FRONT)
    tgt = jnp.where((prepare & ~front & (p["prepare_rear_init"] > 0))[:, None], jnp.asarray(params.TABLE2_INIT, dt),
                    jnp.asarray(params.TABLE2_TARGET).astype(dt))
    tgt = tgt.at[:, 0].add(-jnp.where(front, 1.0, -1.0) * backoff)
    tgt = tgt.at[:, 2].add(jnp.where(prepare & front, h_est, 0.0))
    clear = jnp.where(front, p["clearance_front"], p["clearance_rear"])
    q_tgt, _ = kinematics.inverse_kinematics_all(_KP, tgt.at[:, 2].add(-p["transfer_press"]))
    q_abv, _ = kinematics.inverse_kinematics_all(_KP, tgt.at[:, 2].add(clear))
    q_tgt, q_abv = jnp.clip(q_tgt, ARM_LO, ARM_HI), jnp.clip(q_abv, ARM_LO, ARM_HI)
    return tgt, q_tgt, q_abv


def _torque_periods(p, arms: ArmState, sense: Sensed, transferring: Array) -> Array:
    """(4,) int32: consecutive periods in which a transferring arm's boom or elbow torque
    was beyond collision_torque [N m] (arms.hit_n + 1, else 0). In LIFT only with that
    joint standing still (moved less than collision_still since the last period: a
    lifting arm pressed on the ground by its folding elbow reaches 117 N m on the step),
    and only once the boom has risen collision_lift [rad] from where the lift began (an
    arm starting on the ground first presses it: the elbow turns by Delta_B while the
    loaded boom has barely moved, which is no obstacle; without this the rear arm in
    PREPARE "collided" in its first 0.1 s and was never moved)."""
    still = jnp.abs(sense.q[:, 1:] - arms.q_prev[:, 1:]) < p["collision_still"]
    lifting = arms.arm_phase == clm_rules.LIFT
    grounded = lifting & (sense.q[:, 1] > arms.lift_from - p["collision_lift"])
    over = transferring & ~grounded & jnp.any(
        (jnp.abs(sense.tau[:, 1:]) > p["collision_torque"]) & (still | ~lifting[:, None]), axis=-1)
    return jnp.where(over, arms.hit_n + 1, 0)


def arm_transfer(p, arms: ArmState, contacts: Array, sense: Sensed, prepare: Array, h_est: Array) -> Transfer:
    """One period of the active arm's transfer (Eqs. 19-21, `clm_rules.transfer_step`: LIFT to
    A_B, SWING to A_S, OVER the target, LOWER until contact) and its collision stop.

    LOWER ends on contact: a joint torque rising by more than collision_threshold in a
    period (`clm_rules.collision`), the boom or elbow held more than contact_lag [rad] short of
    the command of two periods before (a blocked arm: the servo follows a free arm within
    a period), a boom or elbow torque beyond collision_torque for collision_periods
    periods, or the boom at its joint limit (deep pit); past the target's angles the
    boom creeps down by Delta_B per period until then. In SWING and OVER a boom or
    elbow torque beyond collision_torque [N m] for collision_periods periods (in LIFT
    with that joint standing still: a grounded arm's folding elbow presses) stops the arm
    where it is, its command the measured angles (the paper's "the torque of elbow joint
    would reach to the setting value ... all of the joints in that arm stopped in this
    sample period"; free motion reaches 45 N m).
    A_B: lift_boom (rear) / lift_boom_front (front), or lift_min above the current boom if
    that is higher (`lift_to`). A placed arm's contact is its EPRA (encoders), its stop
    case `clm_rules.arm_stop_case` (delta_c, delta_d) against its target; a front arm stopped on
    an obstacle is on the step. `contacts`: the support arms' (`support_arms`)."""
    dt = sense.q.dtype
    q, tau, tips = sense.q, sense.tau, sense.tips
    front = jnp.asarray(FRONT)
    arm_phase, active = arms.arm_phase, arms.active
    is_active = (jnp.arange(4) == active) & (active >= 0)
    tgt, q_tgt, q_abv = transfer_targets(p, prepare, h_est, dt, arms.backoff)
    # > 0: the boom is held up, short of the command of two periods ago (the servo
    # follows a free arm's command within a period; the last command may be a step)
    lag = jnp.max(arms.q_cmd2[:, 1:] - q[:, 1:], axis=-1)  # boom or elbow held up
    hit = clm_rules.collision(tau, arms.tau_prev, p["collision_threshold"])
    lower = arm_phase == clm_rules.LOWER
    at_limit = arms.q_cmd[:, 1] >= BOOM_MAX - 1e-6
    transferring = is_active & (arm_phase <= clm_rules.LOWER)
    hit_n = _torque_periods(p, arms, sense, transferring)
    # LOWER also ends on the torque rule of the other phases (collision_torque for
    # collision_periods): a roller that meets the ground at a slant rolls on, so neither
    # the rise nor the lag fires, and the arm pressed on (a block run, 7 Dec 2026: the
    # elbow torque climbed 50 -> 270 N m over 1.6 s, the roller swept under the body and
    # lifted the robot's side). Free LOWER motion stays below 65 N m before the roller
    # touches (flat and block, 1,400 descents)
    pressed = lower & (hit_n >= p["collision_periods"])
    contact = lower & (hit | (lag > p["contact_lag"]) | pressed)
    # Case 3, a deep pit: the boom at its limit and still no contact ("a new target point
    # will be selected"): the arm lifts again for a target pit_backoff nearer the body
    deep = lower & at_limit & ~contact & (arms.backoff < p["pit_backoff_max"])
    contact = contact | (lower & at_limit & ~deep)
    # A_B: the boom turns up to lift_boom, or by lift_min if it is already higher (a
    # front arm on a high step stands with its boom near vertical: turning it "up" to
    # lift_boom would push the roller into the step)
    lift = jnp.where(arm_phase == clm_rules.LIFT,
                     jnp.maximum(jnp.minimum(jnp.where(front, p["lift_boom_front"], p["lift_boom"]), arms.lift_to),
                                 ARM_LO[1]), arms.lift_to)
    tr_cmd, tr_next = jax.vmap(
        lambda qq, ph, c, qt, qa, ab: clm_rules.transfer_step(qq, ph, c, qt, qa, ab, p["K"], p["delta_a"], p["delta_b"])
    )(arms.q_cmd, arm_phase, contact, q_tgt, q_abv, lift)
    # past the target's angles the descent goes on by Delta_B per period until contact
    # (transfer_step returns to the target angles once the command overshot them)
    creeping = lower & (jnp.abs(arms.q_cmd[:, 2] - q_tgt[:, 2]) < 1e-6) & (arms.q_cmd[:, 1] >= q_tgt[:, 1] - 1e-6)
    tr_cmd = jnp.where(creeping[:, None], arms.q_cmd.at[:, 1].add(p["delta_b"]), tr_cmd)
    tr_cmd = tr_cmd.at[:, 1].set(jnp.minimum(tr_cmd[:, 1], BOOM_MAX))
    # a collision in any phase of the transfer stops the arm: "all of the joints in that
    # arm stopped in this sample period, and arm state moved to arm moving phase from
    # the next sample period" (Figs. 19-20). In SWING and OVER the signal is the paper's,
    # a boom or elbow torque beyond collision_torque ("the torque of elbow joint would
    # reach to the setting value"), collision_periods periods in a row (free motion
    # reaches 26 and 45 N m there: benchmarks/octopus_collision_torque.py); in LIFT that
    # joint must also stand still (`_torque_periods`). (Until 7 Dec 2026 SWING and OVER
    # asked for the stillness too; an arm whose OVER drove its roller into the 500 mm
    # block top then lifted the robot's side off the floor for 0.25 s, the pressed elbow
    # still moving as the body rose, and dropped it when the stop came.) In LOWER the
    # same count is a contact (above)
    collided = (arm_phase < clm_rules.LOWER) & (hit_n >= p["collision_periods"])
    tr_cmd = jnp.where(collided[:, None], sense.q, tr_cmd)
    tr_next = jnp.where(collided, clm_rules.PLACED, tr_next)
    # Case 3 (a pit at the target) of a front arm: a deep one (above), or the roller
    # stopped more than delta_d below its target: hold this period, then LIFT again (A_B
    # lift_min above the boom) for a target pit_backoff nearer the body ("a new target
    # point will be selected"; the text says so for the deep pit, we do it for both: an
    # arm in a pit holds no support). `stop`: where the roller stands against its target
    # (Cases 1-3), for the pit and for a placed arm
    stop = clm_rules.arm_stop_case(tips, tgt, p["delta_c"], p["delta_d"])
    in_pit = lower & contact & front & (stop == clm_rules.STOP_IN_PIT) & (arms.backoff < p["pit_backoff_max"])
    deep = transferring & (deep | in_pit)
    tr_cmd = jnp.where(deep[:, None], arms.q_cmd, tr_cmd)
    tr_next = jnp.where(deep, clm_rules.LIFT, tr_next)
    lift = jnp.where(deep, arms.q_cmd[:, 1] - p["lift_min"], lift)
    just_placed = transferring & (tr_next == clm_rules.PLACED)
    # a placed arm: its contact is where the encoders put the EPRA
    return Transfer(
        cmd=tr_cmd,
        arm_phase=jnp.where(transferring, tr_next, arm_phase),
        transferring=transferring,
        just_placed=just_placed,
        contacts=jnp.where(just_placed[:, None], tips, contacts),
        stop_case=jnp.where(just_placed, stop, arms.stop_case),
        # on the step: the roller stopped more than delta_d above its target, whether or not
        # it also stopped short of it along x (STOP_BLOCKED: a front arm that lands on a
        # 200 mm step top short of its target, near the edge, is on the step too)
        on_step=jnp.where(just_placed, front & (tips[:, 2] - tgt[:, 2] > p["delta_d"]), arms.on_step),
        lift=lift,
        lift_from=jnp.where(deep, arms.q_cmd[:, 1], arms.lift_from),
        hit_n=hit_n,
        deep=deep,
        backoff=arms.backoff + jnp.where(deep, p["pit_backoff"], 0.0),
    )


def detect_step(p, confirmed: Array, h_est: Array, h_est_side: Array, on_step: Array, contacts: Array,
                pitch: Array, roll: Array, walk: Array) -> tuple[Array, Array, Array]:
    """Step detection (WALK): both front arms stopped on an obstacle and H_EST (Eq. 9,
    `kinematics.explore_terrain` on the contact points (4, 3) in {R}) > sigma1 [m] -> the step
    is confirmed, H_EST [m] kept (a rear arm in transfer counts with its stored contact),
    and with it the step height under each side (2,) [m] (`kinematics.side_step_heights`,
    whose mean is H_EST). Returns (confirmed, h_est, h_est_side)."""
    est = kinematics.explore_terrain(_KP, contacts, pitch, roll)
    confirm_now = walk & ~confirmed & jnp.all(on_step[:2]) & (est.step_height > p["sigma1"])
    sides = kinematics.side_step_heights(est.tips_c)
    return (confirmed | confirm_now, jnp.where(confirm_now, est.step_height, h_est),
            jnp.where(confirm_now, sides, h_est_side))


def gait_sequence(p, arms: ArmState, tr: Transfer, ph: Phases, confirmed: Array, squared: Array,
                  control_dt: float) -> ArmState:
    """The crawl gait: one arm transfers at a time; after a transfer ends and gait_pause
    [s] has passed the next one starts (LIFT, A_B = its boom - lift_min at first). In
    WALK (until a step is confirmed) the next arm in CRAWL_ORDER (RR, RF, LR, LF); one
    front arm on the step -> the other front arm next (the rear arms wait, Fig. 14 C);
    that one on the floor -> no step: both marks cleared, the gait goes on. In
    PREPARE, once squared, the rear arms in PREPARE_ORDER (RR, then LR), N_PREPARE in all.
    Returns the arm state with the transfer's contacts, stop cases, on_step and the
    sequencing (arm phases, ptr, active, pause, placed_n, lift_to); the commands are the
    caller's (`arm_commands`)."""
    order = jnp.asarray(CRAWL_ORDER)
    front = jnp.asarray(FRONT)
    ended = jnp.any(tr.just_placed)
    pause = jnp.where(ended | (arms.active >= 0), 0.0, arms.pause + control_dt)
    active = jnp.where(ended, -1, arms.active)
    placed_n = arms.placed_n + jnp.where(ended & ph.prepare, 1, 0)
    ptr = jnp.where(ended, (arms.ptr + 1) % 4, arms.ptr)
    # step detection: one front arm on the step -> the other front arm goes next; if
    # that one lands on the floor, the obstacle is no step across the path (a block
    # beside the robot, Figs. 19-20): the first one's mark is cleared and the gait goes on
    on_step = tr.on_step
    other_front_down = ended & jnp.any(tr.just_placed & front & ~on_step)
    on_step = jnp.where(ph.walk & other_front_down, False, on_step)
    one_front = jnp.any(on_step & front) & ~jnp.all(on_step[:2])
    other = jnp.where(on_step[0], 1, 0)
    other_ptr = jnp.argmax(order == other).astype(jnp.int32)
    ptr = jnp.where(ph.walk & one_front & ended, other_ptr, ptr)
    want_next = (ph.walk & ~confirmed) | (ph.prepare & squared & (placed_n < N_PREPARE))
    start = want_next & (active < 0) & (pause >= p["gait_pause"]) & ~ended
    nxt_arm = jnp.where(ph.prepare, jnp.asarray(PREPARE_ORDER)[jnp.minimum(placed_n, N_PREPARE - 1)], order[ptr])
    active = jnp.where(start, nxt_arm, active)
    starting = start & (jnp.arange(4) == nxt_arm)
    return arms._replace(
        arm_phase=jnp.where(starting, clm_rules.LIFT, tr.arm_phase),
        ptr=ptr,
        active=active,
        pause=pause,
        placed_n=placed_n,
        contacts=tr.contacts,
        stop_case=tr.stop_case,
        on_step=on_step,
        lift_to=jnp.where(starting, arms.q_cmd[:, 1] - p["lift_min"], tr.lift),
        lift_from=jnp.where(starting, arms.q_cmd[:, 1], tr.lift_from),
    )


def front_flipper_rule(p, flip: Array, flip_tau: Array) -> tuple[Array, Array, Array]:
    """The front flippers' torque rule in WALK (`clm_rules.flipper_rule`, Cases 1-3: T0,
    flip_delta_a, A0, flip_delta_b) on the last commands (4,) [rad] and the flipper
    torques (4,) [N m]. Returns the front flipper commands (2,) [rad], the cases (2,) and
    whether the riser is met: Case 3 (A' > A0), or with stop_on_touch a front flipper
    yielded (Case 2) touch_rise above front_start (a single Case 2 period also comes from
    the arm transfers' jolts)."""
    f_rule, f_case = clm_rules.flipper_rule(flip[:2], flip_tau[:2], p["T0"], p["flip_delta_a"], p["A0"],
                                     p["flip_delta_b"])
    f_rule = jnp.clip(f_rule, -FLIPPER_MAX, FLIPPER_MAX)
    touched_riser = jnp.any(f_rule > p["front_start"] + p["touch_rise"])
    at_a0 = jnp.any(f_case == clm_rules.FLIPPER_LIMIT) | ((p["stop_on_touch"] > 0) & touched_riser)
    return f_rule, f_case, at_a0


def crawler_stall(p, stall: Array, v: Array, ph: Phases, confirmed: Array, crawl_sub: Array,
                  control_dt: float) -> Array:
    """How long [s] the crawlers (mean encoder speed v [m/s]) have been below a third of
    clm_speed while they should drive into something: at the riser (WALK, step
    confirmed), or blocked by the next riser with the arms carried (DONE, CRAWL past
    RAISE); 0 otherwise."""
    watch = (ph.walk & confirmed) | ph.done | (ph.crawl & (crawl_sub > RAISE))
    return jnp.where(watch & (v < p["clm_speed"] / 3.0), stall + control_dt, 0.0)


def climb_step(p, s: ClmState, sense: Sensed, h: Array, travel: Array) -> Climb:
    """One period of CLIMB: arm and flipper commands and the release condition.

    `climb_paper` = 0 (ours, the level lift): Eq. 28 per arm in task space: the pushing
    arms lower their EPRAs by delta_e * l1 [m] per period along the world vertical
    (`_tips_moved`), front / rear and left / right arms taking turns to stay within
    level_band [rad] of level, while the front crawler ends are below the step top
    (front_clearance [m], from the front EPRAs resting on it); Eq. 29 (`clm_rules.climb_rule`):
    the flippers turn down by delta_f once the front is lifted (front to flip_min, rear to
    rear_flip_min; with rear_flip_late = 0 the rear ones at once). Over when H - h0 >
    H_EST, S > L (S = `travel` [m] from the front flippers' touch-down) and the pitch below
    release_pitch. `climb_paper` = 1: `paper_climb_step`, over when H > H_EST and S > L
    (S = the stored travel, from the CLIMB start). h: the COG height H [m] (Eqs. 10-17)."""
    dt = sense.q.dtype
    a_p, a_r = sense.pitch, sense.roll
    q_cmd, flip = s.arms.q_cmd, s.flip
    rise = h - s.climb.h0
    # the release waits for the body to be back near level (see module docstring)
    s_eff = jnp.where((a_p < p["release_pitch"]) & s.climb.touched, travel, -1.0)
    _, flip_c, on_top = clm_rules.climb_rule(q_cmd[:, 1], flip, rise, s.h_est, s_eff, p["settle_distance"],
                                             p["delta_e"], p["delta_f"])
    # the paper: S from the CLIMB start (Eq. 18), H the COG height above the rear EPRAs'
    # ground (Eqs. 10-17) against H_EST; per side (climb_per_side, Fig. 17) each side's H
    # above its rear EPRA against the step height under it
    per_side = p["climb_per_side"] > 0
    h_side = jnp.where(per_side, kinematics.cog_height_sides(_KP, sense.tips, a_p, a_r), h)
    side_up = (h_side > jnp.where(per_side, s.h_est_side, s.h_est)) & (s.travel > p["settle_distance"])
    on_top_paper = jnp.all(side_up)
    # Eq. 28 per arm, a level lift: the arms push the body up while the front crawler
    # ends are below the step top (estimated from the front EPRAs resting on it:
    # "H < H_EST"); front and rear (left and right) arms take turns so that the body
    # stays within level_band of level; once lifted they only keep it level. (Lifting
    # the nose alone rolls the robot backwards over its rear flipper tips.)
    axles_c = kinematics.to_level_frame(jnp.asarray(FRONT_AXLES, dt), a_p, a_r)
    front_c = kinematics.to_level_frame(sense.tips[:2], a_p, a_r)
    clear = jnp.min(axles_c[:, 2] - params.MAIN_WHEEL_RADIUS - (front_c[:, 2] - params.ROLLER_RADIUS))
    front_low = clear < p["front_clearance"]
    band = p["level_band"]
    push = jnp.where(jnp.asarray(FRONT), (front_low & (a_p < band)) | (a_p < -band),
                     (front_low & (a_p > -band)) | (a_p > band))
    push = push & jnp.where(LEFT, a_r > -band, a_r < band)
    # Eq. 28, read in the task space: a boom turning down by Delta_E lowers its EPRA by
    # about Delta_E l1; we lower the EPRAs of the pushing arms by Delta_E l1 along the
    # world vertical (inverse kinematics, elbow included), so that the arms lift the
    # body instead of pushing it backwards when it is pitched
    dz = p["delta_e"] * params.L1
    q_climb = _tips_moved(q_cmd, push & ~on_top, -dz, a_p, a_r)
    # the front flippers stay raised until the front is above the step top (they
    # would jam against the riser), then turn down onto it (to flip_min); the rear
    # ones (to rear_flip_min) too, or at once with rear_flip_late = 0: turning down with
    # their tips on the ground they lifted the tail but pushed the robot (on the arms'
    # free rollers) about 7 cm back from the riser, out of the lifted flippers' reach
    flip_c = jnp.where((FRONT4 | (p["rear_flip_late"] > 0)) & front_low & ~on_top, flip, flip_c)
    flip_c = jnp.clip(flip_c, jnp.where(FRONT4, p["flip_min"], p["rear_flip_min"]), FLIPPER_MAX)
    # the paper's CLIMB (Eqs. 28-29 as printed)
    paper = p["climb_paper"] > 0
    q_paper, flip_paper = paper_climb_step(p, q_cmd, flip, sense.flip_q, sense.flip_tau, side_up)
    # the release also waits for the body to have tipped over the edge onto the top
    # (IMU pitch back below release_pitch): S from the crawler encoders runs ahead of
    # the body when the tracks slip on the edge
    over = jnp.where(paper, on_top_paper, on_top & (a_p < p["release_pitch"]))
    return Climb(jnp.where(paper, q_paper, q_climb), jnp.where(paper, flip_paper, flip_c), over, front_low)


def release_step(p, q_cmd: Array, flip: Array, pitch: Array, roll: Array) -> tuple[Array, Array, Array]:
    """One period of RELEASE (Eqs. 28-29, second branches), from the last arm commands
    (4, 3) and flipper commands (4,) [rad]. `climb_paper` = 0: every EPRA rises by
    delta_e * l1 [m] per period along the world vertical (the body goes down evenly onto
    the crawlers) until back at the Table 2 height in {R} ("theta_2' > 0" of the authors'
    joint zero); the flippers turn up by delta_f to 0. `climb_paper` = 1:
    `paper_release_step`. Returns arm commands, flipper commands and whether all are
    back (-> DONE)."""
    dz = p["delta_e"] * params.L1
    high = kinematics.arm_tips(_KP, q_cmd)[:, 2] >= TABLE2_Z - 1e-3
    q_release = _tips_moved(q_cmd, ~high, dz, pitch, roll)
    flip_r = jnp.where(flip < 0, jnp.minimum(flip + p["delta_f"], 0.0), flip)
    back = jnp.all(high) & jnp.all(flip >= 0.0)
    paper = p["climb_paper"] > 0
    q_paper, flip_paper, back_paper = paper_release_step(p, q_cmd, flip)
    return (
        jnp.where(paper, q_paper, q_release),
        jnp.where(paper, flip_paper, flip_r),
        jnp.where(paper, back_paper, back),
    )


def carry_step(p, q_cmd: Array) -> Array:
    """DONE and CRAWL: the arms (commands (4, 3) [rad]) go to the carrying pose, clear of
    the terrain (booms at lift_boom_front first, then the elbows to carry_elbow; swings
    held), by at most delta_b per joint and period."""
    carry = jnp.stack([q_cmd[:, 0], jnp.full(4, p["lift_boom_front"]), jnp.full(4, p["carry_elbow"])], axis=1)
    booms_up = jnp.all(q_cmd[:, 1] <= p["lift_boom_front"] + 1e-3)
    step_max = jnp.where(jnp.arange(3) == 2, jnp.where(booms_up, p["delta_b"], 0.0), p["delta_b"])
    return q_cmd + jnp.clip(carry - q_cmd, -step_max, step_max)


def crawl_step(p, s: ClmState, sense: Sensed, stalled: Array, crawl: Array, control_dt: float
               ) -> tuple[Array, CrawlState, Array]:
    """One period of CRAWL (`_crawl_step`, from the last flipper and arm commands) while
    `crawl`; otherwise the sub-phase rests at RAISE. `stalled`: the crawlers stalled
    stall_s. Returns the flipper commands (4,) [rad], the CRAWL state (crawled_last as it
    was: `enter_phase` sets it) and whether the sub-phases are over (LEVEL for
    crawl_level_s)."""
    flip_cr, sub, t_sub, over = _crawl_step(p, s.crawl, s.arms.q_cmd, s.flip, sense.pitch, sense.time, stalled,
                                            control_dt)
    return flip_cr, s.crawl._replace(sub=jnp.where(crawl, sub, RAISE), t_sub=t_sub), over


def arm_commands(ph: Phases, transferring: Array, hold: Array, tr_cmd: Array, q_hold: Array, q_cmd: Array,
                 q_climb: Array, q_release: Array, q_done: Array) -> Array:
    """The arm commands (4, 3) [rad] of the phase, within the joint ranges: WALK and
    PREPARE: the transferring arm its transfer command, the holding support arms their
    contact-holding command, the rest their last command (IDLE arms; the arms rolling
    along in the PREPARE approach); CLIMB, RELEASE: theirs; DONE and CRAWL: the carry."""
    q_walk = jnp.where(transferring[:, None], tr_cmd, jnp.where(hold[:, None], q_hold, q_cmd))
    q = jnp.select([ph.climb, ph.release, ph.done | ph.crawl], [q_climb, q_release, q_done], q_walk)
    return jnp.clip(q, ARM_LO, ARM_HI)


def flipper_commands(p, ph: Phases, flip: Array, f_rule: Array, flip_climb: Array, flip_release: Array,
                     flip_crawl: Array) -> Array:
    """The flipper commands (4,) [rad] of the phase: WALK: the front ones by the torque rule
    (`front_flipper_rule`), the rear ones 0; PREPARE: the front ones up to A0 by
    flip_delta_a per period (Fig. 9d); CLIMB, RELEASE, CRAWL: theirs; DONE: 0."""
    dt = flip.dtype
    flip_walk = jnp.concatenate([f_rule, jnp.zeros(2, dt)])
    flip_prep = flip.at[:2].set(jnp.minimum(flip[:2] + p["flip_delta_a"], p["A0"]))
    flip_walk = jnp.where(ph.walk, flip_walk, jnp.where(ph.prepare, flip_prep, flip))
    return jnp.select(
        [ph.climb, ph.release, ph.done, ph.crawl], [flip_climb, flip_release, jnp.zeros(4, dt), flip_crawl], flip_walk
    )


def phase_transition(p, s: ClmState, ph: Phases, arms: ArmState, confirmed: Array, h_est: Array, at_riser: Array,
                     stall: Array, climb_over: Array, release_over: Array, crawl_over: Array) -> Transition:
    """The robot phase transitions (`arms`, `confirmed`, `h_est`, `stall`: this period's).
    WALK -> PREPARE: a confirmed step, the riser met (`at_riser`) or the crawlers stalled
    stall_s [s], no transfer under way; -> CRAWL instead if H_EST <= crawl_max_h [m].
    PREPARE -> CLIMB: the N_PREPARE rear arms placed. CLIMB -> RELEASE: `climb_over`.
    RELEASE -> DONE: `release_over`; CRAWL -> DONE: `crawl_over`. DONE -> WALK after
    done_distance [m] (the stored travel) or stalled; stalled right after a CRAWL climb ->
    CRAWL (the next terrace of a staircase)."""
    to_prepare = ph.walk & confirmed & (at_riser | (stall > p["stall_s"])) & (arms.active < 0)
    low_step = h_est <= p["crawl_max_h"]
    to_climb = ph.prepare & (arms.placed_n >= N_PREPARE) & (arms.active < 0)
    to_release = ph.climb & climb_over
    # DONE -> WALK once the robot has driven done_distance on the top (arms carried):
    # the arms are placed again one at a time (crawlers waiting), for the next terrace
    # ... but blocked again right after a CRAWL climb: the next low terrace of a
    # staircase, climbed the same way (groping it with the arms while pitched on the
    # last edge tipped the robot over)
    recrawl = ph.done & s.crawl.crawled_last & (stall > p["stall_s"])
    rewalk = ph.done & ~recrawl & ((s.travel > p["done_distance"]) | (stall > p["stall_s"]))
    released = ph.release & release_over
    crawled = ph.crawl & crawl_over
    finished = released | crawled
    nxt = jnp.select([to_prepare & low_step, to_prepare, to_climb, to_release, finished, recrawl, rewalk],
                     [CRAWL, PREPARE, CLIMB, RELEASE, DONE, CRAWL, WALK],
                     s.phase)
    return Transition(nxt, nxt != s.phase, finished, crawled, rewalk)


def enter_phase(tr: Transition, time: Array, arms: ArmState, confirmed: Array, crawl: CrawlState
                ) -> tuple[ArmState, Array, CrawlState]:
    """The resets of a phase change: entering PREPARE or WALK restarts the gait at RR
    (ptr 0); any change restarts the pause and the PREPARE count; a finished climb
    (-> DONE) or entering CRAWL makes every arm IDLE (to be placed again, one at a time,
    in the next WALK), and a finished climb clears the step detection and the active arm;
    entering CRAWL starts its sub-phase clock at `time` [s]."""
    nxt, changed, finished = tr.phase, tr.changed, tr.finished
    arms = arms._replace(
        ptr=jnp.where(changed & ((nxt == PREPARE) | (nxt == WALK)), 0, arms.ptr),
        placed_n=jnp.where(changed, 0, arms.placed_n),
        arm_phase=jnp.where(finished | (changed & (nxt == CRAWL)), IDLE, arms.arm_phase),
        on_step=jnp.where(finished, False, arms.on_step),
        active=jnp.where(finished, -1, arms.active),
        pause=jnp.where(changed, 0.0, arms.pause),
    )
    crawl = crawl._replace(t_sub=jnp.where(changed & (nxt == CRAWL), time, crawl.t_sub),
                           crawled_last=jnp.where(finished, tr.crawled, crawl.crawled_last))
    return arms, jnp.where(finished, False, confirmed), crawl


def climb_progress(p, s: ClmState, sense: Sensed, ph: Phases, tr: Transition, front_low: Array, h: Array,
                   travel: Array) -> tuple[ClimbState, Array]:
    """CLIMB bookkeeping: the front is up once the front crawler ends cleared the step
    top; S (Eq. 18, Fig. 5: the front flipper pivots past the edge) starts when the
    lifted front flippers touch down on the step top (|torque| > T0): the edge is then
    just behind their tips, S = -(flipper length x cos A) [m]; the paper's climb counts S
    from the CLIMB start ("when the robot starts to climb the obstacle, S equals 0"), or
    from the touch-down with s_from_touch = 1. In DONE (until WALK) the travel counts the
    drive on the top; otherwise 0. h0: the COG height H [m] on entering CLIMB.
    `travel`: the stored travel advanced by this period's encoder travel. Returns the
    CLIMB state and the travel [m]."""
    climb, done = ph.climb, ph.done
    front_up = climb & (s.climb.front_up | ~front_low)
    touch_now = climb & ~s.climb.touched & ~front_low & jnp.any(jnp.abs(sense.flip_tau[:2]) > p["T0"])
    reach0 = params.FLIPPER_LENGTH * jnp.mean(jnp.cos(sense.flip_q[:2]))
    touched = (s.climb.touched | touch_now) & (tr.phase == CLIMB)
    s_touch = (p["climb_paper"] <= 0) | (p["s_from_touch"] > 0)
    travel = jnp.where(touch_now & s_touch, -reach0,
                       jnp.where((climb & (s.climb.touched | ~s_touch)) | (done & ~tr.rewalk), travel, 0.0))
    h0 = jnp.where(tr.changed & (tr.phase == CLIMB), h, s.climb.h0)
    return ClimbState(h0.astype(s.climb.h0.dtype), touched, front_up), travel


def clm_step(p, s: ClmState, obs, control_dt: float = CONTROL_DT) -> tuple[ClmState, Array]:
    """One control period of the CLM: the next state and the action (crawlers (2,) [m/s],
    flippers (4,) [rad], arm joints (12,) [rad]). Wires the functions above."""
    sense = measure(obs)
    dt = sense.q.dtype
    a_p, a_r = sense.pitch, sense.roll
    ph = phase_masks(s.phase)
    travel_step = sense.v * control_dt  # L of Eqs. 22-27, from the crawler encoders

    # crawlers (and the PREPARE approach)
    approach, approaching = approach_step(p, s.approach, s.flip, s.h_est, sense, ph.prepare, control_dt)
    drive, v_cmd, v_side = crawler_drive(p, s, ph, approaching, approach)
    # the arms: support, transfer, step detection, gait
    t_p = terrain_pitch(s.arms.contacts, a_p, a_r)
    contacts, q_hold = support_arms(p, s.arms, jnp.where(drive, travel_step, 0.0), t_p, a_p)
    tr = arm_transfer(p, s.arms, contacts, sense, ph.prepare, s.h_est)
    confirmed, h_est, h_est_side = detect_step(p, s.confirmed, s.h_est, s.h_est_side, tr.on_step, tr.contacts, a_p,
                                               a_r, ph.walk)
    arms = gait_sequence(p, s.arms, tr, ph, confirmed, approach.squared, control_dt)
    # front flippers, stall
    f_rule, f_case, at_riser = front_flipper_rule(p, s.flip, sense.flip_tau)
    stall = crawler_stall(p, s.stall, sense.v, ph, confirmed, s.crawl.sub, control_dt)
    # CLIMB, RELEASE, CRAWL, DONE
    h = kinematics.cog_height(_KP, sense.tips, a_p, a_r)
    travel = kinematics.travel_update(s.travel, travel_step, a_p)
    climb = climb_step(p, s, sense, h, travel)
    q_release, flip_release, release_over = release_step(p, s.arms.q_cmd, s.flip, a_p, a_r)
    flip_crawl, crawl, crawl_over = crawl_step(p, s, sense, stall > p["stall_s"], ph.crawl, control_dt)
    q_done = carry_step(p, s.arms.q_cmd)
    # commands: the PREPARE approach holds the arm commands (the passive rollers roll
    # along with the body: holding the contacts by the encoder travel there loaded the
    # arms more as the tracks slipped at the riser, until the robot stood on its arms)
    support = s.arms.arm_phase == clm_rules.PLACED
    hold = support & ~(approaching & ~approach.squared)
    q_cmd = arm_commands(ph, tr.transferring, hold, tr.cmd, q_hold, s.arms.q_cmd, climb.q, q_release, q_done)
    flip_n = flipper_commands(p, ph, s.flip, f_rule, climb.flip, flip_release, flip_crawl)
    # phase transitions
    trans = phase_transition(p, s, ph, arms, confirmed, h_est, at_riser, stall, climb.over, release_over, crawl_over)
    arms, confirmed, crawl = enter_phase(trans, sense.time, arms, confirmed, crawl)
    climb_st, travel = climb_progress(p, s, sense, ph, trans, climb.front_low, h, travel)
    # contacts of IDLE arms follow the EPRA, and so do those of the arms in CLIMB and
    # RELEASE and of the arms rolling along in the PREPARE approach
    rolling = (support & ~hold)[:, None]
    contacts = jnp.where((arms.arm_phase == IDLE)[:, None] | (ph.climb | ph.release) | rolling, sense.tips,
                         arms.contacts)

    # no heading hold: the CLM cannot measure the yaw (`operator` steers, if anyone)
    tracks = jnp.where(ph.prepare, v_side, jnp.stack([v_cmd, v_cmd]))
    action = jnp.concatenate([tracks.astype(dt), flip_n, q_cmd.reshape(-1)])
    new = ClmState(
        phase=trans.phase.astype(jnp.int32),
        t_phase=jnp.where(trans.changed, sense.time, s.t_phase).astype(dt),
        confirmed=confirmed,
        h_est=h_est.astype(dt),
        h_est_side=h_est_side.astype(dt),
        flip=flip_n,
        flip_case=f_case.astype(jnp.int32),
        stall=stall.astype(dt),
        travel=travel.astype(dt),
        climbed=s.climbed + jnp.where(trans.finished, 1, 0).astype(jnp.int32),
        # a pit ahead (Case 3 of a transfer, `Transfer.deep`): the paper does not say how
        # the CLM goes down, so the crawlers stop and the operator decides
        pit=s.pit | (ph.walk & jnp.any(tr.deep)),
        arms=ArmState(
            arm_phase=arms.arm_phase.astype(jnp.int32),
            ptr=arms.ptr.astype(jnp.int32),
            active=arms.active.astype(jnp.int32),
            pause=arms.pause.astype(dt),
            placed_n=arms.placed_n.astype(jnp.int32),
            contacts=contacts,
            stop_case=arms.stop_case.astype(jnp.int32),
            on_step=arms.on_step,
            q_cmd=q_cmd,
            q_cmd2=s.arms.q_cmd,
            lift_to=arms.lift_to.astype(dt),
            lift_from=arms.lift_from.astype(dt),
            tau_prev=sense.tau,
            q_prev=sense.q,
            backoff=tr.backoff.astype(dt),
            hit_n=tr.hit_n.astype(jnp.int32),
        ),
        approach=approach,
        climb=climb_st,
        crawl=CrawlState(crawl.sub.astype(jnp.int32), crawl.t_sub.astype(dt), crawl.crawled_last),
    )
    return new, action


def make_controller(control_dt: float = CONTROL_DT) -> Controller:
    """The CLM as a `Controller` (`clm_init`, `clm_step` at control_dt [s])."""

    def step(p, s: ClmState, obs) -> tuple[ClmState, Array]:
        return clm_step(p, s, obs, control_dt)

    return Controller(clm_init, step, name="clm")
