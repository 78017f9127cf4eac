"""T² Snake-3's application experiments (Sec. V-D) in MuJoCo, driven by a scripted
operator: picking up a T-joint pipe (Fig. 13). (Rotating a valve and opening a door
with a knob, Fig. 14, are not built yet.)

The operator (the paper's joystick commands as a time series): `kinsim.Target` with a
script of smooth steps of the gripper tip's pose and the SCP psi_3 (the controlled
variable w~ = [w, psi_3], Sec. IV-C3), fed to the paper's feedforward task-space control
of the tip (`sim_control.task_space_controller`, fixing state sigma = 1).

The Omni-gripper (Sec. IV-B: soft, then hardened by vacuum around what it touches):
the gripper capsule on the head with a MuJoCo adhesion actuator on the head link,
GRIP_FORCE [N] at ctrl 1 (ours): off while the gripper is pressed onto the object
("soft"), on from `grip_at` (the pump's command: "hardened").

Picking up the pipe (`PICK_SCRIPT`): from the Sec. V-A posture the tip goes down to the
pipe lying across its path on the ground with psi_3 lowered by 0.9 rad (with psi_3
at its 110 deg SCP target the head part cannot reach the floor: psi_2 hits its
limit; lowered by 1.2 rad the head part, stretched out, could not lift the pipe on
its servos), the gripper hardens, and the tip lifts by 0.1 m. The pipe (a T of two
capsules, PIPE_MASS, ours) is placed under the gripper's middle. Measured (`run_pick`):
the pipe comes up 5.4 cm; the tip ends 3.8 cm below the script (the paper's
feedforward control: the head part sags under the lifted pose; the paper's operator
corrects such errors by joystick, Sec. V-A), against the issue's 30 mm.
"""

from __future__ import annotations

import functools
from typing import Any

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from jaxloco.robots.snake import kinematics as K
from jaxloco.robots.snake import params as P
from jaxloco.robots.snake import scenarios as SC
from jaxloco.robots.snake import sim_control as SCt
from jaxloco.sim.rollout import RolloutResult, rollout
from jaxloco.sim.scenario import Scenario

CONTROL_DT = 0.02  # [s]
GRIP_FORCE = 20.0  # [N] adhesion of the hardened gripper, ours
GRIP_REACH = 0.01  # [m] the hardened gripper holds what is within this of its surface (geom margin = gap), ours
PIPE_RADIUS = 0.02  # [m], ours
PIPE_HALF_LENGTH = (0.08, 0.03)  # [m] the main tube (across, along y) and the branch (along +x), ours
PIPE_MASS = 0.2  # [kg], ours
# the operator's script (ours): (start [s], duration [s], change of w~ = [x, y, z, roll, pitch, yaw, psi_3])
PICK_SCRIPT = (
    (1.0, 5.0, (0.0, 0.0, -0.28, 0.0, 0.0, 0.0, -0.9)),  # reach down to the pipe, psi_3 lowered by 0.9 rad
    (7.5, 3.0, (0.0, 0.0, 0.10, 0.0, 0.0, 0.0, 0.0)),  # lift
)
PICK_GRIP_AT = 6.5  # [s] the gripper hardens (after the reach, before the lift)
PICK_HORIZON = 12.0  # [s]
GRIPPER_MID = P.GRIPPER_TIP - 0.5 * P.GRIPPER_LENGTH  # [m] the gripper's centre ahead of the head frame


def initial_tip() -> np.ndarray:
    """The gripper tip's pose (6,) in the Sec. V-A posture, base at the origin [m, rad]."""
    with jax.enable_x64(True):
        return np.asarray(K.tip_from_head(K.base_frame_pose(jnp.zeros(3), jnp.asarray(P.INITIAL_PHI))))


def _add_pipe_and_gripper(spec: mujoco.MjSpec) -> None:
    tip = initial_tip()
    centre = [float(tip[0] - P.GRIPPER_TIP + GRIPPER_MID), 0.0, PIPE_RADIUS]
    pipe = spec.worldbody.add_body(name="pipe", pos=centre)
    pipe.add_freejoint(name="pipe")
    both = {"contype": 3, "conaffinity": 3, "condim": 3, "friction": [1.0, 0.005, 0.0001]}
    main, branch = PIPE_HALF_LENGTH
    pipe.add_geom(name="pipe_main", type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[PIPE_RADIUS, main, 0],
                  quat=[0.7071068, 0.7071068, 0, 0], mass=0.7 * PIPE_MASS, rgba=[0.7, 0.7, 0.75, 1], **both)
    pipe.add_geom(name="pipe_branch", type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[PIPE_RADIUS, branch, 0],
                  pos=[branch, 0, 0], quat=[0.7071068, 0, 0.7071068, 0], mass=0.3 * PIPE_MASS,
                  rgba=[0.7, 0.7, 0.75, 1], **both)
    pipe.add_site(name="pipe")
    spec.add_sensor(name="pipe_pos", type=mujoco.mjtSensor.mjSENS_FRAMEPOS, objtype=mujoco.mjtObj.mjOBJ_SITE,
                    objname="pipe")
    for geom in spec.geoms:  # contacts within GRIP_REACH of the gripper are seen (adhesion pulls across it)
        if geom.name == "gripper":
            geom.margin, geom.gap = GRIP_REACH, GRIP_REACH
    grip = spec.add_actuator(name="gripper", target="link1", trntype=mujoco.mjtTrn.mjTRN_BODY)
    grip.set_to_adhesion(gain=GRIP_FORCE)
    grip.ctrlrange = [0.0, 1.0]


def _grip(p: Any, t: Any) -> Any:
    return jnp.atleast_1d(jnp.where(t >= p["grip_at"], 1.0, 0.0))


def _no_mocap(p: Any, dtype: Any) -> tuple[Any, Any]:
    return jnp.zeros((0, 3), dtype), jnp.zeros((0, 4), dtype)


PIPE = SC.Fixture(add=_add_pipe_and_gripper, bodies=(), pose=_no_mocap, sensors=("pipe_pos",),
                  actuators=("gripper",), ctrl=_grip)


@functools.lru_cache(maxsize=2)
def pick_scenario(horizon: float = PICK_HORIZON) -> Scenario:
    """The flat-ground snake scenario with the pipe and the gripper, the tip under the
    paper's feedforward task-space control."""
    return SC.snake_scenario(horizon, CONTROL_DT, SCt.task_space_controller(CONTROL_DT, "tip", False), fixture=PIPE)


def script_params(script=PICK_SCRIPT, grip_at: float = PICK_GRIP_AT, n: int = 1, **overrides) -> dict[str, Any]:
    """Simulation params of n runs of an operator's script (module docstring)."""
    params = SCt.params_batch(n, **overrides)
    params["script_t0"] = np.tile([s[0] for s in script], (n, 1))
    params["script_duration"] = np.tile([s[1] for s in script], (n, 1))
    params["script_delta"] = np.tile(np.array([s[2] for s in script], float), (n, 1, 1))
    params["grip_at"] = np.full(n, grip_at)
    return params


def script_target(t: np.ndarray, w0: np.ndarray, script=PICK_SCRIPT) -> np.ndarray:
    """The tip pose the script asks for at times t (n,) from its start pose w0 (6,)."""
    out = np.tile(np.asarray(w0, float)[:6], (len(t), 1))
    for t0, dur, delta in script:
        tau = np.clip((np.asarray(t) - t0) / dur, 0.0, 1.0)
        out += np.outer(tau - np.sin(2 * np.pi * tau) / (2 * np.pi), np.asarray(delta, float)[:6])
    return out


def run_pick(n: int = 1, grip_at: float = PICK_GRIP_AT, **overrides) -> tuple[RolloutResult, dict[str, np.ndarray]]:
    """The pick-up, n runs: the rollout and (pipe_lift [m]: the pipe's height gained at
    the end, max_tip_error [m]: the largest distance of the measured tip from the
    script's (both from t = 0, the tip measured then as the script's start))."""
    res = rollout(pick_scenario(), script_params(grip_at=grip_at, n=n, **overrides), backend="native")
    pipe = np.asarray(res.records["fixture"])  # (n, T, 3)
    tip = np.asarray(res.records["tip"])
    want = np.stack([script_target(res.times, tip[i, 0]) for i in range(n)])
    err = np.linalg.norm(tip[..., :3] - want[..., :3], axis=-1)
    return res, {"pipe_lift": pipe[:, -1, 2] - pipe[:, 0, 2], "max_tip_error": err.max(-1),
                 "final_tip_error": err[:, -1]}
