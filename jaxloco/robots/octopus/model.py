"""The MJCF model of the e-OCTOPUS (Table 3, Fig. 3): `jaxloco/models/octopus.xml`.

Generated from `params.py` by `python -m jaxloco.robots.octopus.model --write jaxloco/models/octopus.xml`; a test
checks that the committed file is in sync. `load_spec` / `load_model` read it back (a
scenario adds its terrain to the spec).

Structure ({R} = the `chassis` body frame, see `params.py`; 100 kg in all):
  * chassis: free joint `root`; a colliding box (500 x 300 x 360 mm, 123 mm ground
    clearance) and non-colliding battery, arm deck and crawler side frames carrying most
    of the mass low (COG 210 mm below {R}, 273 mm above flat ground); the `imu` site at
    the origin with `imu_quat` (framequat), `imu_gyro`, `imu_acc`;
  * two main crawlers (y = +-250 mm), each a row of MAIN_WHEELS = 6 sphere wheels of
    radius 90 mm over the 500 mm body length, and four flippers `flipper_fl/fr/rl/rr`
    pivoting on the crawler end axles, each carrying FLIPPER_WHEELS = 3 sphere wheels
    tapering from 78 to 55 mm up to the tip at 250 mm (flipper length, Table 3); flipper
    angle 0 continues the crawler's bottom line, > 0 lifts the tip, limits +-85 deg;
  * arms `arm1..4` (1 LF, 2 RF, 3 LR, 4 RR) at (+-m/2, +-n/2, 0): hinges `arm{i}_swing`
    (z), `arm{i}_boom` (y; > 0 lowers the boom), `arm{i}_elbow` (y, d3 to the right of the
    boom end), the forearm (l2 to the roller centre), then the passive two-axis roller: a
    sphere of radius 50 mm on a ball joint `arm{i}_roller` that rolls in every direction
    (`add_roller`). The site `arm{i}_tip` at the roller centre is the EPRA of Eqs. 1-6;
  * contact-point sites (`scenarios.CONTACT_SITES`, observed by the controllers; the
    stability margin uses every wheel and roller, `scenarios.SUPPORT_BODIES`):
    `crawler_{l,r}_{front,rear}` under the main crawler end axles and `flipper_*_tip`
    under the flipper tip wheels (the contact points when the crawler / flipper bottom
    line rests on a plane);
  * touch sensors (MuJoCo `touch`: the normal force [N] of the contacts of one body inside
    a site volume), each on a sphere site TOUCH_MARGIN larger than its wheel or roller,
    centred on it (sites never collide; they add no mass): first those of the
    contact-point sites, in the order of `touch_names()` (= `scenarios.CONTACT_SITES`):
    `crawler_{l,r}_{front,rear}_touch` (main end wheels), `flipper_*_touch` (tip wheels),
    `arm{i}_touch` (rollers); then the other wheels, `wheel_{l,r}{2..5}_touch` and
    `flipper_*_w{1,2}_touch`, so that the load of every track segment is known;
  * actuators (ctrl order `params.ACTUATOR_NAMES`): `crawler_l`, `crawler_r` velocity
    servos [m/s, +-63 mm/s] on a tendon per side; position servos [rad] on the four
    flippers and twelve arm joints, with torque limits; sensors: joint encoders
    `<joint>_pos`, `<actuator>_torque` (actuatorfrc), crawler encoders `crawler_*_pos`,
    `crawler_*_vel` (tendon, [m]);
  * keyframes `home` (Table 2 start pose, standing on flat ground z = 0) and `envelope`
    (the Table 3 envelope pose, `params.ENVELOPE_POSE`).

How faithful the crawlers are: a track is modelled as a row of driven sphere wheels. The
wheels of one side (main crawler and both flippers) are coupled by joint equalities so
that their rims move at one speed, like one belt, and one velocity servo per side drives
them through a fixed tendon whose length is the mean rim travel [m]: ctrl is the track
speed and the tendon force the total traction of that side. Spheres give one contact each
(cheap, robust on box terrain); the wheels overlap, so the underside has only 6 mm deep
notches between main wheels (with 4 wheels per side, 17 mm notches caught step edges
and the robot stalled on a 200 mm step). No grousers, no belt over the top, flipper
pivots on the end axles as on most flipper robots. Measured with the arms held level and
a scripted flipper sequence (flippers raised 1.2-1.3 rad while approaching, lowered to 0
once the front stalls at the edge): 150 and 200 mm steps are climbed at 63 mm/s; at 250
and 300 mm the robot turns over backwards, and 400 mm is out of reach, as the paper
reports for its crawler-only mode (steps < 250 mm, "the length of flippers").
Collision bits follow `jaxloco.sim.terrain` (robot contype 1 / conaffinity 2, terrain
2 / 1): the robot collides with terrain pieces, never with itself. Robot friction is
lower than the terrain's default so that MuJoCo's max rule lets the terrain decide.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from jaxloco.robots.octopus import params
from jaxloco.sim import mjcf

MODEL_PATH = mjcf.MODELS_DIR / "octopus.xml"
TIMESTEP = 0.002  # [s]
ROBOT_CONTYPE, ROBOT_CONAFFINITY = 1, 2  # = jaxloco.sim.terrain.ROBOT_* (tested)

# Arm servos (swing, boom, elbow): stiffness [N m/rad], damping [N m s/rad], torque limit
# [N m]. The boom carries most of the load when the arms lift the body (Eq. 28).
ARM_KP = (1000.0, 3000.0, 2000.0)
ARM_KV = (60.0, 120.0, 80.0)
ARM_TAU = (150.0, 400.0, 300.0)
ARM_RANGE = ((-3.1, 3.1), (-0.5 * math.pi - 0.1, 1.3), (-0.5, 2.8))  # [rad]
ARM_ARMATURE = 0.2  # reflected rotor inertia [kg m^2]
FLIPPER_KP, FLIPPER_KV, FLIPPER_TAU = 2000.0, 60.0, 200.0
FLIPPER_ARMATURE = 0.2
CRAWLER_KV = 10000.0  # track velocity servo gain [N/(m/s)]
CRAWLER_FORCE = 600.0  # traction limit per side [N]
WHEEL_ARMATURE = 0.01
ROLLER_DAMPING, ROLLER_ARMATURE = 0.05, 0.005  # [N m s/rad], [kg m^2] (`add_roller`)
# touch site radius beyond its wheel / roller sphere [m]: MuJoCo counts a contact when its
# point (mid-penetration, < 1 mm inside the sphere here) lies in the site; 10 mm covers
# deep transient penetration. Only contacts of the site's own body count, so the sites of
# the overlapping wheels do not see each other's contacts. Default (ours).
TOUCH_MARGIN = 0.01
FRICTION = (0.8, 0.005, 0.0001)
BOOM_RADIUS, FOREARM_RADIUS = 0.030, 0.025
CHASSIS_HALF = (0.25, 0.15, 0.18)  # colliding chassis box half sizes [m]
CHASSIS_Z = -0.18  # its centre in {R}: bottom at -0.36 m, ground clearance 0.123 m
VISUAL = {"contype": 0, "conaffinity": 0, "group": 1}
COLLIDE = {"contype": ROBOT_CONTYPE, "conaffinity": ROBOT_CONAFFINITY, "condim": 3, "friction": list(FRICTION)}

_SPHERE, _CAPSULE, _BOX = mujoco.mjtGeom.mjGEOM_SPHERE, mujoco.mjtGeom.mjGEOM_CAPSULE, mujoco.mjtGeom.mjGEOM_BOX
_HINGE = mujoco.mjtJoint.mjJNT_HINGE
_LIMITED = mujoco.mjtLimited.mjLIMITED_TRUE


def main_wheel_x() -> np.ndarray:
    """x of the main crawler axles in {R} [m], rear to front."""
    return np.linspace(-params.MAIN_AXLE_X, params.MAIN_AXLE_X, params.MAIN_WHEELS)


def flipper_wheels() -> tuple[np.ndarray, np.ndarray]:
    """Distances of the flipper wheels from the pivot along the flipper [m] and their
    radii [m] (linear taper from the main wheel to the tip wheel, so all are tangent to
    the flipper's bottom line)."""
    s = np.linspace(0.0, params.FLIPPER_LENGTH, params.FLIPPER_WHEELS + 1)[1:]
    radius = (
        params.MAIN_WHEEL_RADIUS + (params.FLIPPER_TIP_RADIUS - params.MAIN_WHEEL_RADIUS) * s / params.FLIPPER_LENGTH
    )
    return s, radius


def wheel_names(side: str) -> list[str]:
    """Wheel joint names of one side ("l" or "r"): main wheels rear to front, then the
    front and rear flipper wheels."""
    main = [f"wheel_{side}{k + 1}" for k in range(params.MAIN_WHEELS)]
    flips = [f"flipper_{fr}{side}_w{k + 1}" for fr in ("f", "r") for k in range(params.FLIPPER_WHEELS)]
    return main + flips


def touch_name(body: str) -> str:
    """The touch site / sensor of the wheel or roller body `body`: the main end wheels
    and the flipper tip wheels are named after their contact-point sites
    (`wheel_l1` -> `crawler_l_rear_touch`, `wheel_l6` -> `crawler_l_front_touch`,
    `flipper_fl_w3` -> `flipper_fl_touch`), the rollers after their arms (`arm1_roller`
    -> `arm1_touch`), every other wheel after itself (`wheel_l2_touch`)."""
    if body.endswith("_roller"):
        return body[: -len("_roller")] + "_touch"
    if body.startswith("wheel_"):
        side, k = body[len("wheel_")], int(body[len("wheel_") + 1:])
        if k in (1, params.MAIN_WHEELS):
            return f"crawler_{side}_{'rear' if k == 1 else 'front'}_touch"
    elif body.endswith(f"_w{params.FLIPPER_WHEELS}"):
        return body[: -len(f"_w{params.FLIPPER_WHEELS}")] + "_touch"
    return f"{body}_touch"


def touch_names() -> tuple[str, ...]:
    """The touch sensors in sensordata order: those of the contact-point sites
    (crawler_l_front, crawler_l_rear, crawler_r_front, crawler_r_rear, the flipper tips
    in `params.FLIPPER_NAMES` order, the arm rollers; the order of `scenarios.CONTACT_SITES`),
    then the other wheels (`wheel_names` order, left then right)."""
    ends = [f"crawler_{s}_{e}_touch" for s in "lr" for e in ("front", "rear")]
    tips = [f"{f}_touch" for f in params.FLIPPER_NAMES]
    rollers = [f"{a}_touch" for a in params.ARM_NAMES]
    first = ends + tips + rollers
    others = [touch_name(w) for side in "lr" for w in wheel_names(side)]
    return tuple(first + [n for n in others if n not in first])


def home_arm_angles() -> np.ndarray:
    """Arm joint angles (4, 3) [rad] of the Table 2 start pose (closed-form IK in NumPy,
    the same formulas as `kinematics.inverse_kinematics`; tested equal)."""
    out = np.zeros((4, 3))
    for k in range(4):
        base = np.array(
            [params.ARM_SIGNS[k, 0] * 0.5 * params.ARM_BASE_M, params.ARM_SIGNS[k, 1] * 0.5 * params.ARM_BASE_N, 0.0]
        )
        x, y, z = params.TABLE2_INIT[k] - base
        r = math.sqrt(x * x + y * y - params.D3 ** 2)
        t1 = math.atan2(y, x) + math.atan2(params.D3, r)
        dist2 = r * r + z * z
        t3 = math.acos((dist2 - params.L1 ** 2 - params.L2 ** 2) / (2 * params.L1 * params.L2))
        t2 = math.atan2(-z, r) - math.atan2(params.L2 * math.sin(t3), params.L1 + params.L2 * math.cos(t3))
        out[k] = [math.atan2(math.sin(t1), math.cos(t1)), t2, t3]
    return np.round(out, 6)


def build_spec() -> mujoco.MjSpec:
    """The robot alone (no terrain) as an MjSpec, from the constants in `params.py`."""
    spec = mujoco.MjSpec()
    spec.modelname = "octopus"
    spec.compiler.degree = False
    spec.option.timestep = TIMESTEP
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.cone = mujoco.mjtCone.mjCONE_PYRAMIDAL
    spec.option.iterations = 20
    spec.option.ls_iterations = 10

    chassis = spec.worldbody.add_body(name="chassis", pos=[0, 0, params.BASE_HEIGHT])
    chassis.add_freejoint(name="root")
    chassis.add_geom(name="chassis", type=_BOX, size=list(CHASSIS_HALF), pos=[0, 0, CHASSIS_Z],
                     mass=params.MASS_CHASSIS, rgba=[0.85, 0.65, 0.15, 1], **COLLIDE)
    chassis.add_geom(name="battery", type=_BOX, size=[0.20, 0.12, 0.05], pos=[0, 0, -0.30], mass=params.MASS_BATTERY,
                     rgba=[0.2, 0.2, 0.2, 1], **VISUAL)
    chassis.add_geom(name="deck", type=_BOX, size=[0.28, 0.28, 0.025], pos=[0, 0, -0.025], mass=params.MASS_DECK,
                     rgba=[0.85, 0.65, 0.15, 1], **VISUAL)
    axle_z = params.MAIN_WHEEL_RADIUS - params.BASE_HEIGHT
    for side, sy in (("l", 1.0), ("r", -1.0)):
        chassis.add_geom(
            name=f"frame_{side}",
            type=_BOX,
            size=[params.MAIN_AXLE_X, 0.03, 0.06],
            pos=[0, sy * params.CRAWLER_Y, axle_z],
            mass=params.MASS_SIDE_FRAME,
            rgba=[0.25, 0.25, 0.25, 1],
            **VISUAL,
        )
        for end, sx in (("front", 1.0), ("rear", -1.0)):
            chassis.add_site(
                name=f"crawler_{side}_{end}",
                pos=[sx * params.MAIN_AXLE_X, sy * params.CRAWLER_Y, -params.BASE_HEIGHT],
                size=[0.01, 0, 0],
            )
        for k, x in enumerate(main_wheel_x()):
            wheel = chassis.add_body(name=f"wheel_{side}{k + 1}", pos=[float(x), sy * params.CRAWLER_Y, axle_z])
            wheel.add_joint(name=f"wheel_{side}{k + 1}", type=_HINGE, axis=[0, 1, 0], armature=WHEEL_ARMATURE)
            wheel.add_geom(name=f"wheel_{side}{k + 1}", type=_SPHERE, size=[params.MAIN_WHEEL_RADIUS, 0, 0],
                           mass=params.MASS_MAIN_WHEEL, rgba=[0.1, 0.1, 0.1, 1], **COLLIDE)
            _touch_site(wheel, f"wheel_{side}{k + 1}", params.MAIN_WHEEL_RADIUS)
    chassis.add_site(name="imu", size=[0.01, 0, 0])

    dist, radii = flipper_wheels()
    for name, (sf, sy) in zip(params.FLIPPER_NAMES, params.FLIPPER_SIGNS):
        side = "l" if sy > 0 else "r"
        direction = np.array([sf * math.cos(params.FLIPPER_DIP), 0.0, -math.sin(params.FLIPPER_DIP)])
        flipper = chassis.add_body(name=name, pos=[sf * params.MAIN_AXLE_X, sy * params.CRAWLER_Y, axle_z])
        flipper.add_joint(name=name, type=_HINGE, axis=[0, -sf, 0], range=[-params.FLIPPER_LIMIT, params.FLIPPER_LIMIT],
                          limited=_LIMITED, armature=FLIPPER_ARMATURE, damping=1.0)
        tip = params.FLIPPER_LENGTH * direction
        flipper.add_geom(name=f"{name}_frame", type=_CAPSULE, size=[0.02, 0, 0], fromto=[0, 0, 0, *tip.tolist()],
                         mass=params.MASS_FLIPPER_FRAME, rgba=[0.25, 0.25, 0.25, 1], **VISUAL)
        flipper.add_site(name=f"{name}_tip", pos=(tip - np.array([0, 0, params.FLIPPER_TIP_RADIUS])).tolist(),
                         size=[0.01, 0, 0])
        for k, (s, rad) in enumerate(zip(dist, radii)):
            wname = f"flipper_{'f' if sf > 0 else 'r'}{side}_w{k + 1}"
            wheel = flipper.add_body(name=wname, pos=(s * direction).tolist())
            wheel.add_joint(name=wname, type=_HINGE, axis=[0, 1, 0], armature=WHEEL_ARMATURE)
            wheel.add_geom(name=wname, type=_SPHERE, size=[float(rad), 0, 0], mass=params.MASS_FLIPPER_WHEEL,
                           rgba=[0.1, 0.1, 0.1, 1], **COLLIDE)
            _touch_site(wheel, wname, float(rad))

    for k, arm in enumerate(params.ARM_NAMES):
        base = [params.ARM_SIGNS[k, 0] * 0.5 * params.ARM_BASE_M, params.ARM_SIGNS[k, 1] * 0.5 * params.ARM_BASE_N, 0.0]
        swing = chassis.add_body(name=f"{arm}_swing", pos=base)
        _arm_joint(swing, f"{arm}_swing", [0, 0, 1], 0)
        swing.add_geom(name=f"{arm}_shoulder", type=_SPHERE, size=[0.06, 0, 0], mass=params.MASS_SHOULDER,
                       rgba=[0.3, 0.3, 0.35, 1], **VISUAL)
        boom = swing.add_body(name=f"{arm}_boom")
        _arm_joint(boom, f"{arm}_boom", [0, 1, 0], 1)
        boom.add_geom(name=f"{arm}_boom", type=_CAPSULE, size=[BOOM_RADIUS, 0, 0], fromto=[0, 0, 0, params.L1, 0, 0],
                      mass=params.MASS_BOOM, rgba=[0.85, 0.65, 0.15, 1], **COLLIDE)
        fore = boom.add_body(name=f"{arm}_forearm", pos=[params.L1, -params.D3, 0])
        _arm_joint(fore, f"{arm}_elbow", [0, 1, 0], 2)
        fore.add_geom(name=f"{arm}_forearm", type=_CAPSULE, size=[FOREARM_RADIUS, 0, 0],
                      fromto=[0, 0, 0, params.L2 - params.ROLLER_RADIUS, 0, 0], mass=params.MASS_FOREARM,
                      rgba=[0.85, 0.65, 0.15, 1], **COLLIDE)
        fore.add_site(name=f"{arm}_tip", pos=[params.L2, 0, 0], size=[0.01, 0, 0])
        add_roller(fore, arm, [params.L2, 0, 0])

    # Tracks: joint equalities tie every wheel of a side to its first main wheel (equal rim
    # speeds), and a tendon (mean rim travel [m]) carries the side's velocity servo.
    for side in ("l", "r"):
        names = wheel_names(side)
        rad = _wheel_radii()
        tendon = spec.add_tendon(name=f"crawler_{side}")
        for jn in names:
            tendon.wrap_joint(jn, rad[jn] / len(names))
        for jn in names[1:]:
            eq = spec.add_equality(name=f"track_{jn}", type=mujoco.mjtEq.mjEQ_JOINT, name1=jn, name2=names[0],
                                   objtype=mujoco.mjtObj.mjOBJ_JOINT)
            data = np.array(eq.data)
            data[:5] = [0.0, rad[names[0]] / rad[jn], 0.0, 0.0, 0.0]
            eq.data = data
            eq.solref = [0.01, 1.0]

    for side in ("l", "r"):
        act = spec.add_actuator(name=f"crawler_{side}", target=f"crawler_{side}", trntype=mujoco.mjtTrn.mjTRN_TENDON)
        act.set_to_velocity(kv=CRAWLER_KV)
        mjcf.set_actuator_limits(act, (-params.CRAWLER_MAX_SPEED, params.CRAWLER_MAX_SPEED), CRAWLER_FORCE)
    for name in params.FLIPPER_NAMES:
        act = spec.add_actuator(name=name, target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        act.set_to_position(kp=FLIPPER_KP, kv=FLIPPER_KV)
        mjcf.set_actuator_limits(act, (-params.FLIPPER_LIMIT, params.FLIPPER_LIMIT), FLIPPER_TAU)
    for arm in params.ARM_NAMES:
        for j, joint in enumerate(params.ARM_JOINTS):
            act = spec.add_actuator(name=f"{arm}_{joint}", target=f"{arm}_{joint}", trntype=mujoco.mjtTrn.mjTRN_JOINT)
            act.set_to_position(kp=ARM_KP[j], kv=ARM_KV[j])
            mjcf.set_actuator_limits(act, ARM_RANGE[j], ARM_TAU[j])

    sens = mujoco.mjtSensor
    for name in params.FLIPPER_NAMES + tuple(f"{a}_{j}" for a in params.ARM_NAMES for j in params.ARM_JOINTS):
        spec.add_sensor(name=f"{name}_pos", type=sens.mjSENS_JOINTPOS, objtype=mujoco.mjtObj.mjOBJ_JOINT, objname=name)
    for name in params.FLIPPER_NAMES + tuple(f"{a}_{j}" for a in params.ARM_NAMES for j in params.ARM_JOINTS):
        spec.add_sensor(name=f"{name}_torque", type=sens.mjSENS_ACTUATORFRC, objtype=mujoco.mjtObj.mjOBJ_ACTUATOR,
                        objname=name)
    for side in ("l", "r"):
        for kind, stype in (("pos", sens.mjSENS_TENDONPOS), ("vel", sens.mjSENS_TENDONVEL)):
            spec.add_sensor(name=f"crawler_{side}_{kind}", type=stype, objtype=mujoco.mjtObj.mjOBJ_TENDON,
                            objname=f"crawler_{side}")
        spec.add_sensor(name=f"crawler_{side}_force", type=sens.mjSENS_ACTUATORFRC,
                        objtype=mujoco.mjtObj.mjOBJ_ACTUATOR, objname=f"crawler_{side}")
    for name, stype in (("imu_quat", sens.mjSENS_FRAMEQUAT), ("imu_gyro", sens.mjSENS_GYRO),
                        ("imu_acc", sens.mjSENS_ACCELEROMETER)):
        spec.add_sensor(name=name, type=stype, objtype=mujoco.mjtObj.mjOBJ_SITE, objname="imu")
    for name in touch_names():
        spec.add_sensor(name=name, type=sens.mjSENS_TOUCH, objtype=mujoco.mjtObj.mjOBJ_SITE, objname=name)

    model = spec.compile()
    for key, arms in (("home", home_arm_angles()), ("envelope", params.ENVELOPE_POSE)):
        qpos, ctrl = pose_qpos_ctrl(model, arms)
        spec.add_key(name=key, qpos=qpos.tolist(), ctrl=ctrl.tolist())
    return spec


def pose_qpos_ctrl(model: mujoco.MjModel, arms: np.ndarray, flippers: np.ndarray | None = None,
                   base_height: float = params.BASE_HEIGHT) -> tuple[np.ndarray, np.ndarray]:
    """qpos (chassis level at `base_height`, arms (4, 3) and flippers (4,) [rad], wheels
    and rollers 0) and the matching ctrl (crawlers stopped, servos holding the pose)."""
    flippers = np.zeros(4) if flippers is None else np.asarray(flippers, float)
    qpos = model.qpos0.copy()
    qpos[:7] = [0, 0, base_height, 1, 0, 0, 0]
    ctrl = np.zeros(model.nu)
    for k, name in enumerate(params.FLIPPER_NAMES):
        qpos[model.joint(name).qposadr[0]] = flippers[k]
        ctrl[model.actuator(name).id] = flippers[k]
    for k, arm in enumerate(params.ARM_NAMES):
        for j, joint in enumerate(params.ARM_JOINTS):
            qpos[model.joint(f"{arm}_{joint}").qposadr[0]] = arms[k][j]
            ctrl[model.actuator(f"{arm}_{joint}").id] = arms[k][j]
    return qpos, ctrl


def _wheel_radii() -> dict[str, float]:
    out = {}
    _, radii = flipper_wheels()
    for side in ("l", "r"):
        for k in range(params.MAIN_WHEELS):
            out[f"wheel_{side}{k + 1}"] = params.MAIN_WHEEL_RADIUS
        for fr in ("f", "r"):
            for k in range(params.FLIPPER_WHEELS):
                out[f"flipper_{fr}{side}_w{k + 1}"] = float(radii[k])
    return out


def add_roller(parent: mujoco.MjsBody, arm: str, pos: list[float]) -> mujoco.MjsBody:
    """The passive two-axis roller at an arm's end (paper, "Arm moving", Fig. 8): a sphere
    of radius ROLLER_RADIUS on a ball joint `{arm}_roller`, so that it rolls freely in
    every direction on the ground (the paper's purpose: "to prevent robot arms being
    broken during EPRA's slippage"), with its touch site. Before 3 Dec 2026 it hung on two
    nested hinges (forearm z, then y). Dragged over a floor (mu 0.8) with the forearm 45
    deg down and back, that roller slid at about mu N in both directions, where the ball
    rolls at 2.4 % of mu N (`tests/test_octopus_model.py::test_roller_rolls_every_way`),
    so a placed arm whose boom turned dragged its roller and pushed the body (a model
    artifact). Bearing damping ROLLER_DAMPING and torsional contact friction (condim 4)
    keep the free ball from spinning up: with 0.01 N m s/rad and no torsional friction
    rollers reached the 100 rad/s divergence limit in 3 of 20 block runs. Default (ours)."""
    roller = parent.add_body(name=f"{arm}_roller", pos=pos)
    roller.add_joint(name=f"{arm}_roller", type=mujoco.mjtJoint.mjJNT_BALL, damping=ROLLER_DAMPING,
                     armature=ROLLER_ARMATURE)
    roller.add_geom(name=f"{arm}_roller", type=_SPHERE, size=[params.ROLLER_RADIUS, 0, 0], mass=params.MASS_ROLLER,
                    rgba=[0.1, 0.1, 0.1, 1], **{**COLLIDE, "condim": 4})
    _touch_site(roller, f"{arm}_roller", params.ROLLER_RADIUS)
    return roller


def _touch_site(body: mujoco.MjsBody, name: str, radius: float) -> None:
    """The touch site of a wheel or roller body (`touch_name`), invisible."""
    body.add_site(name=touch_name(name), size=[radius + TOUCH_MARGIN, 0, 0], rgba=[1, 0, 0, 0])


def _arm_joint(body: mujoco.MjsBody, name: str, axis: list[float], j: int) -> None:
    body.add_joint(name=name, type=_HINGE, axis=axis, range=list(ARM_RANGE[j]), limited=_LIMITED,
                   armature=ARM_ARMATURE, damping=1.0)


FILE = mjcf.ModelFile(MODEL_PATH, build_spec)
load_spec = FILE.load_spec
load_model = FILE.load_model
xml_text = FILE.xml_text


def main(argv: list[str] | None = None) -> None:
    FILE.main(__doc__.splitlines()[0], argv)


if __name__ == "__main__":
    main()
