"""The MJCF model of the leg-grope quadruped (Table 1): `jaxloco/models/leggrope.xml`.

The file is generated from `LegGropeParams` by `python -m jaxloco.robots.leggrope.model
--write jaxloco/models/leggrope.xml` (and a test checks that it is in sync); `load_spec` reads it back as an MjSpec
to which a scenario adds its terrain.

Structure (robot frame Sigma_R = the torso body frame: x forward, y left, z up, origin at
the body centre in the hip plane):
  * torso: box 0.29 x 0.15 x 0.04 m, 4.54 kg, free joint; an IMU site at the origin
    with `imu_quat` (framequat), `imu_gyro` and `imu_acc` sensors;
  * leg i (L1..L4) at the hip `params.hips()[i]`, rotated by its mount angle: a yaw
    joint `Li_yaw` (z), the link i1 (l1 along x), a pitch joint `Li_pitch` and the link
    i2, the knee `Li_knee` and the link i3, each pitch axis -y so that a positive angle
    lifts the link (the convention of `kinematics.py`); links are capsules with their
    Table 1 mass (uniform rods: COM at the midpoint);
  * a toe body `Li_toe` at the end of link i3 with a sphere of radius TOE_RADIUS (the
    only leg geom that collides) and a site `Li_toe` carrying the 3-axis force sensor
    `Li_force` (as the real robot's toe sensors);
  * toe contacts: elliptic cone with MuJoCo's no-slip solver (see CONTACT_SOLREF); a
    scenario's MJX variant switches to a pyramidal cone without it (`use_mjx_contacts`);
  * a position actuator per joint (the real robot's joints take position inputs) with
    stiffness KP, damping KV and torque limit TAU_MAX.
Collision bits: the torso and toes use `contype 1, conaffinity 2`, terrain pieces
`contype 2, conaffinity 1` (`jaxloco.sim.terrain`): the robot never collides with
itself. Toe sliding friction is 0 so that MuJoCo's max-combination gives the terrain's
friction, which scenarios sweep.
"""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np

from jaxloco.robots.leggrope.params import LEG_NAMES, LegGropeParams, default_params
from jaxloco.sim import mjcf

MODEL_PATH = mjcf.MODELS_DIR / "leggrope.xml"
TOE_RADIUS = 0.008  # [m]
KP = 150.0  # position servo stiffness [N m / rad]
KV = 3.0  # position servo damping [N m s / rad]
# The servos follow their setpoints through a first-order filter (MJCF `timeconst`), as a
# servo amplifier's setpoint smoothing does. Without it each 20 ms control period's new
# setpoint is a step: a stiff servo answers it with a force transient every period, the
# toes slip a little at each one, and at R_ref = 0.4 M g cos(theta) a walk's stance toes
# crept up to 67 mm downhill in one cycle (18 mm with a 4 ms control period). Default (ours).
SERVO_TIMECONST = 0.02  # [s]
TAU_MAX = 12.0  # joint torque limit [N m]
ARMATURE = 0.005  # reflected rotor inertia [kg m^2]
TIMESTEP = 0.002  # physics step [s]
# Toe contacts. MuJoCo's soft contacts let a loaded toe creep: with its defaults (solref
# 0.02, solimp 0.9, pyramidal cone, impratio 1) a robot standing on the 15 degree slope
# crept about 50 mm/s. Our first fix, near-hard contacts (solref 0.004 = 2 timesteps,
# solimp 0.99, impratio 10), stopped the creep but made the toe forces chatter at the
# physics rate during the walk (mean |change| of a toe's normal force per 20 ms control
# period 0.24 R_ref, spikes to 15 R_ref), which both fakes force feedback and ruins the
# "normal force below R_ref" metric. Now: moderately soft contacts (solref 0.01) with an
# elliptic friction cone and MuJoCo's no-slip post-solver, which removes the creep of
# soft friction (standing on the slope: < 0.1 mm/s, `tests/test_leggrope_sim.py`) with
# smooth forces (0.007 R_ref per period in the same walk). The MJX backend ignores
# `noslip_iterations` (it warns): there the toes creep as with plain soft contacts.
CONTACT_SOLREF = (0.01, 1.0)  # time constant 5 timesteps, critically damped
CONTACT_SOLIMP = (0.9, 0.95, 0.001, 0.5, 2.0)
IMPRATIO = 1.0
NOSLIP_ITERATIONS = 5
# The MJX-compatible toe contacts (`use_mjx_contacts`): MJX has no no-slip solver, and its
# elliptic cone gives NaN forward-mode derivatives, so the MJX variant of a scenario uses
# the pyramidal cone without no-slip. Plain soft friction then lets a loaded toe creep:
# standing on the 15 degree slope, 36 mm/s at impratio 1, 12 at 3, 3.7 at 10, 1.1 at 30,
# 0.24 at 100 (elliptic with no-slip: 0.001 mm/s; MuJoCo C, 1 s after 0.5 s of settling).
# impratio makes the friction rows harder than the normal ones without raising mu.
# Default (ours): 30. At 100 the walk's toe forces spiked to 1.0-1.09 R_ref in steps where
# MuJoCo's C engine keeps them at 0.84-0.98 (30: 0.82-0.98); at 10 the stance crept 70 mm
# in the first grope. See docs/simulation.md for what the walk still differs by.
MJX_IMPRATIO = 30.0
# MJX emits every contact that a geom pair's collision function can make (toes x 13
# terrain boxes, torso x 13 boxes: 104 contacts, 428 constraint rows) and solves them all,
# the inactive ones masked. The walk never has more than a few in touch (four toes; a
# fallen torso on a box: 4), so the MJX variant keeps the 16 deepest (MJX's
# `max_contact_points`): half the time per physics step on CPU. Default (ours).
MJX_MAX_CONTACTS = 16
JOINTS = ("yaw", "pitch", "knee")


def build_spec(params: LegGropeParams | None = None) -> mujoco.MjSpec:
    """The robot alone (no terrain) as an MjSpec, from `params`."""
    params = params or default_params()
    spec = mujoco.MjSpec()
    spec.modelname = "leggrope"
    spec.compiler.degree = False
    spec.option.timestep = TIMESTEP
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.option.impratio = IMPRATIO
    spec.option.noslip_iterations = NOSLIP_ITERATIONS
    spec.option.iterations = 20
    spec.option.ls_iterations = 10
    lengths = np.asarray(params.link_lengths, float)
    masses = np.asarray(params.link_masses, float)
    hips = np.asarray(params.hips(), float)
    mounts = np.asarray(params.mount_angles(), float)

    torso = spec.worldbody.add_body(name="torso", pos=[0, 0, float(params.body_height)])
    torso.add_freejoint(name="root")
    half = [0.5 * float(params.body_length), 0.5 * float(params.body_width), 0.02]
    torso.add_geom(name="torso", type=mujoco.mjtGeom.mjGEOM_BOX, size=half, mass=float(params.body_mass),
                   contype=1, conaffinity=2, rgba=[0.3, 0.4, 0.6, 1])
    torso.add_site(name="imu", size=[0.01, 0, 0])
    for i, leg in enumerate(LEG_NAMES):
        parent = torso.add_body(name=f"{leg}_hip", pos=hips[i].tolist(), quat=_yaw_quat(mounts[i]))
        axes = ([0, 0, 1], [0, -1, 0], [0, -1, 0])
        ranges = ([-0.5 * math.pi, 0.5 * math.pi], [-0.5 * math.pi, 0.5 * math.pi], [-math.pi + 0.05, 0.2])
        for j, name in enumerate(JOINTS):
            if j:
                parent = parent.add_body(name=f"{leg}_{name}_link", pos=[float(lengths[j - 1]), 0, 0])
            parent.add_joint(
                name=f"{leg}_{name}",
                axis=axes[j],
                range=ranges[j],
                limited=mujoco.mjtLimited.mjLIMITED_TRUE,
                armature=ARMATURE,
                damping=0.02,
            )
            parent.add_geom(name=f"{leg}_link{j + 1}", type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[0.01, 0, 0],
                            fromto=[0, 0, 0, float(lengths[j]), 0, 0], mass=float(masses[j]), contype=0, conaffinity=0,
                            rgba=[0.7, 0.7, 0.7, 1])
        toe = parent.add_body(name=f"{leg}_toe", pos=[float(lengths[2]), 0, 0])
        toe.add_geom(name=f"{leg}_toe", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[TOE_RADIUS, 0, 0], mass=0.0,
                     contype=1, conaffinity=2, condim=3, friction=[0.0, 0.005, 0.0001], solref=list(CONTACT_SOLREF),
                     solimp=list(CONTACT_SOLIMP),
                     rgba=[0.9, 0.3, 0.2, 1])
        toe.add_site(name=f"{leg}_toe", size=[0.005, 0, 0])
    for leg in LEG_NAMES:
        for name in JOINTS:
            servo = spec.add_actuator(name=f"{leg}_{name}", target=f"{leg}_{name}", trntype=mujoco.mjtTrn.mjTRN_JOINT)
            servo.set_to_position(kp=KP, kv=KV, timeconst=SERVO_TIMECONST)
            servo.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
            servo.forcerange = [-TAU_MAX, TAU_MAX]
    for leg in LEG_NAMES:
        spec.add_sensor(name=f"{leg}_force", type=mujoco.mjtSensor.mjSENS_FORCE,
                        objtype=mujoco.mjtObj.mjOBJ_SITE, objname=f"{leg}_toe")
    spec.add_sensor(name="imu_quat", type=mujoco.mjtSensor.mjSENS_FRAMEQUAT, objtype=mujoco.mjtObj.mjOBJ_SITE,
                    objname="imu")
    spec.add_sensor(name="imu_gyro", type=mujoco.mjtSensor.mjSENS_GYRO, objtype=mujoco.mjtObj.mjOBJ_SITE, objname="imu")
    spec.add_sensor(name="imu_acc", type=mujoco.mjtSensor.mjSENS_ACCELEROMETER, objtype=mujoco.mjtObj.mjOBJ_SITE,
                    objname="imu")
    return spec


def use_mjx_contacts(spec: mujoco.MjSpec, impratio: float = IMPRATIO, max_contacts: int | None = None
                     ) -> mujoco.MjSpec:
    """Switch `spec` (in place; returned) to contacts that MJX simulates like MuJoCo's C
    engine: pyramidal friction cone, no no-slip post-solver, `impratio` (the friction rows'
    impedance ratio; the robot's own IMPRATIO unless given, MJX_IMPRATIO for the walk) and,
    if given, MJX's `max_contact_points` (the deepest `max_contacts` contacts are solved;
    MuJoCo's C engine ignores it)."""
    spec.option.cone = mujoco.mjtCone.mjCONE_PYRAMIDAL
    spec.option.noslip_iterations = 0
    spec.option.impratio = float(impratio)
    if max_contacts is not None:
        spec.add_numeric(name="max_contact_points", data=[float(max_contacts)])
    return spec


def _yaw_quat(angle: float) -> list[float]:
    return [math.cos(0.5 * angle), 0.0, 0.0, math.sin(0.5 * angle)]


def load_spec(path: str | Path | None = None) -> mujoco.MjSpec:
    """The robot MJCF (default `jaxloco/models/leggrope.xml`) as an MjSpec; SpecError (one line)
    for a missing or broken file."""
    return mjcf.load_spec(path if path is not None else MODEL_PATH)


def xml_text(params: LegGropeParams | None = None) -> str:
    return mjcf.xml_text(build_spec(params))


def main(argv: list[str] | None = None) -> None:
    mjcf.write_main(__doc__.splitlines()[0], MODEL_PATH, xml_text, argv)


if __name__ == "__main__":
    main()
