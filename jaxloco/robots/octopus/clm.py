"""The compound locomotion mode (CLM) controller of OCTOPUS (paper, "Control system design
for CLM" and "Arms and crawlers control in getting over obstacle", Figs. 7, 9, 14): the
crawlers drive, the front flippers follow the terrain by their torque, and the four arms
walk beside the crawlers in a crawl gait, grope the terrain and lift the body over steps.
Pure JAX, one simulation, fixed shapes, 50 Hz; every switch is a mask (`jnp.where`,
`jnp.select`); the rollout vmaps it. It composes the rules of `clm_rules` and the
kinematics of `kinematics`, and senses only what the real robot senses: joint angles and
torques, the IMU (attitude, and the heading for the heading hold), the crawler encoders
(travel). Never the terrain parameters. Every gain is a params entry (`PARAM_DEFAULTS`).

Robot phases (`PHASE_NAMES`; Fig. 9 a-h and the phases A-F of Fig. 14):
  WALK 0 (Fig. 9a-c, Fig. 14 A-C): crawlers at `clm_speed` (heading hold); front flippers
    by the torque rule (`clm_rules.flipper_rule`, Cases 1-3: T0, flip_delta_a, A0,
    flip_delta_b), rear flippers 0. Arms: the support arms hold their ground contacts
    (Eqs. 22-27, `predict_contacts` with the crawler-encoder travel, then inverse
    kinematics); one arm at a time transfers (`transfer_step`, Eqs. 19-21: lift to A_B,
    swing to A_S, over the target, lower until contact) to its Table 2 target, in
    `CRAWL_ORDER` (RR, RF, LR, LF) with `gait_pause` between transfers: at least three
    arms support the robot at any time (while any arm is IDLE the crawlers wait). Where a
    transfer stopped is classified by `arm_stop_case` (delta_c, delta_d).
    Step detection: a front arm stops on an obstacle (STOP_ON_OBSTACLE, dz > delta_d) ->
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
    approach_max driven) -> the heading to hold becomes the current one. (Without it, at
    400 mm the first flipper touch left the crawler fronts about 0.15 m short of the
    riser, and the lifted front flippers did not reach the top: 0/8.) Then the rear arms
    (RR, then LR) are transferred to their Table 2 *start* points on the ground (farther
    back than the targets: from there the rear rollers reached the riser before the body
    had travelled L); the front arms stay on the step top. Both placed -> CLIMB.
  CLIMB 2 (Fig. 9e, Fig. 14 E): Eq. 28 in task space: the pushing arms lower their EPRAs
    by delta_e * l1 per period along the world vertical (inverse kinematics), lifting the
    body level (front / rear and left / right arms take turns to stay within level_band),
    while the front crawler ends are below the step top (from the front EPRAs resting on
    it: the reading of "H < H_EST" that lets the crawlers onto the step). Eq. 29: the
    flippers turn down by delta_f once the front is lifted (front to flip_min, onto the
    step top; rear to rear_flip_min; with rear_flip_late = 0 the rear ones at once). The crawlers drive once the front is
    lifted. S (Eq. 18, crawler encoders) starts when the front flippers touch down on the
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
    before (a blocked arm), or the boom at its joint limit (deep pit). Only LOWER watches
    it (in OVER the fast free motion gives torque jumps of the same size). The joints aim
    transfer_press below the target, so the roller meets the ground before the command
    stops, and past the target angles the boom creeps down by Delta_B per period.
  * A_B, A_S: our joint zeros differ from the authors' (see `clm_rules.transfer_step`):
    A_B = lift_boom (rear) / lift_boom_front (front arms, higher: their rollers must
    pass over a 400 mm step top), or lift_min above the current boom if that is already
    higher; A_S from inverse kinematics of the target; the target is passed over from
    clearance_front / clearance_rear above it.
  * Eq. 28 turns only the booms: with the elbows held the EPRAs sweep arcs and, once the
    robot pitches, push it backwards; in the simulation that rolled the robot over its
    rear flipper tips. We move the EPRAs straight down in the world instead (the boom's
    Delta_E at the boom end, delta_e * l1) and lift level.
  * T_P of Eqs. 22-27: the terrain pitch of the contact points (Eq. 7) while the terrain
    reads flat (Case 1), else the robot's pitch (T_P - R_P = 0): across a step edge Eq. 7
    gives the slope of the edge, not of the ground the crawlers run on.
  * A0: Case 3 needs A' > A0, so A0 is a little below the 85 deg joint limit.
  * step confirmed = both front arms on an obstacle and H_EST > sigma1 (terrain Case 2
    needs the rear arms too, but a rear arm may be in transfer; its stored contact is
    used).
  * the support arms aim at their contact points (press = 0): pressing them 10 mm below
    unloaded the tracks unevenly and turned the robot by 0.16 rad on flat ground.
  * heading hold (heading_gain; 0 is the paper's controller, which assumes the yaw does
    not change): ours turns when one front flipper meets the riser first.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco.robots.octopus import clm_rules as cr
from jaxloco.robots.octopus import kinematics as kin
from jaxloco.robots.octopus import model as octo_model
from jaxloco.robots.octopus import params as P
from jaxloco.sim.scenario import Controller

Array = jax.Array

WALK, PREPARE, CLIMB, RELEASE, DONE, CRAWL = 0, 1, 2, 3, 4, 5
PHASE_NAMES = ("walk", "prepare", "climb", "release", "done", "crawl")
# CRAWL sub-phases: front flippers up (arms to the carrying pose), front flippers down
# onto the edge while driving, rear flippers push, level on the top
RAISE, LOWER_F, PUSH, LEVEL = 0, 1, 2, 3
IDLE = 5  # arm phase after cr.PLACED (4): holding, waiting for a transfer
ARM_PHASE_NAMES = (*cr.TRANSFER_PHASES, "idle")
CONTROL_DT = 0.02  # [s] 50 Hz
FRONT = np.array([True, True, False, False])  # arms 1..4 (LF, RF, LR, RR)
LEFT = np.array([True, False, True, False])
FRONT4 = np.array([True, True, False, False])  # flippers fl, fr, rl, rr
TABLE2_Z = float(P.TABLE2_TARGET[0, 2])
# the front main crawler axles in {R} [m]
FRONT_AXLES = np.array([[P.MAIN_AXLE_X, s * P.CRAWLER_Y, P.MAIN_WHEEL_RADIUS - P.BASE_HEIGHT] for s in (1.0, -1.0)])
CRAWL_ORDER = np.array(cr.CRAWL_ORDER)
N_PREPARE = 2
PREPARE_ORDER = np.array([3, 2])  # PREPARE transfers the rear arms only (RR, then LR)

PARAM_DEFAULTS: dict[str, float] = {
    "clm_speed": 0.03,  # [m/s] crawler speed in CLM (slower than CCM: the arms must follow)
    # front flipper torque rule (Cases 1-3)
    "T0": 15.0,  # [N m] torque threshold
    "flip_delta_a": 0.02,  # [rad/period] Delta_A
    "A0": math.radians(82.0),  # [rad] flipper limit A0 (just below the 85 deg joint limit)
    "flip_delta_b": 0.01,  # [rad/period] Delta_B
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
    "collision_threshold": 50.0,  # [N m] joint torque rise in one period = collision
    "contact_lag": 0.04,  # [rad] boom / elbow behind its command = blocked (LOWER only)
    "transfer_press": 0.05,  # [m] a transfer aims this far below its target
    "carry_elbow": 1.6,  # [rad] elbow of the carrying pose after the release
    "done_distance": 0.4,  # [m] driven on the top with the arms carried before walking again
    "gait_pause": 0.3,  # [s] between two transfers
    "heading_gain": 0.2,  # [m/s per rad] track speed difference per rad of heading error
    "press": 0.0,  # [m] support arms aim this far below their contact points (> 0 loads the
    # arms, but unloads the tracks unevenly: 10 mm turned the robot by 0.16 rad on flat ground)
    # arm stop cases
    "delta_c": 0.08,  # [m]
    "delta_d": 0.05,  # [m]
    # terrain exploration
    "sigma1": 0.05,  # [m]
    "stall_s": 1.0,  # [s] crawlers below a third of the command this long = stalled
    # climbing (Eqs. 28-29)
    "delta_e": 0.006,  # [rad/period] boom step (the EPRA moves Delta_E l1 per period)
    "delta_f": 0.01,  # [rad/period] flipper step
    "settle_distance": 0.3,  # [m] L = 0.6 x 500 mm
    # CRAWL (an addition, see the module docstring): low steps climbed by crawlers and flippers
    "crawl_max_h": 0.25,  # [m] confirmed steps up to this height (paper: < 250 mm without arms)
    "crawl_speed": 0.063,  # [m/s] crawler speed in CRAWL (the CCM baseline's)
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
    "approach_min_h": 0.35,  # [m] ... on steps with H_EST above this only (see make_controller)
    "approach_stall_s": 0.6,  # [s] a crawler below a third of clm_speed this long = at the riser
    "approach_max": 0.35,  # [m] the approach ends after this travel (encoders) in any case
    "approach_tau": 6.0,  # [N m] a raised front flipper pressed by the riser: |torque| above this ...
    "approach_touch_s": 0.1,  # [s] ... this long = that crawler is at the riser
}

_KP = P.default_params()
BOOM_MAX = octo_model.ARM_RANGE[1][1]
ARM_LO = np.array([r[0] for r in octo_model.ARM_RANGE])
ARM_HI = np.array([r[1] for r in octo_model.ARM_RANGE])
FLIPPER_MAX = P.FLIPPER_LIMIT


def start_pose() -> tuple[np.ndarray, np.ndarray]:
    """The CLM start pose: arms (4, 3) in the Table 2 initial pose (rollers on the
    ground), flippers (4,) [rad] (front ones at `front_start`)."""
    flips = np.array([PARAM_DEFAULTS["front_start"]] * 2 + [0.0, 0.0])
    return octo_model.home_arm_angles(), flips


def _yaw(quat: Array) -> Array:
    w, x, y, z = quat[0], quat[1], quat[2], quat[3]
    return jnp.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def _wrap(a: Array) -> Array:
    return jnp.arctan2(jnp.sin(a), jnp.cos(a))


def _tips_moved(q: Array, move: Array, dz_level: Array, a_p: Array, a_r: Array) -> Array:
    """Arm joints (4, 3) that move the EPRAs of the arms with `move` (4,) by dz_level [m]
    along the vertical of the level frame {C} (inverse kinematics from the current
    commands `q`); the others, and any out of reach, keep `q`."""
    tips = kin.arm_tips(_KP, q)
    d_r = kin.level_rotation(a_p, a_r).T @ jnp.stack([0.0 * dz_level, 0.0 * dz_level, dz_level])
    q_new, reach = kin.inverse_kinematics_all(_KP, tips + d_r)
    ok = move & (reach > 0.005)
    return jnp.where(ok[:, None], q_new, q)


def _crawl_step(p, s, flip: Array, pitch: Array, t: Array, stalled: Array, control_dt: float):
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
    Returns the flipper commands, the next sub-phase, its start time and whether CRAWL
    is over."""
    sub, t0 = s["crawl"], s["t_crawl"]
    booms_up = jnp.all(s["q_cmd"][:, 1] <= p["lift_boom_front"] + 1e-3)
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


def make_controller(control_dt: float = CONTROL_DT) -> Controller:
    kp = _KP
    targets0 = jnp.asarray(P.TABLE2_TARGET)
    order = jnp.asarray(CRAWL_ORDER)
    front = jnp.asarray(FRONT)

    def measure(obs):
        dt = jnp.result_type(float)
        q = obs["arm_q"].reshape(4, 3).astype(dt)
        att = kin.attitude_from_quat(obs["quat"].astype(dt))
        tips = kin.arm_tips(kp, q)
        return q, att, tips

    def init(p, obs):
        q, _, tips = measure(obs)
        dt = q.dtype
        flips = jnp.stack([p["front_start"], p["front_start"], 0.0 * p["front_start"], 0.0 * p["front_start"]])
        return {
            "phase": jnp.asarray(WALK, jnp.int32),
            "t_phase": jnp.zeros((), dt),
            "arm_phase": jnp.full((4,), cr.PLACED, jnp.int32),
            "ptr": jnp.zeros((), jnp.int32),  # index into CRAWL_ORDER of the next transfer
            "active": jnp.asarray(-1, jnp.int32),  # the transferring arm, -1 none
            "pause": jnp.zeros((), dt),  # [s] since the last transfer ended
            "contacts": tips,  # (4, 3) contact points in {R}
            "stop_case": jnp.zeros((4,), jnp.int32),
            "on_step": jnp.zeros((4,), bool),
            "confirmed": jnp.asarray(False),
            "h_est": jnp.zeros((), dt),
            "placed_n": jnp.zeros((), jnp.int32),  # transfers done in PREPARE
            "q_cmd": q,
            "q_cmd2": q,
            "lift_to": q[:, 1],  # [rad] the boom angle the current LIFT aims at (A_B)
            "flip": flips.astype(dt),
            "tau_prev": obs["arm_tau"].reshape(4, 3).astype(dt),
            "travel": jnp.zeros((), dt),  # S (Eq. 18) since CLIMB began
            "h0": jnp.zeros((), dt),
            "touched": jnp.asarray(False),  # CLIMB: the front flippers are down on the step
            "front_up": jnp.asarray(False),  # CLIMB: the front crawler ends cleared the step top  # [m] COG height H when CLIMB began
            "stall": jnp.zeros((), dt),
            "climbed": jnp.zeros((), jnp.int32),
            "yaw0": _yaw(obs["quat"].astype(dt)),  # [rad] heading to hold (IMU)
            "flip_case": jnp.zeros((2,), jnp.int32),
            "side_stall": jnp.zeros((2,), dt),  # [s] PREPARE approach: each crawler stalled
            "side_touch": jnp.zeros((2,), dt),  # [s] PREPARE approach: each front flipper pressed
            "blocked": jnp.zeros((2,), bool),  # PREPARE approach: crawler (left, right) at the riser
            "squared": jnp.asarray(False),  # PREPARE: the approach is over (both crawlers at the riser)
            "approached": jnp.zeros((), dt),  # [m] PREPARE approach travel (encoders)
            "crawl": jnp.asarray(RAISE, jnp.int32),  # CRAWL sub-phase
            "crawled_last": jnp.asarray(False),  # the last step was climbed in CRAWL
            "t_crawl": jnp.zeros((), dt),  # [s] time the CRAWL sub-phase began
        }

    def step(p, s, obs):
        q, att, tips = measure(obs)
        dt = q.dtype
        a_p, a_r = att[0], att[1]
        tau = obs["arm_tau"].reshape(4, 3).astype(dt)
        phase = s["phase"]
        walk, prepare, climb, release = (phase == WALK), (phase == PREPARE), (phase == CLIMB), (phase == RELEASE)
        arm_phase = s["arm_phase"]
        v_meas = jnp.mean(obs["track_speed"]).astype(dt)
        travel_step = v_meas * control_dt  # L of Eqs. 22-27, from the crawler encoders

        # ---- terrain estimate from the contact points (stored for the arms in transfer)
        support = arm_phase == cr.PLACED
        contacts = s["contacts"]
        est = kin.explore_terrain(kp, contacts, a_p, a_r)
        t_p = jnp.where(est.case == kin.CASE_FLAT, est.pitch, a_p)

        # ---- crawlers: drive in WALK (unless an arm is idle) and CLIMB
        any_idle = jnp.any(arm_phase == IDLE)
        done = phase == DONE
        crawl = phase == CRAWL
        # PREPARE approach: once the front flippers are up at A0 (clear of the riser), each
        # crawler drives on until the riser blocks its front wheel (its encoder stalls for
        # approach_stall_s); a blocked side stops and the other one drives on alone, so the
        # robot turns about the blocked corner until both fronts are at the riser (square
        # up: the yaw failure, one flipper meeting the riser first, needs the lagging side
        # to catch up, which a heading hold refuses). The climb then starts with the
        # crawler fronts at the riser, so the lifted front flippers reach onto the top.
        # (the encoders too: a flipper still turning up shows a torque like a touch)
        flips_up = jnp.all(s["flip"][:2] >= p["A0"] - 1e-6) & jnp.all(obs["flipper_q"][:2] >= p["A0"] - 0.02)
        # Only on high steps (H_EST > approach_min_h): on 200 / 300 mm steps the first touch
        # stops the robot close enough (the flipper tip meets the riser lower down) and
        # driving on to the riser made the later climb lose its grip (the lifted front
        # flippers then rest flat on the top, lightly loaded): 300 mm 0/8 with, 4/8 without
        use_approach = (p["approach"] > 0) & (s["h_est"] > p["approach_min_h"])
        approaching = prepare & ~s["squared"] & flips_up & use_approach
        side_v = obs["track_speed"].astype(dt)
        side_stall = jnp.where(approaching & (side_v < p["clm_speed"] / 3.0), s["side_stall"] + control_dt, 0.0)
        # the riser met by a side: its raised front flipper's tip (at A0 it is about as far
        # forward as the crawler's front wheel) pressed back (the flipper torque, the
        # paper's touch signal), or its encoder stalled (the tracks slip once the arms carry
        # the body, so the torque comes first on a high step)
        f_press = jnp.abs(obs["flipper_tau"][:2].astype(dt)) > p["approach_tau"]
        side_touch = jnp.where(approaching & f_press, s["side_touch"] + control_dt, 0.0)
        blocked = approaching & (s["blocked"] | (side_stall > p["approach_stall_s"])
                                 | (side_touch > p["approach_touch_s"]))
        approached = jnp.where(approaching, s["approached"] + jnp.mean(side_v) * control_dt, 0.0)
        squared = s["squared"] | (prepare & ~use_approach) | (
            approaching & (jnp.all(blocked) | (approached > p["approach_max"])))
        squared = squared & prepare
        drive = ((walk & ~any_idle) | (climb & s["front_up"]) | done | (approaching & ~squared)
                 | (crawl & (s["crawl"] > RAISE)))
        v_cmd = jnp.where(drive, jnp.where(crawl, p["crawl_speed"], p["clm_speed"]), 0.0)
        v_side = jnp.where(approaching & ~squared & ~blocked, p["clm_speed"], 0.0)

        # ---- support arms: hold the ground contacts while the body moves (Eqs. 22-27)
        moved = jnp.where(drive, travel_step, 0.0)
        contacts_next = jnp.where(support[:, None], cr.predict_contacts(contacts, moved, t_p, a_p), contacts)
        press = jnp.stack([jnp.zeros_like(p["press"]), jnp.zeros_like(p["press"]), p["press"]])
        q_hold, reach = kin.inverse_kinematics_all(kp, contacts_next - press)
        q_hold = jnp.where((reach > 0.005)[:, None], q_hold, s["q_cmd"])  # out of reach: hold

        # ---- the transferring arm (Eqs. 19-21)
        active = s["active"]
        is_active = (jnp.arange(4) == active) & (active >= 0)
        # PREPARE: front arms to their Table 2 targets on the step top (z + H_EST), rear arms
        # to their Table 2 *start* points, farther back: from the Table 2 targets the rear
        # rollers reached the riser before the body had travelled L
        tgt = jnp.where((prepare & ~front)[:, None], jnp.asarray(P.TABLE2_INIT, dt), targets0.astype(dt))
        tgt = tgt.at[:, 2].add(jnp.where(prepare & front, s["h_est"], 0.0))
        clear = jnp.where(front, p["clearance_front"], p["clearance_rear"])
        # the joints aim `transfer_press` below the target, so that the roller meets the
        # ground before the command stops (the servo then lags: contact)
        q_tgt, _ = kin.inverse_kinematics_all(kp, tgt.at[:, 2].add(-p["transfer_press"]))
        q_abv, _ = kin.inverse_kinematics_all(kp, tgt.at[:, 2].add(clear))
        q_tgt, q_abv = jnp.clip(q_tgt, ARM_LO, ARM_HI), jnp.clip(q_abv, ARM_LO, ARM_HI)
        # > 0: the boom is held up, short of the command of two periods ago (the servo
        # follows a free arm's command within a period; the last command may be a step)
        lag = jnp.max(s["q_cmd2"][:, 1:] - q[:, 1:], axis=-1)  # boom or elbow held up
        hit = cr.collision(tau, s["tau_prev"], p["collision_threshold"])
        lower = arm_phase == cr.LOWER
        at_limit = s["q_cmd"][:, 1] >= BOOM_MAX - 1e-6
        contact = lower & (hit | (lag > p["contact_lag"]) | at_limit)
        # A_B: the boom turns up to lift_boom, or by lift_min if it is already higher (a
        # front arm on a high step stands with its boom near vertical: turning it "up" to
        # lift_boom would push the roller into the step)
        lift = jnp.where(arm_phase == cr.LIFT,
                         jnp.maximum(jnp.minimum(jnp.where(front, p["lift_boom_front"], p["lift_boom"]), s["lift_to"]),
                                     ARM_LO[1]), s["lift_to"])
        tr_cmd, tr_next = jax.vmap(
            lambda qq, ph, c, qt, qa, ab: cr.transfer_step(qq, ph, c, qt, qa, ab, p["K"], p["delta_a"], p["delta_b"])
        )(s["q_cmd"], arm_phase, contact, q_tgt, q_abv, lift)
        # past the target's angles the descent goes on by Delta_B per period until contact
        # (transfer_step returns to the target angles once the command overshot them)
        creeping = lower & (jnp.abs(s["q_cmd"][:, 2] - q_tgt[:, 2]) < 1e-6) & (s["q_cmd"][:, 1] >= q_tgt[:, 1] - 1e-6)
        tr_cmd = jnp.where(creeping[:, None], s["q_cmd"].at[:, 1].add(p["delta_b"]), tr_cmd)
        tr_cmd = tr_cmd.at[:, 1].set(jnp.minimum(tr_cmd[:, 1], BOOM_MAX))
        transferring = is_active & (arm_phase <= cr.LOWER)
        just_placed = transferring & (tr_next == cr.PLACED)
        # a placed arm: its contact is where the encoders put the EPRA
        stop = cr.arm_stop_case(tips, tgt, p["delta_c"], p["delta_d"])
        contacts_next = jnp.where(just_placed[:, None], tips, contacts_next)
        stop_case = jnp.where(just_placed, stop, s["stop_case"])
        on_step = jnp.where(just_placed, front & (stop == cr.STOP_ON_OBSTACLE), s["on_step"])
        arm_phase_n = jnp.where(transferring, tr_next, arm_phase)

        # ---- gait sequencing: the next transfer after a pause
        ended = jnp.any(just_placed)
        pause = jnp.where(ended | (active >= 0), 0.0, s["pause"] + control_dt)
        active_n = jnp.where(ended, -1, active)
        placed_n = s["placed_n"] + jnp.where(ended & prepare, 1, 0)
        ptr = jnp.where(ended, (s["ptr"] + 1) % 4, s["ptr"])
        # step detection: one front arm on the step -> the other front arm goes next
        one_front = jnp.any(on_step & front) & ~jnp.all(on_step[:2])
        other = jnp.where(on_step[0], 1, 0)
        other_ptr = jnp.argmax(order == other).astype(jnp.int32)
        ptr = jnp.where(walk & one_front & ended, other_ptr, ptr)
        est_n = kin.explore_terrain(kp, contacts_next, a_p, a_r)
        confirm_now = walk & ~s["confirmed"] & jnp.all(on_step[:2]) & (est_n.step_height > p["sigma1"])
        confirmed = s["confirmed"] | confirm_now
        h_est = jnp.where(confirm_now, est_n.step_height, s["h_est"])
        want_next = (walk & ~confirmed) | (prepare & squared & (placed_n < N_PREPARE))
        start = want_next & (active_n < 0) & (pause >= p["gait_pause"]) & ~ended
        nxt_arm = jnp.where(prepare, jnp.asarray(PREPARE_ORDER)[jnp.minimum(placed_n, N_PREPARE - 1)], order[ptr])
        active_n = jnp.where(start, nxt_arm, active_n)
        starting = start & (jnp.arange(4) == nxt_arm)
        arm_phase_n = jnp.where(starting, cr.LIFT, arm_phase_n)
        lift_to = jnp.where(starting, s["q_cmd"][:, 1] - p["lift_min"], lift)

        # ---- front flippers: the torque rule in WALK
        flip = s["flip"]
        f_rule, f_case = cr.flipper_rule(flip[:2], obs["flipper_tau"][:2].astype(dt), p["T0"], p["flip_delta_a"],
                                         p["A0"], p["flip_delta_b"])
        f_rule = jnp.clip(f_rule, -FLIPPER_MAX, FLIPPER_MAX)
        # the riser touched: a front flipper has yielded (Case 2) by touch_rise above its
        # walking angle (a single Case 2 period also comes from the arm transfers' jolts)
        touched_riser = jnp.any(f_rule > p["front_start"] + p["touch_rise"])
        at_a0 = jnp.any(f_case == cr.FLIPPER_LIMIT) | ((p["stop_on_touch"] > 0) & touched_riser)
        # crawlers stalled: at the riser (WALK, step confirmed), or blocked by the next riser
        # while driving on with the arms carried (DONE, CRAWL)
        stall = jnp.where(((walk & confirmed) | done | (crawl & (s["crawl"] > RAISE))) & (v_meas < p["clm_speed"] / 3.0), s["stall"] + control_dt, 0.0)
        to_prepare = walk & confirmed & (at_a0 | (stall > p["stall_s"])) & (active_n < 0)
        low_step = h_est <= p["crawl_max_h"]

        # ---- climbing and release (Eqs. 28-29): booms and flippers
        h = kin.cog_height(kp, tips, a_p, a_r)
        travel = kin.travel_update(s["travel"], travel_step, a_p)
        rise = h - s["h0"]
        # the release waits for the body to be back near level (see module docstring)
        s_eff = jnp.where((a_p < p["release_pitch"]) & s["touched"], travel, -1.0)
        _, flip_c, on_top = cr.climb_rule(s["q_cmd"][:, 1], flip, rise, s["h_est"], s_eff,
                                               p["settle_distance"], p["delta_e"], p["delta_f"])
        # Eq. 28 per arm, a level lift: the arms push the body up while the front crawler
        # ends are below the step top (estimated from the front EPRAs resting on it:
        # "H < H_EST"); front and rear (left and right) arms take turns so that the body
        # stays within level_band of level; once lifted they only keep it level. (Lifting
        # the nose alone rolls the robot backwards over its rear flipper tips.)
        axles_c = kin.to_level_frame(jnp.asarray(FRONT_AXLES, dt), a_p, a_r)
        front_c = kin.to_level_frame(tips[:2], a_p, a_r)
        clear = jnp.min(axles_c[:, 2] - P.MAIN_WHEEL_RADIUS - (front_c[:, 2] - P.ROLLER_RADIUS))
        front_low = clear < p["front_clearance"]
        # the crawlers drive in CLIMB once the front is above the step top (driving while
        # the arms lift pushes the nose into the riser and twists the robot)
        front_up = climb & (s["front_up"] | ~front_low)
        band = p["level_band"]
        push = jnp.where(front, (front_low & (a_p < band)) | (a_p < -band),
                         (front_low & (a_p > -band)) | (a_p > band))
        push = push & jnp.where(LEFT, a_r > -band, a_r < band)
        # Eq. 28, read in the task space: a boom turning down by Delta_E lowers its EPRA by
        # about Delta_E l1; we lower the EPRAs of the pushing arms by Delta_E l1 along the
        # world vertical (inverse kinematics, elbow included), so that the arms lift the
        # body instead of pushing it backwards when it is pitched
        dz = p["delta_e"] * P.L1
        tips_cmd = kin.arm_tips(kp, s["q_cmd"])
        q_climb = _tips_moved(s["q_cmd"], push & ~on_top, -dz, a_p, a_r)
        # the front flippers stay raised until the front is above the step top (they
        # would jam against the riser), then turn down onto it (to flip_min); the rear
        # ones (to rear_flip_min) too, or at once with rear_flip_late = 0: turning down with
        # their tips on the ground they lifted the tail but pushed the robot (on the arms'
        # free rollers) about 7 cm back from the riser, out of the lifted flippers' reach
        flip_c = jnp.where((FRONT4 | (p["rear_flip_late"] > 0)) & front_low & ~on_top, flip, flip_c)
        flip_c = jnp.clip(flip_c, jnp.where(FRONT4, p["flip_min"], p["rear_flip_min"]), FLIPPER_MAX)
        # release (Eqs. 28-29, second branches): every EPRA rises by Delta_E l1 per period
        # (the body goes down evenly onto the crawlers) until it is back at the Table 2
        # height in {R} ("theta_2' > 0" of the authors' joint zero); the flippers turn up
        # to 0
        high = tips_cmd[:, 2] >= TABLE2_Z - 1e-3
        q_release = _tips_moved(s["q_cmd"], ~high, dz, a_p, a_r)
        flip_r = jnp.where(flip < 0, jnp.minimum(flip + p["delta_f"], 0.0), flip)
        released = release & jnp.all(high) & jnp.all(flip >= 0.0)

        # ---- CRAWL: a low step climbed by the crawlers and flippers, arms carried
        flip_cr, crawl_n, t_crawl, crawled = _crawl_step(p, s, flip, a_p, obs["time"], stall > p["stall_s"],
                                                                         control_dt)
        crawl_n = jnp.where(crawl, crawl_n, RAISE)
        crawled = crawl & crawled

        # ---- arm commands
        # the PREPARE approach holds the arm commands: the passive rollers roll along with
        # the body. Holding the contacts by the encoder travel (Eqs. 22-27) there loaded
        # the arms more as the tracks slipped at the riser, until the tracks were off the
        # ground and the robot stood still on its arms. (The same in WALK once the step is
        # confirmed made the later climbs less reliable: 2/8 instead of 6/8 at 400 mm.)
        hold = support & ~(approaching & ~squared)
        q_walk = jnp.where(transferring[:, None], tr_cmd, jnp.where(hold[:, None], q_hold, s["q_cmd"]))
        # DONE: the arms go to the carrying pose (booms up first, then the elbows), clear of
        # the terrain, while the robot drives on
        carry = jnp.stack([s["q_cmd"][:, 0], jnp.full(4, p["lift_boom_front"]), jnp.full(4, p["carry_elbow"])], axis=1)
        booms_up = jnp.all(s["q_cmd"][:, 1] <= p["lift_boom_front"] + 1e-3)
        step_max = jnp.where(jnp.arange(3) == 2, jnp.where(booms_up, p["delta_b"], 0.0), p["delta_b"])
        q_done = s["q_cmd"] + jnp.clip(carry - s["q_cmd"], -step_max, step_max)
        q_cmd = jnp.select([climb, release, done | crawl], [q_climb, q_release, q_done], q_walk)
        q_cmd = jnp.clip(q_cmd, ARM_LO, ARM_HI)
        # ---- flipper commands
        flip_walk = jnp.concatenate([f_rule, jnp.zeros(2, dt)])
        # PREPARE: the front flippers go up to A0 (Fig. 9d)
        flip_prep = flip.at[:2].set(jnp.minimum(flip[:2] + p["flip_delta_a"], p["A0"]))
        flip_walk = jnp.where(walk, flip_walk, jnp.where(prepare, flip_prep, flip))
        flip_n = jnp.select([climb, release, done, crawl], [flip_c, flip_r, jnp.zeros(4, dt), flip_cr], flip_walk)

        # ---- phase transitions
        to_climb = prepare & (placed_n >= N_PREPARE) & (active_n < 0)
        # the release also waits for the body to have tipped over the edge onto the top
        # (IMU pitch back below release_pitch): S from the crawler encoders runs ahead of
        # the body when the tracks slip on the edge
        to_release = climb & on_top & (a_p < p["release_pitch"])
        # DONE -> WALK once the robot has driven done_distance on the top (arms carried):
        # the arms are placed again one at a time (crawlers waiting), for the next terrace
        # ... but blocked again right after a CRAWL climb: the next low terrace of a
        # staircase, climbed the same way (groping it with the arms while pitched on the
        # last edge tipped the robot over)
        recrawl = done & s["crawled_last"] & (stall > p["stall_s"])
        rewalk = done & ~recrawl & ((s["travel"] > p["done_distance"]) | (stall > p["stall_s"]))
        finished = released | crawled
        nxt = jnp.select([to_prepare & low_step, to_prepare, to_climb, to_release, finished, recrawl, rewalk],
                         [CRAWL, PREPARE, CLIMB, RELEASE, DONE, CRAWL, WALK],
                         phase)
        changed = nxt != phase
        # entering PREPARE: restart the gait at RR; entering WALK after a release: every
        # arm idle, to be placed again (rear arms first)
        ptr = jnp.where(changed & ((nxt == PREPARE) | (nxt == WALK)), 0, ptr)
        placed_n = jnp.where(changed, 0, placed_n)
        arm_phase_n = jnp.where(finished | (changed & (nxt == CRAWL)), IDLE, arm_phase_n)
        on_step = jnp.where(finished, False, on_step)
        confirmed = jnp.where(finished, False, confirmed)
        active_n = jnp.where(finished, -1, active_n)
        pause = jnp.where(changed, 0.0, pause)
        # S (Eq. 18, Fig. 5: the front flipper pivots past the obstacle edge) starts when the
        # lifted front flippers touch down on the step top (flipper torque beyond T0): the
        # edge is then just behind their tips, S = -(flipper length x cos A)
        touch_now = climb & ~s["touched"] & ~front_low & jnp.any(jnp.abs(obs["flipper_tau"][:2]) > p["T0"])
        reach0 = P.FLIPPER_LENGTH * jnp.mean(jnp.cos(obs["flipper_q"][:2].astype(dt)))
        touched = (s["touched"] | touch_now) & (nxt == CLIMB)
        travel = jnp.where(touch_now, -reach0, jnp.where((climb & s["touched"]) | (done & ~rewalk), travel, 0.0))
        h0 = jnp.where(changed & (nxt == CLIMB), h, s["h0"])
        # after an IDLE arm is placed it is in support; contacts of idle arms follow the EPRA
        # ... and so do those of the arms rolling along in the PREPARE approach
        rolling = (support & ~hold)[:, None]
        contacts_next = jnp.where((arm_phase_n == IDLE)[:, None] | (climb | release) | rolling, tips, contacts_next)

        # heading hold while driving (an addition: the paper assumes the yaw does not change,
        # ours does when one front flipper meets the riser first); heading_gain = 0 is the
        # paper's controller
        dyaw = _wrap(_yaw(obs["quat"].astype(dt)) - s["yaw0"])
        steer = jnp.where(drive & ~prepare, jnp.clip(p["heading_gain"] * dyaw, -p["clm_speed"], p["clm_speed"]), 0.0)
        tracks = jnp.where(prepare, v_side, jnp.stack([v_cmd + steer, v_cmd - steer]))
        # squared up at the riser: the heading to hold from now on is the riser's normal
        yaw0 = jnp.where(squared & ~s["squared"], _yaw(obs["quat"].astype(dt)), s["yaw0"])
        action = jnp.concatenate([tracks.astype(dt), flip_n, q_cmd.reshape(-1)])
        new = {
            "phase": nxt.astype(jnp.int32),
            "t_phase": jnp.where(changed, obs["time"], s["t_phase"]).astype(dt),
            "arm_phase": arm_phase_n.astype(jnp.int32),
            "ptr": ptr.astype(jnp.int32),
            "active": active_n.astype(jnp.int32),
            "pause": pause.astype(dt),
            "contacts": contacts_next,
            "stop_case": stop_case.astype(jnp.int32),
            "on_step": on_step,
            "confirmed": confirmed,
            "h_est": h_est.astype(dt),
            "placed_n": placed_n.astype(jnp.int32),
            "q_cmd": q_cmd,
            "q_cmd2": s["q_cmd"],
            "lift_to": lift_to.astype(dt),
            "flip": flip_n,
            "tau_prev": tau,
            "travel": travel.astype(dt),
            "h0": h0.astype(dt),
            "touched": touched,
            "front_up": front_up,
            "stall": stall.astype(dt),
            "climbed": s["climbed"] + jnp.where(finished, 1, 0).astype(jnp.int32),
            "yaw0": yaw0.astype(dt),
            "flip_case": f_case.astype(jnp.int32),
            "side_stall": side_stall.astype(dt),
            "side_touch": side_touch.astype(dt),
            "blocked": blocked,
            "squared": squared,
            "approached": approached.astype(dt),
            "crawl": crawl_n.astype(jnp.int32),
            "crawled_last": jnp.where(finished, crawled, s["crawled_last"]),
            "t_crawl": jnp.where(changed & (nxt == CRAWL), obs["time"], t_crawl).astype(dt),
        }
        return new, action

    return Controller(init, step, name="clm")
