"""T² Snake-3's application experiments (Sec. V-D) in MuJoCo, driven by a scripted
operator: picking up a T-joint pipe (Fig. 13), rotating a gate valve, and opening a door
with a knob (Fig. 14), where a base yaw joint reaches its limit and mode switching frees
it.

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
capsules, PIPE_MASS, ours) is placed under the gripper's middle.

Rotating the valve (`VALVE_SCRIPT`): a handwheel (VALVE_HALF, on a hinge along the
tip's axis, stem friction VALVE_FRICTION, all ours) 1 cm ahead of the tip; the soft
gripper is pushed 2 cm towards it ("so that the center of the gripper aligned with the
center of the valve"), hardens, and the tip rolls by 90 deg (the paper turns the joint
at the gripper's base; our gripper joints are fixed, so the head rolls, Table III's
alpha motion). The membrane's wrap is the contact's torsional friction (VALVE_TORSION,
ours).

Opening the door (`door_script`): the tip holds the knob of a door (hinge 0.35 m to its
right, opening towards the robot only, ours) and pulls it along the arc it would follow
held rigidly to the door, in four 3 s steps to 1.2 rad, yawing with the door (Sec. V-D
3). The robot stands turned DOOR_APPROACH off the door's normal (`door_start`) so that
it backs away along its own heading as the door opens (the paper's robot moves
backward; square to the door the arc pulls the base sideways, which no wheel can, and
the head part folds into a singular pose: docs/snake.md). A base yaw joint reaches
its limit at about 7.5 s (Fig. 14 d); the teleoperator model (`operator`,
`operator_enter` < 1) then pauses the script and commands the switching state (Fig. 14
e) until the base joints are free, and again at the next stall (f, g). The controller
runs with OPERATION_GAINS (below).

The measured results (5 perturbed trials each, `operations_analysis`, `jaxloco sweep
snake_operations`) are in docs/snake.md.

On MJX (`operation_scenario(..., backend="mjx")`: the model's MJX variant,
`scenarios.mjx_variant`, and each fixture's `mjx`): MJX has no adhesion actuator (a body
transmission), so the hardened gripper is a tendon from the gripper's centre to the
object (the pipe's centre, the handwheel's hub, the knob's centre) pulled with
GRIP_FORCE at ctrl 1 while the object is within about GRIP_REACH of the gripper along it
(`_mjx_grip`). Adhesion pulls at each contact within GRIP_REACH, along its normal,
shared among them; the tendon pulls at one point of the object along the line to the
gripper's centre. The gripper's margin (the contacts are active GRIP_REACH out, in
MuJoCo 4 and MJX alike: the held object rests about 9 mm off the capsule) is kept.
docs/simulation.md gives the differences.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from jaxloco.robots.snake import kinematics, predictive, scenarios, sim_control
from jaxloco.robots.snake import params as snake_params
from jaxloco.sim.rollout import RolloutResult, rollout
from jaxloco.sim.scenario import Scenario

CONTROL_DT = 0.02  # [s]
GRIP_FORCE = 20.0  # [N] adhesion of the hardened gripper, ours
GRIP_REACH = 0.01  # [m] the hardened gripper holds what is within this of its surface (geom margin = gap), ours
GRIP_RELEASE = 0.002  # [m] on MJX (`_mjx_grip`), beyond GRIP_REACH the pull fades to 0 over this, ours
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
GRIPPER_MID = (
    snake_params.GRIPPER_TIP - 0.5 * snake_params.GRIPPER_LENGTH
)  # [m] the gripper's centre ahead of the head frame
OBJECT = {"contype": 3, "conaffinity": 3, "condim": 3, "friction": [1.0, 0.005, 0.0001]}  # touches robot and floor
STEEL = [0.7, 0.7, 0.75, 1]
# the gate valve (ours): handwheel half sizes (radius, half thickness) [m], its gap ahead of the tip [m], the
# stem's friction [N m], the torsional friction of the handwheel's face [m] (what the wrapped membrane holds)
VALVE_HALF = (0.05, 0.008)
VALVE_GAP = 0.01
VALVE_FRICTION = 0.05
VALVE_TORSION = 0.03
VALVE_SCRIPT = (
    (1.0, 2.0, (0.02, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)),  # push the soft gripper onto the handwheel
    (4.0, 4.0, (0.0, 0.0, 0.0, math.pi / 2, 0.0, 0.0, 0.0)),  # roll the gripper by 90 deg
)
VALVE_GRIP_AT = 3.5  # [s]
# the door (ours): knob radius, hinge to knob [m], panel half sizes (thickness, width, height) [m], the angles
# the operator pulls it open to [rad]
KNOB_RADIUS = 0.02
DOOR_RADIUS = 0.35
DOOR_HALF = (0.01, 0.25, 0.3)
DOOR_ANGLES = (0.3, 0.6, 0.9, 1.2)
DOOR_GRIP_AT = 1.5  # [s]
DOOR_TIP_BEHIND = 2 * KNOB_RADIUS + 0.002 + DOOR_HALF[0]  # [m] the gripper tip's distance in front of the hinge line
# [m] the tip's horizontal distance ahead of link 7's psi_3 axle in the Sec. V-A posture
TIP_AHEAD = 0.349  # (`initial_tip()[0]`: link 7 at the origin)
# [rad] how the robot stands at the door (default (ours): the paper gives no layout; its robot "could not move
# backward" and "resume[d] moving backward", Sec. V-D 3): link 7 turned this far to the hinge's other side of the
# door's normal, the head's theta_1 turned back by as much so the gripper faces the door. Then, held rigidly to the
# door, link 7's axle would move straight backward as the door opens (its path's tangent is its heading:
# atan((tip behind the hinge line + tip ahead of link 7) / knob radius)), instead of sideways, which no wheel can.
DOOR_APPROACH = math.atan2(DOOR_TIP_BEHIND + TIP_AHEAD, DOOR_RADIUS)
VALVE_HORIZON = 10.0  # [s]
# The controller's two values the paper does not give, in the operations (default (ours)): the null-space gain
# k_eta of Eq. 14 and W's wheel weight (`control.default_weights`). The other MuJoCo experiments keep 0.1 and 1
# (`params.PARAMETERS`). Chosen for the door (docs/snake.md, "Opening the door"): with 0.1 and 1 the switching
# states turn link 7 off the pull's direction and the last pull stretches the head part into its singular pose
# (psi_2 = 0; tip 92 mm off). A search of about 150 settings of (operator_enter, operator_exit,
# operator_min_switch, k_eta, w_wheel) on 2-5 perturbed trials each found these; on 20 held-out seeds every trial
# stalls twice, opens the door 1.12-1.15 rad and keeps the tip within 26.1 mm. Narrow: k_eta 0.3, w_wheel 1.0 or
# the earlier 5 s switching minimum push the door open after the same blow-up (81-156 mm). The pick and the valve
# do not depend on them (their rows are within 1 mm and 0.01 rad).
OPERATION_GAINS: Mapping[str, float] = {"k_eta": 0.35, "w_wheel": 1.5}


@jax.jit
def _tip_pose(base: jax.Array, phi: jax.Array) -> jax.Array:
    """The gripper tip's pose (6,) for the base pose (x, y, heading) and joint angles
    phi (12,): one program (this module computes `door_start` at import; op by op that
    compiled ~50 one-operation programs in every process)."""
    return kinematics.tip_from_head(kinematics.base_frame_pose(base, phi))


def initial_tip() -> np.ndarray:
    """The gripper tip's pose (6,) in the Sec. V-A posture, base at the origin [m, rad]."""
    with jax.enable_x64(True):
        return np.asarray(_tip_pose(np.zeros(3), np.asarray(snake_params.INITIAL_PHI, float)))


def _add_gripper(spec: mujoco.MjSpec) -> None:
    """The Omni-gripper's hardening: an adhesion actuator on the head link; contacts
    within GRIP_REACH of the gripper are seen (geom margin = gap), so it pulls across it."""
    for geom in spec.geoms:
        if geom.name == "gripper":
            geom.margin, geom.gap = GRIP_REACH, GRIP_REACH
    grip = spec.add_actuator(name="gripper", target="link1", trntype=mujoco.mjtTrn.mjTRN_BODY)
    grip.set_to_adhesion(gain=GRIP_FORCE)
    grip.ctrlrange = [0.0, 1.0]


def _add_pipe(spec: mujoco.MjSpec) -> None:
    """The T-joint pipe on the floor under the gripper's middle (free body), its centre
    recorded (`pipe_pos`), and the gripper."""
    tip = initial_tip()
    centre = [float(tip[0] - snake_params.GRIPPER_TIP + GRIPPER_MID), 0.0, PIPE_RADIUS]
    pipe = spec.worldbody.add_body(name="pipe", pos=centre)
    pipe.add_freejoint(name="pipe")
    main, branch = PIPE_HALF_LENGTH
    pipe.add_geom(name="pipe_main", type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[PIPE_RADIUS, main, 0],
                  quat=[0.7071068, 0.7071068, 0, 0], mass=0.7 * PIPE_MASS, rgba=STEEL, **OBJECT)
    pipe.add_geom(name="pipe_branch", type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[PIPE_RADIUS, branch, 0],
                  pos=[branch, 0, 0], quat=[0.7071068, 0, 0.7071068, 0], mass=0.3 * PIPE_MASS, rgba=STEEL, **OBJECT)
    pipe.add_site(name="pipe")
    spec.add_sensor(name="pipe_pos", type=mujoco.mjtSensor.mjSENS_FRAMEPOS, objtype=mujoco.mjtObj.mjOBJ_SITE,
                    objname="pipe")
    _add_gripper(spec)


def _add_valve(spec: mujoco.MjSpec) -> None:
    """A gate valve's handwheel facing the gripper tip (hinge along the tip's x, on a fixed
    mount), VALVE_GAP ahead of it, its angle recorded (`valve_angle`), and the gripper."""
    tip = initial_tip()
    hub = [float(tip[0] + VALVE_GAP + VALVE_HALF[1]), 0.0, float(tip[2])]
    wheel = spec.worldbody.add_body(name="valve", pos=hub)
    wheel.add_joint(name="valve", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[1, 0, 0], frictionloss=VALVE_FRICTION,
                    damping=0.01, armature=0.001)
    wheel.add_geom(name="valve", type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=list(VALVE_HALF),
                   quat=[0.7071068, 0, 0.7071068, 0], mass=0.3, rgba=[0.75, 0.15, 0.1, 1],
                   **{**OBJECT, "condim": 4, "friction": [1.0, VALVE_TORSION, 0.0001]})
    spec.add_sensor(name="valve_angle", type=mujoco.mjtSensor.mjSENS_JOINTPOS, objtype=mujoco.mjtObj.mjOBJ_JOINT,
                    objname="valve")
    _add_gripper(spec)


def _door_layout() -> tuple[np.ndarray, np.ndarray]:
    """The door's knob centre and hinge foot (3,), (3,) [m] in the world (`_add_door`)."""
    tip = initial_tip()
    knob = np.array([tip[0] + KNOB_RADIUS + 0.002, tip[1], tip[2]])
    return knob, np.array([knob[0] + KNOB_RADIUS + DOOR_HALF[0], knob[1] - DOOR_RADIUS, 0.0])


def _add_door(spec: mujoco.MjSpec) -> None:
    """A door facing the gripper (its panel in the y-z plane beyond the tip) on a vertical
    hinge DOOR_RADIUS to the tip's right, a knob (sphere) touching the tip, the door's
    angle recorded (`door_angle`), and the gripper."""
    knob, hinge = _door_layout()
    door = spec.worldbody.add_body(name="door", pos=hinge.tolist())
    door.add_joint(name="door", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 0, 1], damping=0.2, frictionloss=0.05,
                   range=[0.0, 2.0], limited=mujoco.mjtLimited.mjLIMITED_TRUE)  # the frame: it opens towards the robot
    door.add_geom(name="door", type=mujoco.mjtGeom.mjGEOM_BOX, size=[DOOR_HALF[0], DOOR_HALF[1], DOOR_HALF[2]],
                  pos=[0.0, DOOR_HALF[1], DOOR_HALF[2] + 0.01], mass=1.0, rgba=[0.55, 0.4, 0.25, 1], **OBJECT)
    door.add_geom(name="knob", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[KNOB_RADIUS, 0, 0],
                  pos=[float(knob[0] - hinge[0]), DOOR_RADIUS, float(knob[2])], mass=0.05, rgba=STEEL, **OBJECT)
    spec.add_sensor(name="door_angle", type=mujoco.mjtSensor.mjSENS_JOINTPOS, objtype=mujoco.mjtObj.mjOBJ_JOINT,
                    objname="door")
    _add_gripper(spec)


def _mjx_grip(spec: mujoco.MjSpec, body: str, point, touch: float) -> None:
    """The MJX variant's gripper (module docstring), in place: its adhesion becomes a
    tendon from the gripper's centre (GRIPPER_MID ahead of the head frame) to `point`
    (3,) [m] in the frame of `body`, pulled with GRIP_FORCE [N] times its ctrl while the
    tendon is shorter than `touch` (its length [m] when the two surfaces touch along it)
    + GRIP_REACH, fading to 0 over GRIP_RELEASE beyond (an affine gain in the tendon's
    length, clipped to [0, GRIP_FORCE]). The actuator keeps its name and index."""
    spec.body("link1").add_site(name="grip", pos=[GRIPPER_MID, 0.0, 0.0])
    spec.body(body).add_site(name="grip_object", pos=[float(x) for x in point])
    tendon = spec.add_tendon(name="grip")
    tendon.wrap_site("grip")
    tendon.wrap_site("grip_object")
    grip = spec.actuator("gripper")
    grip.trntype, grip.target = mujoco.mjtTrn.mjTRN_TENDON, "grip"
    grip.gear = [-1.0, 0.0, 0.0, 0.0, 0.0, 0.0]  # a positive force shortens the tendon; actuator length = -length
    stiffness = GRIP_FORCE / GRIP_RELEASE  # [N/m] force = stiffness (touch + GRIP_REACH + GRIP_RELEASE - length)
    grip.gaintype = mujoco.mjtGain.mjGAIN_AFFINE
    grip.gainprm[:3] = [stiffness * (touch + GRIP_REACH + GRIP_RELEASE), stiffness, 0.0]
    grip.forcelimited, grip.forcerange = mujoco.mjtLimited.mjLIMITED_TRUE, [0.0, GRIP_FORCE]


_GRIPPER_HALF = 0.5 * snake_params.GRIPPER_LENGTH  # [m] from the gripper's centre to its tip


def _mjx_pipe(spec: mujoco.MjSpec) -> None:
    """`PIPE` on MJX: the gripper pulls the pipe's centre (the main tube across under it)."""
    _mjx_grip(spec, "pipe", (0.0, 0.0, 0.0), snake_params.GRIPPER_RADIUS + PIPE_RADIUS)


def _mjx_valve(spec: mujoco.MjSpec) -> None:
    """`VALVE` on MJX: the gripper's tip pulls the handwheel's hub."""
    _mjx_grip(spec, "valve", (0.0, 0.0, 0.0), _GRIPPER_HALF + VALVE_HALF[1])


def _mjx_door(spec: mujoco.MjSpec) -> None:
    """`DOOR` on MJX: the gripper's tip pulls the knob's centre."""
    knob, hinge = _door_layout()
    _mjx_grip(spec, "door", knob - hinge, _GRIPPER_HALF + KNOB_RADIUS)


def door_script(angles=DOOR_ANGLES, t_start: float = 2.0, duration: float = 3.0) -> tuple:
    """The operator's door script: press the knob, then pull it along the door's arc in
    steps to the door angles `angles` [rad], yawing the gripper with the door so that it
    stays perpendicular to it (Sec. V-D 3): the tip moves on the circle about the hinge
    that it would follow held rigidly to the door, one step every `duration` s from
    t_start."""
    steps, prev, t = [(0.5, 1.0, (0.005, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0))], 0.0, t_start
    tip = np.array([-DOOR_TIP_BEHIND, DOOR_RADIUS])  # the tip from the hinge (x, y) at angle 0

    def turned(a):
        return np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]]) @ tip

    for a in angles:
        dx, dy = turned(a) - turned(prev)
        d = (float(dx), float(dy), 0.0, 0.0, 0.0, a - prev, 0.0)
        steps.append((t, duration, d))
        prev, t = a, t + duration
    return tuple(steps)


def door_start(approach: float = DOOR_APPROACH) -> dict[str, Any]:
    """The robot's start at the door (`DOOR_APPROACH`): params overrides phi0 (12,)
    (the Sec. V-A posture with theta_1 = -approach), heading0 = approach and the base
    placement x0, y0 [m] that put the gripper tip where `initial_tip` is, facing the
    door (+x)."""
    phi0 = np.asarray(snake_params.INITIAL_PHI, float).copy()
    phi0[0] = -approach
    with jax.enable_x64(True):
        def tip(x0, y0):
            return np.asarray(_tip_pose(np.array([x0, y0, approach], float), phi0))

        shift = initial_tip()[:2] - tip(0.0, 0.0)[:2]
    return {"phi0": phi0, "heading0": float(approach), "x0": float(shift[0]), "y0": float(shift[1])}


def _grip(p: Any, t: Any) -> Any:
    return jnp.atleast_1d(jnp.where(t >= p["grip_at"], 1.0, 0.0))


def _no_mocap(p: Any, dtype: Any) -> tuple[Any, Any]:
    return jnp.zeros((0, 3), dtype), jnp.zeros((0, 4), dtype)


DOOR = scenarios.Fixture(
    add=_add_door, bodies=(), pose=_no_mocap, sensors=("door_angle",), actuators=("gripper",), ctrl=_grip,
    mjx=_mjx_door,
)
PIPE = scenarios.Fixture(
    add=_add_pipe, bodies=(), pose=_no_mocap, sensors=("pipe_pos",), actuators=("gripper",), ctrl=_grip,
    mjx=_mjx_pipe,
)
VALVE = scenarios.Fixture(
    add=_add_valve, bodies=(), pose=_no_mocap, sensors=("valve_angle",), actuators=("gripper",), ctrl=_grip,
    mjx=_mjx_valve,
)


@functools.lru_cache(maxsize=8)
def operation_scenario(
    fixture: scenarios.Fixture, horizon: float, prediction: predictive.Prediction | None = None,
    backend: str = "native", twist_compliance: float = 0.0,
) -> Scenario:
    """The flat-ground snake scenario with an operation's objects and the gripper, the
    tip under the paper's feedforward task-space control (`prediction`: the switching
    state's modes chosen by look-ahead, `predictive`, instead of the fixed order); for
    `backend` "mjx" on the MJX variant (module docstring); `twist_compliance`
    [rad/(N m)] > 0: the base twists at its joints (`scenarios.twisting_base`)."""
    return scenarios.snake_scenario(
        horizon, CONTROL_DT, sim_control.task_space_controller(CONTROL_DT, "tip", False, prediction), fixture=fixture,
        backend=backend, twist_compliance=twist_compliance,
    )


def script_params(script=PICK_SCRIPT, grip_at: float = PICK_GRIP_AT, n: int = 1, **overrides) -> dict[str, Any]:
    """Simulation params of n runs of an operator's script (module docstring); a
    "phi0" override (12,) or (n, 12) is the start posture (`scenarios.snake_scenario`)."""
    phi0 = overrides.pop("phi0", None)
    params = sim_control.params_batch(n, **overrides)
    if phi0 is not None:
        params["phi0"] = np.broadcast_to(np.asarray(phi0, float), (n, snake_params.N_PHI)).copy()
    params["script_t0"] = np.tile([s[0] for s in script], (n, 1))
    params["script_duration"] = np.tile([s[1] for s in script], (n, 1))
    params["script_delta"] = np.tile(np.array([s[2] for s in script], float), (n, 1, 1))
    params["grip_at"] = np.broadcast_to(np.asarray(grip_at, float), (n,)).copy()
    return params


def script_target(t: np.ndarray, w0: np.ndarray, script) -> np.ndarray:
    """The tip pose the script asks for at times t (n,) from its start pose w0 (6,)."""
    out = np.tile(np.asarray(w0, float)[:6], (len(t), 1))
    for t0, dur, delta in script:
        tau = np.clip((np.asarray(t) - t0) / dur, 0.0, 1.0)
        out += np.outer(tau - np.sin(2 * np.pi * tau) / (2 * np.pi), np.asarray(delta, float)[:6])
    return out


def tip_distance(records: Mapping[str, Any]) -> np.ndarray:
    """(..., T) distance [m] of the tip from the operator's intended tip position
    (`operator`: the tip seen at t = 0 plus the script's change so far) in a rollout's
    records (with or without the batch axis)."""
    return np.linalg.norm(np.asarray(records["tip"])[..., :3] - np.asarray(records["intent"])[..., :3], axis=-1)


def switching(records: Mapping[str, Any]) -> np.ndarray:
    """(..., T) bool: the commanded mode is not the fixing state's mode 1 (the switching
    state runs modes 2..6, Table II)."""
    return np.any(np.asarray(records["grounded_cmd"]) != np.asarray(snake_params.MODES[0], bool), axis=-1)


def tip_errors(res: RolloutResult) -> tuple[np.ndarray, np.ndarray]:
    """(largest, final) `tip_distance` [m] (n,) of each run."""
    err = tip_distance(res.records)
    return err.max(-1), err[:, -1]


def switching_record(res: RolloutResult) -> np.ndarray:
    """(n, T) `switching` of a rollout."""
    return switching(res.records)


def _pick_measures(res: RolloutResult) -> dict[str, np.ndarray]:
    pipe = np.asarray(res.records["fixture"])  # (n, T, 3)
    return {"pipe_lift": pipe[:, -1, 2] - pipe[:, 0, 2]}


def _valve_measures(res: RolloutResult) -> dict[str, np.ndarray]:
    angle = np.asarray(res.records["fixture"])[..., 0]
    roll = np.unwrap(np.asarray(res.records["tip"])[..., 3], axis=-1)
    return {"valve_turn": angle[:, -1] - angle[:, 0], "roll": roll[:, -1] - roll[:, 0]}


def _door_measures(res: RolloutResult) -> dict[str, np.ndarray]:
    angle = np.asarray(res.records["fixture"])[..., 0]
    return {"door_angle": angle[:, -1], "door_max": angle.max(-1)}


@dataclass(frozen=True)
class Operation:
    """One of the paper's operations: the objects and gripper (`fixture`), the run's
    length [s], the operator's script and when the gripper hardens [s], and what is
    measured on the rollout (`measures(result) -> {name: (n,)}`)."""

    name: str
    fixture: scenarios.Fixture
    horizon: float
    script: tuple
    grip_at: float
    measures: Callable[[RolloutResult], dict[str, np.ndarray]]
    start: Mapping[str, Any] = field(default_factory=dict)  # params overrides: how the robot stands at the object

    def start_params(self, n: int) -> dict[str, np.ndarray]:
        """`start` as params of n runs (x0, y0 are added to any placement jitter)."""
        return {k: np.tile(np.asarray(v, float), (n, 1)) if np.ndim(v) else np.full(n, float(v))
                for k, v in self.start.items()}


DOOR_HORIZON = 40.0  # [s] the script's 14 s and the operator's pauses at the stalls

OPERATIONS: dict[str, Operation] = {
    "pick": Operation("pick", PIPE, PICK_HORIZON, PICK_SCRIPT, PICK_GRIP_AT, _pick_measures),
    "valve": Operation("valve", VALVE, VALVE_HORIZON, VALVE_SCRIPT, VALVE_GRIP_AT, _valve_measures),
    "door": Operation("door", DOOR, DOOR_HORIZON, door_script(), DOOR_GRIP_AT, _door_measures, door_start()),
}


def measure(operation: Operation, res: RolloutResult) -> dict[str, np.ndarray]:
    """The operation's measures and the tip errors (`tip_errors`) of a rollout (n,)."""
    max_err, final_err = tip_errors(res)
    return {**operation.measures(res), "max_tip_error": max_err, "final_tip_error": final_err}


def run_operation(
    name: str,
    n: int = 1,
    script=None,
    grip_at: Any = None,
    horizon: float | None = None,
    prediction: predictive.Prediction | None = None,
    start: Mapping[str, Any] | None = None,
    **overrides,
) -> tuple[RolloutResult, dict[str, np.ndarray]]:
    """n runs of operation `name` (OPERATIONS) on native MuJoCo, its script, grip time and
    start (`Operation.start`; {}: the Sec. V-A posture at the origin) unless given, the
    controller's OPERATION_GAINS and params `overrides` (scalars or (n,); x0, y0 shift the
    start), the switching state's modes predicted if `prediction` is given: the rollout
    and `measure`."""
    op = OPERATIONS[name]
    if start is not None:
        op = replace(op, start=start)
    start = op.start_params(n)
    for k in ("x0", "y0"):
        if k in start and k in overrides:
            start[k] = start[k] + np.asarray(overrides.pop(k), float)
    params = script_params(op.script if script is None else script, op.grip_at if grip_at is None else grip_at, n,
                           **{**OPERATION_GAINS, **start, **overrides})
    res = rollout(operation_scenario(op.fixture, op.horizon if horizon is None else horizon, prediction), params,
                  backend="native")
    return res, measure(op, res)


def run_pick(n: int = 1, grip_at: Any = PICK_GRIP_AT, **overrides) -> tuple[RolloutResult, dict[str, np.ndarray]]:
    """The pick-up, n runs: the rollout and (pipe_lift [m]: the pipe's height gained at
    the end; max_tip_error, final_tip_error [m]: `tip_errors`)."""
    return run_operation("pick", n, grip_at=grip_at, **overrides)


def run_valve(n: int = 1, grip_at: Any = VALVE_GRIP_AT, **overrides) -> tuple[RolloutResult, dict[str, np.ndarray]]:
    """Rotating the gate valve (Sec. V-D 2): push the soft gripper onto the handwheel,
    harden, roll the gripper by 90 deg. Returns the rollout and (valve_turn [rad]: the
    handwheel's angle at the end, roll [rad]: the tip's roll gained, max_tip_error,
    final_tip_error [m] as `run_pick`)."""
    return run_operation("valve", n, grip_at=grip_at, **overrides)


def run_door(n: int = 1, switch_at: Any = np.inf, script=None, grip_at: Any = DOOR_GRIP_AT, horizon: float = 16.0,
             **overrides) -> tuple[RolloutResult, dict[str, np.ndarray]]:
    """Opening the door (Sec. V-D 3, Fig. 14): the tip holds the knob and pulls it along
    the door's arc (`door_script`); `switch_at` [s]: a command to the switching state
    (mode switching from then on; the operator model's own command is `operator_enter`).
    Returns the rollout and (door_angle [rad] at the end, door_max [rad] the widest it
    opened, max_tip_error, final_tip_error [m])."""
    return run_operation("door", n, script=script, grip_at=grip_at, horizon=horizon, switch_at=switch_at, **overrides)
