"""The OCTOPUS MJCF: in sync with model.py, Table 3 mass and envelope, names and collision
bits, and short MuJoCo runs (drop and settle, crawler driving, flippers)."""

import mujoco
import numpy as np
import pytest

from jaxloco.errors import SpecError
from jaxloco.robots.octopus import model as octo_model
from jaxloco.robots.octopus import params
from jaxloco.sim import terrain


@pytest.fixture(scope="module")
def model():
    return octo_model.load_model()


def _world(friction=1.0):
    """The robot on a floor plane with the terrain collision bits (MuJoCo directly)."""
    spec = octo_model.load_spec()
    spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[20, 20, 0.1],
                            contype=terrain.TERRAIN_CONTYPE, conaffinity=terrain.TERRAIN_CONAFFINITY,
                            friction=[friction, 0.005, 0.0001])
    m = spec.compile()
    return m, mujoco.MjData(m)


def _yaw(quat):
    w, x, y, z = quat
    return np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def _up(quat):
    _, x, y, _ = quat
    return 1 - 2 * (x * x + y * y)  # z component of the body z axis


# ------------------------------------------------------------------ file and structure
def test_xml_in_sync_with_model_py():
    assert octo_model.MODEL_PATH.read_text() == octo_model.xml_text(), (
        "jaxloco/models/octopus.xml is stale: run "
        "python -m jaxloco.robots.octopus.model --write jaxloco/models/octopus.xml"
    )


def test_load_errors_are_one_line(tmp_path):
    with pytest.raises(SpecError, match="model file not found") as err:
        octo_model.load_spec(tmp_path / "missing.xml")
    assert "\n" not in str(err.value)
    bad = tmp_path / "bad.xml"
    bad.write_text("<mujoco><worldbody><body><geom type='nonsense'/></body></worldbody></mujoco>")
    with pytest.raises(SpecError, match="broken MJCF") as err:
        octo_model.load_model(bad)
    assert "\n" not in str(err.value)


def test_options_and_counts(model):
    assert model.opt.timestep == pytest.approx(0.002)
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    assert model.nu == 18 and model.ngeom < 60 and model.nv < 60


def test_names(model):
    assert [model.actuator(i).name for i in range(model.nu)] == list(params.ACTUATOR_NAMES)
    for arm in params.ARM_NAMES:
        for j in params.ARM_JOINTS + ("roller",):
            model.joint(f"{arm}_{j}")
        assert model.joint(f"{arm}_roller").type == mujoco.mjtJoint.mjJNT_BALL
        for j in params.ARM_JOINTS:
            assert model.sensor(f"{arm}_{j}_pos").type == mujoco.mjtSensor.mjSENS_JOINTPOS
            assert model.sensor(f"{arm}_{j}_torque").type == mujoco.mjtSensor.mjSENS_ACTUATORFRC
        model.site(f"{arm}_tip")
    for name in params.FLIPPER_NAMES:
        model.joint(name)
        model.site(f"{name}_tip")
        model.sensor(f"{name}_pos")
        model.sensor(f"{name}_torque")
    for side in ("l", "r"):
        for end in ("front", "rear"):
            model.site(f"crawler_{side}_{end}")
        for s in ("pos", "vel", "force"):
            model.sensor(f"crawler_{side}_{s}")
    for s in ("imu_quat", "imu_gyro", "imu_acc"):
        assert model.sensor(s).objid[0] == model.site("imu").id
    # the passive roller joints are unactuated
    actuated = {
        model.actuator_trnid[i, 0] for i in range(model.nu) if model.actuator_trntype[i] == mujoco.mjtTrn.mjTRN_JOINT
    }
    assert all(model.joint(f"{a}_roller").id not in actuated for a in params.ARM_NAMES)


def test_collision_bits_match_terrain(model):
    colliding = [g for g in range(model.ngeom) if model.geom_contype[g] or model.geom_conaffinity[g]]
    assert len(colliding) >= 30
    for g in colliding:
        assert (model.geom_contype[g], model.geom_conaffinity[g]) == (terrain.ROBOT_CONTYPE, terrain.ROBOT_CONAFFINITY)
        assert (
            model.geom_contype[g] & terrain.TERRAIN_CONAFFINITY and terrain.TERRAIN_CONTYPE & model.geom_conaffinity[g]
        )
    # no robot pair can collide
    for a in colliding:
        for b in colliding:
            assert not (model.geom_contype[a] & model.geom_conaffinity[b])
    assert (octo_model.ROBOT_CONTYPE, octo_model.ROBOT_CONAFFINITY) == (
        terrain.ROBOT_CONTYPE,
        terrain.ROBOT_CONAFFINITY,
    )


# ------------------------------------------------------------------ Table 3
def test_total_mass_100kg(model):
    assert model.body_subtreemass[model.body("chassis").id] == pytest.approx(params.TOTAL_MASS, abs=1e-9)


def _bbox(model, data):
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for g in range(model.ngeom):
        kind, size = model.geom_type[g], model.geom_size[g]
        c, R = data.geom_xpos[g], data.geom_xmat[g].reshape(3, 3)
        if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
            pts = np.stack([c - size[0], c + size[0]])
        elif kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
            a = R[:, 2] * size[1]
            pts = np.stack([c + a - size[0], c + a + size[0], c - a - size[0], c - a + size[0]])
        elif kind == mujoco.mjtGeom.mjGEOM_BOX:
            signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).T.reshape(-1, 3)
            pts = c + (signs * size[:3]) @ R.T
        else:
            raise AssertionError(f"unexpected geom type {kind}")
        lo, hi = np.minimum(lo, pts.min(0)), np.maximum(hi, pts.max(0))
    return lo, hi


def test_envelope_pose_bounding_box_is_table3(model):
    """1800 x 1100 x 1700 mm within 2% in the `envelope` keyframe (params.ENVELOPE_POSE:
    front arms straight up, rear arms stretched back, flippers level), standing on z = 0."""
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("envelope").id)
    mujoco.mj_kinematics(model, data)
    lo, hi = _bbox(model, data)
    assert lo[2] == pytest.approx(0.0, abs=1e-6)  # crawler bottom on the ground
    np.testing.assert_allclose(hi - lo, params.ENVELOPE, rtol=0.02)
    # height: rollers of the front arms at base height + l1 + l2 + roller radius
    assert hi[2] == pytest.approx(params.BASE_HEIGHT + params.L1 + params.L2 + params.ROLLER_RADIUS, abs=1e-6)


def test_home_pose_footprint(model):
    """Table 2 start pose: crawler bottoms and rollers on z = 0, COG low in the chassis."""
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    mujoco.mj_forward(model, data)
    lo, _ = _bbox(model, data)
    assert lo[2] == pytest.approx(0.0, abs=1e-5)
    for side in ("l", "r"):
        for end in ("front", "rear"):
            assert data.site(f"crawler_{side}_{end}").xpos[2] == pytest.approx(0.0, abs=1e-12)
    for name in params.FLIPPER_NAMES:
        assert data.site(f"{name}_tip").xpos[2] == pytest.approx(0.0, abs=1e-9)
    com = data.subtree_com[model.body("chassis").id]
    chassis_bottom = params.BASE_HEIGHT + octo_model.CHASSIS_Z - octo_model.CHASSIS_HALF[2]
    assert chassis_bottom < com[2] < params.BASE_HEIGHT  # inside the chassis height range


# ------------------------------------------------------------------ dynamics
def test_drop_and_settle_with_zero_commands():
    """Dropped from 5 cm in qpos0 (all joints 0: arms stretched forward) with ctrl = 0 (tracks
    stopped, servos holding 0): no divergence in 2 s, at rest on the crawlers, level."""
    m, d = _world()
    mujoco.mj_resetData(m, d)
    d.qpos[2] = params.BASE_HEIGHT + 0.05
    heights = []
    for _ in range(10):
        mujoco.mj_step(m, d, nstep=100)
        assert np.all(np.isfinite(d.qpos)) and np.all(np.isfinite(d.qvel))
        heights.append(d.qpos[2])
    assert np.abs(d.qvel).max() < 1e-3
    assert d.qpos[2] == pytest.approx(params.BASE_HEIGHT, abs=2e-3)  # on the wheels (small contact penetration)
    assert np.ptp(heights[-5:]) < 1e-4
    assert _up(d.qpos[3:7]) > 0.9999 and np.linalg.norm(d.qpos[:2]) < 2e-3
    assert max(abs(d.joint(n).qpos[0]) for n in params.FLIPPER_NAMES) < 0.02


def test_home_pose_settles_on_crawlers_and_rollers():
    m, d = _world()
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    d.qpos[2] += 0.02
    mujoco.mj_step(m, d, nstep=1000)
    assert np.abs(d.qvel).max() < 1e-3 and _up(d.qpos[3:7]) > 0.9999
    touching = {m.geom(d.contact[i].geom2).name for i in range(d.ncon)} | {
        m.geom(d.contact[i].geom1).name for i in range(d.ncon)
    }
    assert {f"{a}_roller" for a in params.ARM_NAMES} <= touching
    assert {f"wheel_{s}{k}" for s in "lr" for k in (1, params.MAIN_WHEELS)} <= touching
    # the arms carry part of the weight: the booms hold a torque
    assert all(abs(d.sensor(f"{a}_boom_torque").data[0]) > 1.0 for a in params.ARM_NAMES)


@pytest.mark.parametrize("speed", [0.063, -0.04])
def test_crawlers_drive_at_commanded_speed(speed):
    """Both tracks at `speed`: after 0.5 s the robot moves straight at that speed (within 5%)
    in the home pose, the rollers rolling along; the crawler encoders read the same travel."""
    m, d = _world()
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_step(m, d, nstep=200)
    d.ctrl[0] = d.ctrl[1] = speed
    mujoco.mj_step(m, d, nstep=250)
    x0, enc0, t0 = d.qpos[0], d.sensor("crawler_l_pos").data[0], d.time
    mujoco.mj_step(m, d, nstep=1000)
    v = (d.qpos[0] - x0) / (d.time - t0)
    assert v == pytest.approx(speed, rel=0.05)
    assert abs(d.qpos[1]) < 2e-3 and abs(_yaw(d.qpos[3:7])) < 5e-3
    travel = d.sensor("crawler_l_pos").data[0] - enc0
    assert travel == pytest.approx(d.qpos[0] - x0, rel=0.08)
    # the track: every wheel of a side turns at one rim speed
    radii = octo_model._wheel_radii()
    rims = [d.joint(n).qvel[0] * radii[n] for n in octo_model.wheel_names("l")]
    np.testing.assert_allclose(rims, np.mean(rims), atol=2e-3)


def test_speed_limited_to_table3():
    m, d = _world()
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    d.ctrl[0] = d.ctrl[1] = 0.2  # clamped to 63 mm/s by ctrlrange
    mujoco.mj_step(m, d, nstep=1000)
    assert d.qvel[0] <= params.CRAWLER_MAX_SPEED * 1.02


def test_skid_steer_turns_left():
    m, d = _world()
    mujoco.mj_resetData(m, d)
    d.qpos[2] = params.BASE_HEIGHT
    d.ctrl[0], d.ctrl[1] = -0.05, 0.05
    mujoco.mj_step(m, d, nstep=1000)
    assert _yaw(d.qpos[3:7]) > 0.15 and np.linalg.norm(d.qpos[:2]) < 0.05  # turns on the spot (skid)


def test_flipper_positive_angle_lifts_tip():
    m, d = _world()
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_step(m, d, nstep=100)
    for name in params.FLIPPER_NAMES:
        d.ctrl[m.actuator(name).id] = 0.6
    mujoco.mj_step(m, d, nstep=500)
    for name in params.FLIPPER_NAMES:
        assert d.joint(name).qpos[0] == pytest.approx(0.6, abs=0.02)
        assert d.site(f"{name}_tip").xpos[2] > 0.1
    assert _up(d.qpos[3:7]) > 0.999


def test_crawlers_and_flippers_climb_a_200mm_step():
    """The wheel-row tracks climb a 200 mm step (below the 250 mm flipper length that the paper
    gives as the crawler-only limit) with a scripted flipper sequence: front flippers raised
    1.2 rad while approaching at 63 mm/s, lowered to 0 at 0.3 rad/s once the front stalls
    at the edge. Arms held level (zero pose)."""
    h, edge = 0.2, 0.75
    spec = octo_model.load_spec()
    bits = {"contype": terrain.TERRAIN_CONTYPE, "conaffinity": terrain.TERRAIN_CONAFFINITY}
    spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[20, 20, 0.1], **bits)
    spec.worldbody.add_geom(name="step", type=mujoco.mjtGeom.mjGEOM_BOX, size=[1.5, 1.5, h / 2],
                            pos=[edge + 1.5, 0, h / 2], **bits)
    m = spec.compile()
    d = mujoco.MjData(m)
    qpos, ctrl = octo_model.pose_qpos_ctrl(m, np.zeros((4, 3)), [1.2, 1.2, 0.0, 0.0])
    d.qpos[:], d.ctrl[:] = qpos, ctrl
    d.ctrl[0] = d.ctrl[1] = params.CRAWLER_MAX_SPEED
    front = [m.actuator(n).id for n in params.FLIPPER_NAMES[:2]]
    lowering = False
    for _ in range(int(40.0 / m.opt.timestep)):
        mujoco.mj_step(m, d)
        lowering = lowering or (d.time > 3.0 and abs(d.qvel[0]) < 0.005)
        if lowering:
            d.ctrl[front] = max(0.0, d.ctrl[front[0]] - 0.3 * m.opt.timestep)
    assert np.all(np.isfinite(d.qpos))
    assert d.qpos[0] > edge + 0.5  # the whole robot is on the step
    assert d.qpos[2] == pytest.approx(h + params.BASE_HEIGHT, abs=0.01) and _up(d.qpos[3:7]) > 0.999


def _roller_drag_forces(roller=octo_model.add_roller):
    """A 10 kg stub on x / y slides (velocity servos, 0.1 m/s) and a free z slide, with a
    forearm pointing down and back at 45 deg (as on a placed arm) and the roller at its
    end on a floor (mu 0.8), dragged 0.3 m along y (about six roller turns), then 0.3 m
    along x. Returns the largest servo force [N] in the second half of each drag (the
    steady part) and the weight [N]."""
    spec = mujoco.MjSpec()
    spec.option.timestep = 0.002
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[5, 5, 0.1], contype=terrain.TERRAIN_CONTYPE,
                            conaffinity=terrain.TERRAIN_CONAFFINITY, friction=[0.8, 0.005, 0.0001])
    stub = spec.worldbody.add_body(name="stub", pos=[0, 0, 0.25])
    for name, axis in (("sx", [1, 0, 0]), ("sy", [0, 1, 0]), ("sz", [0, 0, 1])):
        stub.add_joint(name=name, type=mujoco.mjtJoint.mjJNT_SLIDE, axis=axis)
    stub.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.02, 0, 0], mass=10.0, contype=0, conaffinity=0)
    forearm = stub.add_body(name="forearm", euler=[0, 0.75 * np.pi, 0])  # its x axis down and back
    roller(forearm, "arm0", [0.3, 0, 0])
    for name in ("sx", "sy"):
        act = spec.add_actuator(name=name, target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        act.set_to_velocity(kv=2000.0)
    m = spec.compile()
    d = mujoco.MjData(m)
    weight = float(np.sum(m.body_mass) * 9.81)
    steady = []
    for act, n_steps in (("sy", 1500), ("sx", 1500)):
        d.ctrl[:] = 0.0
        d.ctrl[m.actuator(act).id] = 0.1
        forces = []
        for _ in range(n_steps):
            mujoco.mj_step(m, d)
            forces.append(abs(d.actuator_force[m.actuator(act).id]))
        assert d.ncon == 1  # the roller stays on the floor
        steady.append(max(forces[n_steps // 2:]))
    return steady, weight


def test_roller_rolls_every_way():
    """The passive roller rolls in both horizontal directions, also after several turns
    in one of them: dragging it takes a small fraction of the friction limit mu N."""
    (f_side, f_along), weight = _roller_drag_forces()
    assert f_side < 0.1 * 0.8 * weight
    assert f_along < 0.1 * 0.8 * weight


def _gimbal_roller(parent, arm, pos):
    """The roller as it was before 3 Dec 2026 (two nested hinges), for the test below."""
    roller = parent.add_body(name=f"{arm}_roller", pos=pos)
    for jname, axis in (("roller_a", [0, 0, 1]), ("roller_b", [0, 1, 0])):
        roller.add_joint(name=f"{arm}_{jname}", type=mujoco.mjtJoint.mjJNT_HINGE, axis=axis,
                         damping=octo_model.ROLLER_DAMPING, armature=octo_model.ROLLER_ARMATURE)
    roller.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[params.ROLLER_RADIUS, 0, 0], mass=params.MASS_ROLLER,
                    **octo_model.COLLIDE)
    return roller


def test_drag_test_sees_a_locked_roller():
    """The drag test can fail: the nested-hinge roller of before 3 Dec 2026 slides, at
    about mu N, in this forearm pose."""
    forces, weight = _roller_drag_forces(_gimbal_roller)
    assert max(forces) > 0.3 * 0.8 * weight
