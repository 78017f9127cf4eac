"""The crawler-crawling mode (CCM) baseline of the OCTOPUS paper ("Locomotion modes", Fig. 2a,
and the one-terrace step experiment, Fig. 11b): crawlers and flippers only, the arms held
lifted clear of the ground. The paper's CCM was driven by two skilled operators (and failed
the 400 mm step every time); this is an automatic flipper policy in pure JAX instead, a
small state machine on the IMU pitch, the front flipper torques and time (fixed shapes,
transitions by masks, one simulation; the rollout vmaps it).

Policy (angles [rad], flipper angle > 0 lifts the tip, see `model.py`; pitch > 0 nose up):
  0 APPROACH: both crawlers at `speed`; front flippers raised to `front_up` (the paper's
    front flippers "keep a suitable angle with ground to obtain the object information in
    front of the robot"), rear flippers at 0. The front flipper torque is low-pass
    filtered; after `settle_s` its deviation from the value at `settle_s` is watched:
    contact with an obstacle changes it ("Crawler control", Case 2: torque change beyond
    T_0). Obstacle detected when |deviation| > `torque_trigger` [N m] or the pitch exceeds
    `pitch_trigger`.
  1 LOWER: the front flippers rotate down towards `front_down` at `lower_rate` [rad/s]
    (Case 2/3 adjustment by Delta_A per period), pressing the tracks onto the edge so that
    they pull the nose up; crawlers keep driving.
  2 PUSH: once the pitch exceeds `pitch_push`, the rear flippers rotate down to
    `rear_push` at `lower_rate` to lift the tail and move the COG forward over the edge.
  3 LEVEL: once the pitch has fallen back below `pitch_level` after PUSH (the chassis has
    tipped over the edge onto the top), the rear flippers keep pushing for 2 s, then all
    flippers go back to 0 and the robot drives on; after `level_s` it starts a new
    APPROACH (front flippers raised again, new torque baseline) for the next terrace.
  4 RAISE (trying harder, as the paper's operators did on the 400 mm step, where the
    flipper tips stay below the edge): when LOWER has not pitched the robot beyond
    `pitch_trigger` within `hook_s`, the front flippers turn up to their 85 deg limit
    while the crawlers keep driving them against the riser, so that the front climbs the
    riser face; once the pitch passes `pitch_hook` the flippers go down again (LOWER) to
    hook over the edge, and PUSH follows as on a low step. On 400 mm the front does not
    climb the face (the tracks slip against the riser, the pitch stays below 0.1 rad):
    the robot never reaches the top (paper: 0 %).
The arm joints are held at `ARMS_STOWED`, as in the paper's CCM run: front arms in the
zero pose (stretched forward, level, rollers 433 mm above the floor), rear arms lifted
(boom raised 0.6 rad, pointing forward), clear of the ground while on flat floor. On a
step higher than ~430 mm, or pitched nose-down, the front rollers can touch the terrain.

Controller parameters (keys of the params dict, defaults in `PARAM_DEFAULTS`): speed,
front_up, front_down, rear_push, lower_rate, settle_s, torque_trigger, pitch_trigger,
pitch_push, pitch_level, level_s, hook_s, pitch_hook (every value default (ours): the
paper's CCM was two operators' joysticks). The observation is the one built by
`jaxloco.robots.octopus.scenarios` ("time", "quat", "flipper_q", "flipper_tau").
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco.robots.octopus import params
from jaxloco.sim.scenario import Controller

APPROACH, LOWER, PUSH, LEVEL, RAISE = 0, 1, 2, 3, 4
PHASE_NAMES = ("approach", "lower", "push", "level", "raise")
CONTROL_DT = 0.02  # [s] 50 Hz, the paper's sampling frequency (scenarios use it)
TORQUE_TAU = 0.2  # [s] time constant of the flipper torque low-pass filter

# Arm joint targets (4 arms x swing, boom, elbow) [rad]: boom < 0 raises the arm.
ARMS_STOWED = np.array([
    [0.0, 0.0, 0.0],
    [0.0, 0.0, 0.0],
    [0.0, -0.6, 0.0],
    [0.0, -0.6, 0.0],
])

PARAM_DEFAULTS: dict[str, float] = {
    "speed": params.PARAMETERS.default("speed"),  # [m/s] commanded track speed (CRAWLER_MAX_SPEED)
    "front_up": 1.2,  # [rad] front flipper angle while approaching
    "front_down": 0.0,  # [rad] front flipper target once on the edge
    "rear_push": -0.6,  # [rad] rear flipper target while pushing
    "lower_rate": 0.3,  # [rad/s] flipper rate when lowering / pushing
    "settle_s": 1.5,  # [s] before the torque baseline is taken
    "torque_trigger": 15.0,  # [N m] front flipper torque change that means contact
    "pitch_trigger": 0.1,  # [rad] or a nose-up pitch beyond this
    "pitch_push": 0.35,  # [rad] pitch that starts the rear flipper push
    "pitch_level": 0.05,  # [rad] pitch below which (after PUSH) the robot is on top
    "level_s": 3.0,  # [s] in LEVEL before approaching the next terrace
    "hook_s": 3.0,  # [s] LOWER without pitching this long: the flipper tips are below the edge -> RAISE
    "pitch_hook": 0.3,  # [rad] RAISE until the front has climbed the riser face this far, then LOWER
}



def pitch_of(quat):
    """Nose-up pitch [rad] of the IMU quaternion (w, x, y, z) (z-up, x forward:
    minus the usual y rotation)."""
    w, x, y, z = quat[0], quat[1], quat[2], quat[3]
    return -jnp.arcsin(jnp.clip(2.0 * (w * y - z * x), -1.0, 1.0))


def _approach(current, target, rate, dt):
    return current + jnp.clip(target - current, -rate * dt, rate * dt)


class CcmState(NamedTuple):
    """The CCM policy's state."""

    phase: jax.Array  # () int32, index into PHASE_NAMES
    tau_f: jax.Array  # () low-passed mean front flipper torque [N m]
    tau0: jax.Array  # () its baseline, taken while settling [N m]
    flip: jax.Array  # (4,) flipper commands [rad]
    t_phase: jax.Array  # () time the phase began [s]


def make_controller(control_dt: float = CONTROL_DT) -> Controller:
    arms = jnp.asarray(ARMS_STOWED.reshape(-1))

    def init(p, obs):
        tau = jnp.mean(obs["flipper_tau"][:2])
        flip = jnp.stack([p["front_up"], p["front_up"], 0.0 * p["front_up"], 0.0 * p["front_up"]])
        return CcmState(jnp.asarray(APPROACH, jnp.int32), tau, tau, flip.astype(jnp.result_type(float)), jnp.zeros(()))

    def step(p, s, obs):
        t = obs["time"]
        pitch = pitch_of(obs["quat"])
        tau_front = jnp.mean(obs["flipper_tau"][:2])
        alpha = control_dt / (TORQUE_TAU + control_dt)
        tau_f = s.tau_f + alpha * (tau_front - s.tau_f)
        settling = (s.phase == APPROACH) & (t - s.t_phase < p["settle_s"])
        tau0 = jnp.where(settling, tau_f, s.tau0)
        phase = s.phase
        hit = ~settling & ((jnp.abs(tau_f - tau0) > p["torque_trigger"]) | (pitch > p["pitch_trigger"]))
        nxt = jnp.where((phase == APPROACH) & hit, LOWER, phase)
        nxt = jnp.where((nxt == LOWER) & (pitch > p["pitch_push"]), PUSH, nxt)
        nxt = jnp.where((nxt == PUSH) & (pitch < p["pitch_level"]), LEVEL, nxt)
        nxt = jnp.where((phase == LEVEL) & (t - s.t_phase > p["level_s"]), APPROACH, nxt)
        below_edge = (phase == LOWER) & (t - s.t_phase > p["hook_s"]) & (pitch < p["pitch_trigger"])
        nxt = jnp.where(below_edge, RAISE, nxt)
        nxt = jnp.where((phase == RAISE) & (pitch > p["pitch_hook"]), LOWER, nxt)
        # flipper targets per phase (front l, front r, rear l, rear r)
        front = jnp.where(phase == APPROACH, p["front_up"], jnp.where(phase == LEVEL, 0.0, p["front_down"]))
        front = jnp.where(phase == RAISE, params.FLIPPER_LIMIT, front)
        rear = jnp.where((phase == PUSH) | ((phase == LEVEL) & (t - s.t_phase < 2.0)), p["rear_push"], 0.0)
        target = jnp.stack([front, front, rear, rear])
        flip = _approach(s.flip, target, p["lower_rate"], control_dt)
        flip = jnp.where(phase == APPROACH, target, flip)
        speed = p["speed"]
        action = jnp.concatenate([jnp.stack([speed, speed]), flip, arms.astype(flip.dtype)])
        t_phase = jnp.where(nxt != phase, t, s.t_phase)
        new = CcmState(nxt.astype(jnp.int32), tau_f, tau0, flip, t_phase)
        return new, action

    return Controller(init, step, name="ccm")


def arm_pose() -> np.ndarray:
    """The stowed arm joint angles (4, 3) [rad]."""
    return ARMS_STOWED.copy()


