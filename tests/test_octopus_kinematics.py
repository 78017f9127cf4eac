"""OCTOPUS kinematics and estimation: arm FK (Eqs. 1-6) vs the Table 1 D-H chain vs MuJoCo,
IK to the Table 2 points, terrain exploration (Cases 1-3, Eqs. 7-9), COG height (Eqs.
10-17) vs MuJoCo, travelled distance (Eq. 18), gradients and batching."""

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from jax.test_util import check_grads

from jaxloco import geometry as geo
from jaxloco.robots.octopus import kinematics as kin
from jaxloco.robots.octopus import model as octo_model
from jaxloco.robots.octopus import params

PR = params.default_params()
RNG = np.random.default_rng(7)
Q_SAMPLES = np.column_stack(
    [RNG.uniform(-3.0, 3.0, 30), RNG.uniform(-1.6, 1.2, 30), RNG.uniform(-0.4, 2.7, 30)]
)


@pytest.fixture(scope="module")
def mj():
    model = octo_model.load_model()
    return model, mujoco.MjData(model)


def _set_arms(model, data, qs, root_pos=(0.0, 0.0, 0.0), root_quat=(1.0, 0.0, 0.0, 0.0)):
    data.qpos[:] = model.qpos0
    data.qpos[:3] = root_pos
    data.qpos[3:7] = root_quat
    for k, arm in enumerate(params.ARM_NAMES):
        for j, joint in enumerate(params.ARM_JOINTS):
            data.qpos[model.joint(f"{arm}_{joint}").qposadr[0]] = qs[k][j]


# ------------------------------------------------------------------ forward kinematics
def test_arm_numbering_and_bases():
    bases = np.asarray(PR.arm_bases())
    # 1 LF, 2 RF, 3 LR, 4 RR (Table 2: P1 (+,+), P2 (+,-), P3 (-,+), P4 (-,-))
    np.testing.assert_array_equal(np.sign(bases[:, :2]), np.sign(params.TABLE2_INIT[:, :2]))
    np.testing.assert_allclose(np.abs(bases), [[0.25, 0.25, 0.0]] * 4)
    # Eqs. 4-6 for the left-front arm: x = m/2 + x', y = n/2 + y', z = z'
    q = jnp.array([0.3, 0.2, 0.9])
    local = kin.arm_tip_local(PR, q)
    np.testing.assert_allclose(kin.arm_tip(PR, 0, q), local + jnp.array([0.25, 0.25, 0.0]), atol=1e-15)


def test_zero_pose_and_eq3_reading():
    # theta = 0: arm stretched along +x, forearm d3 to the right, at boom-axis height
    np.testing.assert_allclose(
        kin.arm_tip_local(PR, jnp.zeros(3)), [params.L1 + params.L2, -params.D3, 0.0], atol=1e-15
    )
    # Eq. 3 as printed (-l1 cos t2) would not keep the boom end at distance l1 from the
    # boom axis; the sin reading does, for every boom angle.
    t2s = np.linspace(-1.5, 1.5, 7)
    ours = [
        float(jnp.linalg.norm(kin.arm_points(PR, 0, jnp.array([0.4, t2, 0.0]))[1] - PR.arm_bases()[0])) for t2 in t2s
    ]
    np.testing.assert_allclose(ours, np.hypot(params.L1, params.D3), atol=1e-14)
    printed = np.hypot(
        np.hypot(params.L1 * np.cos(t2s), params.D3), params.L1 * np.cos(t2s)
    )  # (x', y', z') with l2 = 0
    assert np.ptp(printed) > 0.3
    # boom > 0 lowers the endpoint (Eq. 28 pushes the body up with +Delta_E)
    assert float(kin.arm_tip_local(PR, jnp.array([0.0, 0.1, 0.0]))[2]) < 0


@pytest.mark.parametrize("arm", range(4))
def test_closed_form_equals_table1_dh_chain(arm):
    for q in Q_SAMPLES:
        q = jnp.asarray(q)
        frames = kin.arm_frames_mdh(PR, arm, q)
        np.testing.assert_allclose(frames[-1, :3, 3], kin.arm_tip(PR, arm, q), atol=1e-12)
        # joint 2 and 3 axes of the chain are -/+ y rotated by the swing: horizontal
        np.testing.assert_allclose(frames[2, 2, 2], 0.0, atol=1e-12)


@pytest.mark.parametrize("arm", range(4))
def test_fk_against_mujoco_sites(mj, arm):
    """The tip site of the MJCF (chassis at the origin: world = {R}) equals Eqs. 1-6, and the
    elbow body sits where `arm_points` says, for random joint angles."""
    model, data = mj
    name = params.ARM_NAMES[arm]
    dofs = [model.joint(f"{name}_{j}").dofadr[0] for j in params.ARM_JOINTS]
    for q in Q_SAMPLES:
        qs = np.zeros((4, 3))
        qs[arm] = q
        _set_arms(model, data, qs)
        mujoco.mj_kinematics(model, data)
        np.testing.assert_allclose(data.site(f"{name}_tip").xpos, kin.arm_tip(PR, arm, jnp.asarray(q)), atol=1e-9)
        np.testing.assert_allclose(data.body(f"{name}_forearm").xpos, kin.arm_points(PR, arm, jnp.asarray(q))[1],
                                   atol=1e-9)
        mujoco.mj_comPos(model, data)
        jacp = np.zeros((3, model.nv))
        mujoco.mj_jacSite(model, data, jacp, None, model.site(f"{name}_tip").id)
        np.testing.assert_allclose(jacp[:, dofs], kin.arm_jacobian(PR, arm, jnp.asarray(q)), atol=1e-9)


def test_fk_against_mujoco_with_moving_chassis(mj):
    """Sites expressed in the chassis frame equal Eqs. 1-6 for any chassis pose."""
    model, data = mj
    for s in range(5):
        rng = np.random.default_rng(s)
        quat = rng.normal(size=4)
        quat /= np.linalg.norm(quat)
        qs = Q_SAMPLES[5 * s:5 * s + 4]
        _set_arms(model, data, qs, root_pos=rng.normal(size=3), root_quat=quat)
        mujoco.mj_kinematics(model, data)
        R = data.body("chassis").xmat.reshape(3, 3)
        o = data.body("chassis").xpos
        tips = np.stack([R.T @ (data.site(f"{a}_tip").xpos - o) for a in params.ARM_NAMES])
        np.testing.assert_allclose(tips, kin.arm_tips(PR, jnp.asarray(qs)), atol=1e-9)
        # the IMU site is the {R} origin
        np.testing.assert_allclose(data.site("imu").xpos, o, atol=1e-12)


# ------------------------------------------------------------------ inverse kinematics
@pytest.mark.parametrize("table", ["init", "target"])
def test_table2_points_reachable_and_round_trip(mj, table):
    model, _ = mj
    points = jnp.asarray(params.TABLE2_INIT if table == "init" else params.TABLE2_TARGET)
    qs, margin = kin.inverse_kinematics_all(PR, points)
    assert bool(jnp.all(margin > 0.05)), margin  # at least 5 cm inside the workspace
    np.testing.assert_allclose(kin.arm_tips(PR, qs), points, atol=1e-10)
    for k, arm in enumerate(params.ARM_NAMES):
        for j, joint in enumerate(params.ARM_JOINTS):
            lo, hi = model.joint(f"{arm}_{joint}").range
            assert lo < float(qs[k, j]) < hi, (arm, joint, float(qs[k, j]))
    assert bool(jnp.all(qs[:, 2] > 0))  # elbow-up branch
    assert bool(jnp.all((qs[:, 1] > -0.6) & (qs[:, 1] < -0.3)))  # booms raised 0.3-0.6 rad


def test_home_keyframe_is_table2_start_pose(mj):
    model, data = mj
    qs, _ = kin.inverse_kinematics_all(PR, jnp.asarray(params.TABLE2_INIT))
    np.testing.assert_allclose(octo_model.home_arm_angles(), qs, atol=1e-6)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    mujoco.mj_kinematics(model, data)
    base = data.body("chassis").xpos
    tips = np.stack([data.site(f"{a}_tip").xpos - base for a in params.ARM_NAMES])
    np.testing.assert_allclose(tips, params.TABLE2_INIT, atol=2e-6)
    # rollers and crawler wheels touch the ground z = 0 together
    assert abs(base[2] - params.BASE_HEIGHT) < 1e-12
    np.testing.assert_allclose(
        [data.site(f"{a}_tip").xpos[2] for a in params.ARM_NAMES], params.ROLLER_RADIUS, atol=2e-6
    )


@pytest.mark.parametrize("arm", range(4))
def test_ik_round_trip_random(arm):
    qs = np.column_stack([RNG.uniform(-3.0, 3.0, 25), RNG.uniform(-1.2, 1.0, 25), RNG.uniform(0.2, 2.7, 25)])
    for q in qs:
        tip = kin.arm_tip(PR, arm, jnp.asarray(q))
        q_ik, margin = kin.inverse_kinematics(PR, arm, tip)
        assert float(margin) > -1e-12
        np.testing.assert_allclose(kin.arm_tip(PR, arm, q_ik), tip, atol=1e-9)


def test_ik_flags_unreachable():
    far = PR.arm_bases()[0] + jnp.array([1.0, 0.5, -0.5])
    q, margin = kin.inverse_kinematics(PR, 0, far)
    assert float(margin) < 0 and bool(jnp.all(jnp.isfinite(q)))
    near = PR.arm_bases()[0] + jnp.array([0.01, 0.0, -0.05])  # inside |l1 - l2| and d3
    q, margin = kin.inverse_kinematics(PR, 0, near)
    assert float(margin) < 0 and bool(jnp.all(jnp.isfinite(q)))


# ------------------------------------------------------------------ attitude
def test_attitude_and_level_rotation_match_eqs_12_to_16():
    rng = np.random.default_rng(3)
    for _ in range(10):
        yaw, pitch, roll = rng.uniform(-0.6, 0.6, 3)
        R = geo.rpy_to_matrix(roll, pitch, yaw)
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, np.asarray(R).ravel())
        a_p, a_r = kin.attitude_from_quat(jnp.asarray(quat))
        np.testing.assert_allclose([a_p, a_r], [-pitch, -roll], atol=1e-12)
        C = kin.level_rotation(a_p, a_r)
        # {C} = heading frame: R = Rz(yaw) C
        np.testing.assert_allclose(geo.rot_z(yaw) @ C, R, atol=1e-12)
        # Eq. 15 row by row
        p = jnp.asarray(rng.normal(size=3))
        sp, cp, sr, cr = np.sin(a_p), np.cos(a_p), np.sin(a_r), np.cos(a_r)
        eq15 = [
            cp * p[0] + sp * sr * p[1] - sp * cr * p[2],
            cr * p[1] + sr * p[2],
            sp * p[0] - cp * sr * p[1] + cp * cr * p[2],
        ]
        np.testing.assert_allclose(C @ p, eq15, atol=1e-12)
    # paper convention: A_P > 0 nose up, A_R > 0 left side down
    C = kin.level_rotation(0.2, 0.0)
    assert float((C @ jnp.array([1.0, 0, 0]))[2]) > 0
    C = kin.level_rotation(0.0, 0.2)
    assert float((C @ jnp.array([0, 1.0, 0]))[2]) < 0


# ------------------------------------------------------------------ terrain exploration
def _tips_on(height_fn, xy=params.TABLE2_INIT[:, :2]):
    xy = np.asarray(xy, float)
    z = np.array([height_fn(x, y) for x, y in xy])
    return jnp.asarray(np.column_stack([xy, z]))


def test_flat_terrain_is_case1():
    est = kin.explore_terrain(PR, jnp.asarray(params.TABLE2_INIT))
    assert int(est.case) == kin.CASE_FLAT
    np.testing.assert_allclose([est.pitch, est.roll, est.step_height], 0.0, atol=1e-14)
    # a level robot pitched on flat ground still sees flat terrain in {C}
    a_p, a_r = 0.2, -0.1
    C = kin.level_rotation(a_p, a_r)
    ground_c = _tips_on(lambda x, y: -0.6)
    tips_r = ground_c @ C  # C^T applied to each row
    est = kin.explore_terrain(PR, tips_r, a_p, a_r)
    assert int(est.case) == kin.CASE_FLAT
    np.testing.assert_allclose([est.pitch, est.roll, est.step_height], 0.0, atol=1e-12)


@pytest.mark.parametrize("layout", ["init", "target"])
@pytest.mark.parametrize("height", [0.1, 0.3, 0.4])
def test_upward_step_is_case2_and_h_est_is_its_height(layout, height):
    xy = (params.TABLE2_INIT if layout == "init" else params.TABLE2_TARGET)[:, :2]
    tips = _tips_on(lambda x, y: -0.433 + (height if x > 0 else 0.0), xy)
    est = kin.explore_terrain(PR, tips)
    assert int(est.case) == kin.CASE_UP
    assert float(est.step_height) == pytest.approx(height, abs=1e-12)
    np.testing.assert_allclose(est.diffs, [height, height], atol=1e-12)


def test_downward_step_is_case3():
    tips = _tips_on(lambda x, y: -0.433 - (0.2 if x > 0 else 0.0))
    est = kin.explore_terrain(PR, tips)
    assert int(est.case) == kin.CASE_DOWN
    assert float(est.step_height) == pytest.approx(-0.2, abs=1e-12)


@pytest.mark.parametrize(
    "height_fn",
    [
        lambda x, y: -0.433 + (0.6 if x > 0 else 0.0),  # too high: above sigma_2
        lambda x, y: -0.433 - (0.6 if x > 0 else 0.0),  # too deep: below -sigma_3
        lambda x, y: -0.433 + (0.2 if (x > 0 and y > 0) else 0.0),  # only one front arm up
        lambda x, y: -0.433 + (0.2 if x > 0 else 0.0) * (1.0 if y > 0 else -1.0),  # up left, down right
        lambda x, y: -0.433 + 0.5 * y,  # strong side slope: diagonal differences of both signs
    ],
)
def test_undetectable(height_fn):
    est = kin.explore_terrain(PR, _tips_on(height_fn))
    assert int(est.case) == kin.CASE_UNDETECTABLE


def test_twist_reads_flat():
    """The Case tests compare diagonal pairs (z1 - z4: LF - RR, z2 - z3: RF - LR with Table 2's
    numbering), so a twisted support (LF and RR up, RF and LR down) is 'flat' for them; the
    roll/pitch plane fit sees no tilt either (the twist is orthogonal to both)."""
    est = kin.explore_terrain(PR, _tips_on(lambda x, y: -0.433 + 0.15 * np.sign(x) * np.sign(y)))
    assert int(est.case) == kin.CASE_FLAT
    np.testing.assert_allclose(est.diffs, 0.0, atol=1e-12)


def test_case_thresholds():
    s = jnp.asarray(params.SIGMA)
    cases = [
        ((0.0, 0.049), kin.CASE_FLAT),
        ((0.051, 0.449), kin.CASE_UP),
        ((-0.051, -0.449), kin.CASE_DOWN),
        ((0.05, 0.05), kin.CASE_UNDETECTABLE),  # on the threshold: neither strict inequality
        ((0.1, 0.0), kin.CASE_UNDETECTABLE),
        ((0.46, 0.2), kin.CASE_UNDETECTABLE),
    ]
    for diffs, expected in cases:
        assert int(kin.terrain_case(jnp.asarray(diffs), s)) == expected, diffs
    # one call, fixed shape, batched
    batch = jax.vmap(lambda d: kin.terrain_case(d, s))(jnp.asarray([c[0] for c in cases]))
    assert batch.shape == (len(cases),) and batch.dtype == jnp.int32
    np.testing.assert_array_equal(batch, [c[1] for c in cases])


@pytest.mark.parametrize("layout", ["init", "target"])
def test_tilted_plane_pitch_and_roll(layout):
    """Rollers on a plane: (T_P, T_R) is the attitude of a robot resting on that plane, for
    asymmetric (init) and symmetric (target) layouts, robot level or tilted."""
    xy = (params.TABLE2_INIT if layout == "init" else params.TABLE2_TARGET)[:, :2]
    rng = np.random.default_rng(11)
    for _ in range(6):
        t_p, t_r = rng.uniform(-0.4, 0.4, 2)
        # plane through (0, 0, -0.5) whose normal is the z axis of a body with attitude (T_P, T_R)
        normal = np.asarray(kin.level_rotation(t_p, t_r) @ jnp.array([0.0, 0.0, 1.0]))
        tips = _tips_on(lambda x, y, n=normal: -0.5 - (n[0] * x + n[1] * y) / n[2], xy)
        est = kin.explore_terrain(PR, tips)
        np.testing.assert_allclose([est.pitch, est.roll], [t_p, t_r], atol=1e-12)
        # the same rollers seen from a robot with attitude (a_p, a_r): unchanged result
        a_p, a_r = rng.uniform(-0.3, 0.3, 2)
        tips_r = tips @ kin.level_rotation(a_p, a_r)
        est2 = kin.explore_terrain(PR, tips_r, a_p, a_r)
        np.testing.assert_allclose([est2.pitch, est2.roll], [t_p, t_r], atol=1e-12)
    # symmetric layout: the joint solve is Eq. 7 and corrected Eq. 8
    tips = _tips_on(lambda x, y: 0.1 * x - 0.2 * y, params.TABLE2_TARGET[:, :2])
    est = kin.explore_terrain(PR, tips)
    x, y, z = (np.asarray(tips)[:, i] for i in range(3))
    eq7 = (z[0] + z[1] - z[2] - z[3]) / (x[0] + x[1] - x[2] - x[3])
    eq8 = (z[0] + z[2] - z[1] - z[3]) / (y[0] + y[2] - y[1] - y[3])
    assert float(est.pitch) == pytest.approx(np.arctan(eq7), abs=1e-12)
    assert float(est.roll) == pytest.approx(-np.arctan(eq8 * np.cos(np.arctan(eq7))), abs=1e-12)


def test_robot_standing_on_slope_reads_its_own_attitude(mj):
    """MuJoCo: the home pose tilted as a rigid body (as if standing on a slope); the IMU
    quaternion and the arm encoders give T_P = A_P, T_R = A_R and the slope's case
    (tolerance 1e-5 rad: the keyframe angles are rounded to 1e-6 rad)."""
    model, data = mj
    qs = octo_model.home_arm_angles()
    # (z-up pitch, roll) -> expected case: nose up = uphill = Case 2, nose down = Case 3,
    # a strong side slope gives diagonal differences of both signs
    for pitch, roll, case in [(-0.2, 0.05, kin.CASE_UP), (0.15, 0.0, kin.CASE_DOWN), (0.0, 0.3, kin.CASE_UNDETECTABLE),
                              (0.02, -0.02, kin.CASE_FLAT)]:
        R = np.asarray(geo.rpy_to_matrix(roll, pitch, 0.3))
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, R.ravel())
        _set_arms(model, data, qs, root_quat=quat)
        mujoco.mj_forward(model, data)
        a = kin.attitude_from_quat(jnp.asarray(data.sensor("imu_quat").data))
        enc = jnp.asarray(
            [[data.sensor(f"{arm}_{j}_pos").data[0] for j in params.ARM_JOINTS] for arm in params.ARM_NAMES]
        )
        est = kin.explore_terrain(PR, kin.arm_tips(PR, enc), a[0], a[1])
        assert int(est.case) == case, (pitch, roll)
        np.testing.assert_allclose([est.pitch, est.roll], [-pitch, -roll], atol=1e-5)


# ------------------------------------------------------------------ COG height, distance
def test_cog_constant_matches_model(mj):
    model, data = mj
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    mujoco.mj_forward(model, data)
    cog = data.subtree_com[model.body("chassis").id] - data.body("chassis").xpos
    np.testing.assert_allclose(cog, params.COG_R, atol=1e-3)


def test_cog_height_kinematic_any_attitude(mj):
    """Eqs. 10-17 against MuJoCo for a rigidly tilted robot in the home pose: H equals the
    world height of the subtree COM above the rear rollers' lowest points (one radius below
    their centres). Exact up to the 1 mm rounding of params.COG_R (tolerance 1.5 mm)."""
    model, data = mj
    qs = octo_model.home_arm_angles()
    rng = np.random.default_rng(5)
    for _ in range(5):
        roll, pitch, yaw = rng.uniform(-0.4, 0.4, 3)
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, np.asarray(geo.rpy_to_matrix(roll, pitch, yaw)).ravel())
        _set_arms(model, data, qs, root_pos=rng.normal(size=3), root_quat=quat)
        mujoco.mj_forward(model, data)
        a = kin.attitude_from_quat(jnp.asarray(data.sensor("imu_quat").data))
        h = kin.cog_height(PR, kin.arm_tips(PR, jnp.asarray(qs)), a[0], a[1])
        rear = 0.5 * (data.site("arm3_tip").xpos + data.site("arm4_tip").xpos)
        com_z = data.subtree_com[model.body("chassis").id][2]
        expected = com_z - (rear[2] - params.ROLLER_RADIUS)
        assert float(h) == pytest.approx(expected, abs=1.5e-3)
        # per side (the climb's per-side adaptation): above each rear roller's lowest point
        sides = kin.cog_height_sides(PR, kin.arm_tips(PR, jnp.asarray(qs)), a[0], a[1])
        for k, site in enumerate(("arm3_tip", "arm4_tip")):
            assert float(sides[k]) == pytest.approx(com_z - (data.site(site).xpos[2] - params.ROLLER_RADIUS),
                                                    abs=1.5e-3)


def test_side_step_heights_are_each_sides_rise_and_average_to_h_est():
    """`side_step_heights`: the front EPRA's height above the rear one per side (level
    frame); their mean is Eq. 9's H_EST (`explore_terrain`). Contacts on a step 0.4 m high
    under the left side and 0.2 m under the right, the robot level and pitched."""
    tips = np.array(params.TABLE2_INIT, float)
    tips[[0, 1], 2] += [0.4, 0.2]
    for a_p, a_r in ((0.0, 0.0), (0.3, -0.1)):
        # the same ground points seen from a tilted robot: {R} = R^T {C}
        rot = np.asarray(kin.level_rotation(a_p, a_r))
        tips_r = jnp.asarray(tips @ rot)
        est = kin.explore_terrain(PR, tips_r, a_p, a_r)
        sides = np.asarray(kin.side_step_heights(est.tips_c))
        np.testing.assert_allclose(sides, [0.4, 0.2], atol=1e-9)
        assert float(est.step_height) == pytest.approx(sides.mean(), abs=1e-9)


def _floor_world():
    spec = octo_model.load_spec()
    spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[5, 5, 0.1], contype=2,
                            conaffinity=1)
    model = spec.compile()
    return model, mujoco.MjData(model)


def test_cog_height_on_flat_ground_equals_mujoco():
    """Robot dropped in the home pose and settled for 1 s on a plane: H from the sensors (IMU
    quaternion, arm encoders) equals MuJoCo's COM height. Tolerance 1.5 mm, from the error
    budget: params.COG_R is rounded to 1 mm (<= 0.5 mm) and fixed, as the paper assumes,
    while the loaded arms sag by up to 3.4 mrad (measured; < 0.2 mm of COG), and the
    rollers sink ~0.5 mm into the ground (contact softness), so the contact is not exactly
    one radius below their centres. Measured error: 0.5 mm."""
    model, data = _floor_world()
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    data.qpos[2] += 0.01
    mujoco.mj_step(model, data, nstep=500)
    a = kin.attitude_from_quat(jnp.asarray(data.sensor("imu_quat").data))
    enc = jnp.asarray([[data.sensor(f"{arm}_{j}_pos").data[0] for j in params.ARM_JOINTS] for arm in params.ARM_NAMES])
    h = kin.cog_height(PR, kin.arm_tips(PR, enc), a[0], a[1])
    com_z = data.subtree_com[model.body("chassis").id][2]
    assert float(h) == pytest.approx(com_z, abs=1.5e-3)
    assert float(h) == pytest.approx(params.BASE_HEIGHT + params.COG_R[2], abs=1.5e-3)  # 0.273 m


def test_travelled_distance_closed_form():
    n, step = 50, 0.063 * 0.02  # 50 periods of 0.02 s at 63 mm/s
    for pitch in (0.0, 0.3, -0.5):
        pitches = jnp.full(n, pitch)
        assert float(kin.travelled_distance(step, pitches)) == pytest.approx(n * step * np.cos(pitch), abs=1e-14)
    pitches = jnp.linspace(0.0, 0.6, n)
    lengths = jnp.linspace(0.001, 0.002, n)
    mask = jnp.arange(n) < 30
    expected = float(np.sum(np.asarray(lengths)[:30] * np.cos(np.asarray(pitches)[:30])))
    assert float(kin.travelled_distance(lengths, pitches, mask)) == pytest.approx(expected, abs=1e-14)
    s = 0.0
    for i in range(30):
        s = kin.travel_update(s, lengths[i], pitches[i])
    assert float(s) == pytest.approx(expected, abs=1e-14)


# ------------------------------------------------------------------ gradients, batching
def test_gradients():
    q = jnp.array([0.4, -0.3, 1.9])
    check_grads(lambda qq: kin.arm_tip(PR, 1, qq), (q,), order=2, modes=("fwd", "rev"))
    qs = jnp.asarray(octo_model.home_arm_angles())

    def h(qs, att):
        return kin.cog_height(PR, kin.arm_tips(PR, qs), att[0], att[1])

    check_grads(h, (qs, jnp.array([0.1, -0.05])), order=2, modes=("fwd", "rev"))
    # through the parameters too (e.g. for tuning l2)
    check_grads(lambda l2: kin.arm_tip(PR.with_(l2=l2), 2, q), (jnp.asarray(0.68),), order=1)
    check_grads(lambda t: kin.inverse_kinematics(PR, 0, t)[0], (jnp.asarray(params.TABLE2_TARGET[0]),), order=1)
    tips = jnp.asarray(params.TABLE2_INIT) + jnp.array([[0.0, 0.0, 0.1], [0.0, 0.0, 0.12], [0, 0, 0], [0, 0, 0.01]])
    check_grads(lambda t: jnp.stack(kin.explore_terrain(PR, t, 0.1, 0.05)[1:4]), (tips,), order=1)


def test_vmap_equals_loop_and_jit():
    qs = jnp.asarray(Q_SAMPLES[:12].reshape(3, 4, 3))
    batched = jax.vmap(lambda q: kin.arm_tips(PR, q))(qs)
    looped = jnp.stack([jnp.stack([kin.arm_tip(PR, k, q[k]) for k in range(4)]) for q in qs])
    np.testing.assert_allclose(batched, looped, atol=1e-14)
    ik_b = jax.vmap(lambda t: kin.inverse_kinematics_all(PR, t)[0])(batched)
    ik_l = jnp.stack([jnp.stack([kin.inverse_kinematics(PR, k, t[k])[0] for k in range(4)]) for t in batched])
    np.testing.assert_allclose(ik_b, ik_l, atol=1e-12)
    atts = jnp.asarray([[0.0, 0.0], [0.1, -0.2], [-0.3, 0.05]])
    explore = jax.jit(jax.vmap(lambda t, a: kin.explore_terrain(PR, t, a[0], a[1])))
    est_b = explore(batched, atts)
    for i in range(3):
        est = kin.explore_terrain(PR, batched[i], atts[i, 0], atts[i, 1])
        for field_b, field in zip(est_b, est):
            np.testing.assert_allclose(field_b[i], field, atol=1e-12)
    h_b = jax.jit(jax.vmap(lambda t, a: kin.cog_height(PR, t, a[0], a[1])))(batched, atts)
    h_l = [kin.cog_height(PR, batched[i], atts[i, 0], atts[i, 1]) for i in range(3)]
    np.testing.assert_allclose(h_b, h_l, atol=1e-14)
    # float32 keeps its dtype
    P32 = PR.astype(jnp.float32)
    f32 = kin.arm_tips(P32, qs[0].astype(jnp.float32))
    assert f32.dtype == jnp.float32
    np.testing.assert_allclose(f32, batched[0], atol=1e-5)


# ------------------------------------------------------------------ crawler side profile
@pytest.mark.parametrize("pitch, rear", [(0.3, 0.0), (0.65, 0.045), (0.6, -0.83), (0.9, -0.4), (0.2, 0.1)])
def test_front_axle_height_on_rear_tips_against_mujoco(mj, pitch, rear):
    """The closed form against the MJCF: the chassis pitched nose-up, the rear flippers
    set, the floor put under the rear tip wheels (their lowest point). To 1 um: the MJCF
    prints its positions to 8 digits."""
    model, data = mj
    data.qpos[:] = model.qpos0
    data.qpos[3:7] = [np.cos(-pitch / 2), 0.0, np.sin(-pitch / 2), 0.0]  # nose up: about -y
    for name in ("flipper_rl", "flipper_rr"):
        data.qpos[model.joint(name).qposadr[0]] = rear
    mujoco.mj_kinematics(model, data)
    tip = f"flipper_rl_w{params.FLIPPER_WHEELS}"
    tip_r = model.geom(tip).size[0]
    floor = data.xpos[model.body(tip).id][2] - tip_r
    left = ("wheel_l", "flipper_fl_w", "flipper_rl_w")
    wheels = [b for b in range(model.nbody) if model.body(b).name.startswith(left)]
    lowest = min(data.xpos[b][2] - model.geom(model.body(b).name).size[0] for b in wheels)
    assert lowest == pytest.approx(floor, abs=1e-6)  # the tip wheel touches the floor first
    front = data.xpos[model.body(f"wheel_l{params.MAIN_WHEELS}").id][2] - floor
    np.testing.assert_allclose(kin.front_axle_height_on_rear_tips(pitch, rear), front, atol=1e-6)
    rear_axle = data.xpos[model.body("wheel_l1").id][2] - floor
    np.testing.assert_allclose(kin.rear_axle_height_on_rear_tips(pitch, rear), rear_axle, atol=1e-6)
    np.testing.assert_allclose(kin.rear_axle_height_to_mount(front - params.MAIN_WHEEL_RADIUS, pitch), rear_axle,
                               atol=1e-6)


def test_mount_pitch_solves_the_front_axle_height():
    h = 0.4
    rears = jnp.array([0.0, -0.3, -0.6, -0.83, -1.2])
    pitch = kin.mount_pitch_on_rear_tips(h, rears)
    np.testing.assert_allclose(jax.vmap(kin.front_axle_height_on_rear_tips)(pitch, rears),
                               h + params.MAIN_WHEEL_RADIUS, atol=1e-12)
    for p, a in zip(pitch, rears):  # the least such pitch: 0.01 rad less falls short
        assert kin.front_axle_height_on_rear_tips(p - 0.01, a) < h + params.MAIN_WHEEL_RADIUS
    # the in-line flippers need 0.81 rad; straight down in the world (a = -0.83) 0.62, the
    # least over a; at the joint limit no pitch reaches the 400 mm top
    np.testing.assert_allclose(pitch[0], 0.8095, atol=1e-4)
    assert float(jnp.min(pitch)) == pytest.approx(float(pitch[3]), abs=1e-12) and 0.61 < pitch[3] < 0.62
    assert np.isnan(kin.mount_pitch_on_rear_tips(h, -params.FLIPPER_LIMIT))
    check_grads(lambda a: kin.mount_pitch_on_rear_tips(h, a), (jnp.asarray(-0.5),), order=1)


def _pose_on_rear_tips(model, data, pitch, rear):
    """The Table 2 start pose (`home`), the chassis pitched nose-up by `pitch` [rad], the
    rear flippers at `rear` [rad]; positions and the subtree COMs computed."""
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    data.qpos[3:7] = [np.cos(-pitch / 2), 0.0, np.sin(-pitch / 2), 0.0]  # nose up: about -y
    for name in ("flipper_rl", "flipper_rr"):
        data.qpos[model.joint(name).qposadr[0]] = rear
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)


@pytest.mark.parametrize("rear", [0.0, -0.4, -0.6, -0.83])
def test_tipping_pitch_puts_mujocos_com_over_the_rear_tips(mj, rear):
    """At the closed form's pitch the whole robot's centre of mass (MuJoCo, the Table 2
    start pose) stands over the rear tip wheels: found by bisection on MuJoCo's COM. To
    0.015 rad: the closed form keeps the COG of the in-line flippers, and turning the
    rear ones down moves it by millimetres."""
    model, data = mj
    tip = model.body(f"flipper_rl_w{params.FLIPPER_WHEELS}").id

    def com_ahead(pitch):
        _pose_on_rear_tips(model, data, pitch, rear)
        return data.subtree_com[model.body("chassis").id][0] - data.xpos[tip][0]

    lo, hi = 0.0, 1.5
    assert com_ahead(lo) > 0 > com_ahead(hi)
    for _ in range(40):
        lo, hi = ((lo + hi) / 2, hi) if com_ahead((lo + hi) / 2) > 0 else (lo, (lo + hi) / 2)
    assert float(kin.tipping_pitch_on_rear_tips(rear)) == pytest.approx(lo, abs=0.015)


def test_cog_lead_over_the_edge_against_mujoco(mj):
    """On its rear flipper tips and a 400 mm edge the COG stays 0.24 m behind the edge at
    best. Checked at the returned pose against the MJCF: the floor under the rear tip
    wheel, the edge where the main wheels' lower tangent is 400 mm up (between the end
    axles) and MuJoCo's whole-robot COM (the Table 2 start pose; to 0.015 m, as the
    tipping pitch: the flippers' own mass moves it)."""
    h = 0.4
    lead, rear, pitch = (float(v) for v in kin.cog_lead_over_edge_on_rear_tips(h))
    assert -0.25 < lead < -0.23 and pitch <= float(kin.tipping_pitch_on_rear_tips(rear)) + 1e-12
    model, data = mj
    _pose_on_rear_tips(model, data, pitch, rear)
    tip = f"flipper_rl_w{params.FLIPPER_WHEELS}"
    floor = data.xpos[model.body(tip).id][2] - model.geom(tip).size[0]
    first, last = (data.xpos[model.body(f"wheel_l{k}").id] for k in (1, params.MAIN_WHEELS))
    axis = (last - first) / np.linalg.norm(last - first)
    below = np.array([axis[2], 0.0, -axis[0]])  # the belly's normal, pointing down (x-z plane)
    s = (floor + h - (first[2] + params.MAIN_WHEEL_RADIUS * below[2])) / axis[2]  # along the belly to height h
    assert 0.0 <= s <= np.linalg.norm(last - first)
    edge_x = first[0] + params.MAIN_WHEEL_RADIUS * below[0] + s * axis[0]
    com_x = data.subtree_com[model.body("chassis").id][0]
    assert com_x - edge_x == pytest.approx(lead, abs=0.015)


def test_cog_lead_does_not_grow_with_a_longer_crawler_and_passes_with_the_cog_far_forward():
    """The bound is set by the rear axle's height (the 250 mm flippers): longer main
    crawlers leave it as it is; on a much shorter one the edge never gets under the belly
    (-inf). The COG 0.5 m ahead of the rear axle (beyond the crawler's front end) would
    pass the edge, 0.45 m would not."""
    h, base = 0.4, kin.CrawlerProfile()
    lead = float(kin.cog_lead_over_edge_on_rear_tips(h, base)[0])
    for longer in (0.42, 0.52):
        assert float(kin.cog_lead_over_edge_on_rear_tips(h, base._replace(axle_spacing=longer))[0]) == \
            pytest.approx(lead, abs=1e-12)
    assert float(kin.cog_lead_over_edge_on_rear_tips(h, base._replace(axle_spacing=0.15))[0]) == -np.inf
    assert float(kin.cog_lead_over_edge_on_rear_tips(h, base._replace(cog_x=0.50))[0]) > 0.0
    assert float(kin.cog_lead_over_edge_on_rear_tips(h, base._replace(cog_x=0.45))[0]) < 0.0
    # a lower step is within reach: on 200 mm the COG passes the edge (the crawler-only limit is 250 mm)
    assert float(kin.cog_lead_over_edge_on_rear_tips(0.2, base)[0]) > 0.0
