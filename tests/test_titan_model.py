"""TITAN XI MJCF model (`models/titan_xi.xml`): Table 1 mass and envelope, the file in
sync with its generator, leg IK against MuJoCo's forward kinematics, the tether actuators."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from jaxloco.robots.titan import kinematics, model, params
from jaxloco.sim import terrain as tr


def test_model_file_is_in_sync_with_the_generator():
    assert model.MODEL_PATH.read_text() == model.xml_text()


def test_mass_and_leg_length_follow_table_1():
    m = model.load_model()
    assert abs(m.body_subtreemass[m.body("body").id] - 7000.0) < 1e-6
    assert abs(kinematics.L1 + kinematics.L2 - params.LEG_LENGTH) < 1e-12
    assert (model.ROBOT_CONTYPE, model.ROBOT_CONAFFINITY) == (
        tr.ROBOT_CONTYPE,
        tr.ROBOT_CONAFFINITY,
    )
    assert (
        m.nu == 15
        and tuple(m.actuator(i).name for i in range(m.nu)) == model.ACTUATOR_NAMES
    )


def test_home_pose_envelope_is_about_table_1():
    """4.8 x 5.0 x 3.0 m (Table 1); the planner's neutral stance makes the footprint 0.3 m
    smaller (model.py), the height is exact."""
    m = model.load_model()
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_forward(m, d)
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for g in range(m.ngeom):
        centre, half = d.geom_xpos[g], _aabb_half(m, d, g)
        lo, hi = np.minimum(lo, centre - half), np.maximum(hi, centre + half)
    size = hi - lo
    assert abs(lo[2]) < 1e-3  # feet on the ground
    assert abs(size[2] - 3.0) < 0.02
    assert np.all(np.abs(size[:2] - np.array([4.8, 5.0])) < 0.35), size


def _aabb_half(m, d, g):
    """Half extents of the world axis-aligned box around geom g (sphere, capsule, box, cylinder)."""
    R = d.geom_xmat[g].reshape(3, 3)
    s = m.geom_size[g]
    t = m.geom_type[g]
    if t == mujoco.mjtGeom.mjGEOM_SPHERE:
        return np.full(3, s[0])
    if t == mujoco.mjtGeom.mjGEOM_CAPSULE:
        return np.abs(R[:, 2]) * s[1] + s[0]
    if t == mujoco.mjtGeom.mjGEOM_CYLINDER:
        return np.abs(R[:, 2]) * s[1] + s[0] * np.sqrt(
            np.maximum(0.0, 1 - R[:, 2] ** 2)
        )
    return np.abs(R) @ s[:3]


def test_leg_ik_matches_mujoco_forward_kinematics():
    """Random foot targets in the fan-shaped reachable areas (Fig. 3), foot 0.9-1.9 m
    below the pivots: the closed-form IK puts MuJoCo's foot site on the target."""
    m = model.load_model()
    d = mujoco.MjData(m)
    rng = np.random.default_rng(0)
    n = 400
    leg = rng.integers(0, 4, n)
    r = rng.uniform(kinematics.R_IN, kinematics.R_OUT, n)
    a = rng.uniform(-0.5 * kinematics.R_THETA, 0.5 * kinematics.R_THETA, n)
    z = rng.uniform(-1.9, -0.9, n)
    psi = kinematics.YAW0[leg] + a
    targets = kinematics.PIVOTS[leg] + np.stack([r * np.cos(psi), r * np.sin(psi), z], axis=1)
    q, reach = jax.vmap(kinematics.inverse_kinematics)(jnp.asarray(leg), jnp.asarray(targets))
    q = np.asarray(q)
    assert np.all(np.asarray(reach) > 0)
    assert np.all(
        np.asarray(jax.vmap(kinematics.in_reach_area)(jnp.asarray(leg), jnp.asarray(targets)))
    )
    adr = {
        (i, j): m.joint(f"{kinematics.LEG_NAMES[i]}_{jn}").qposadr[0]
        for i in range(4)
        for j, jn in enumerate(kinematics.JOINT_NAMES)
    }
    lo, hi = m.jnt_range[1:, 0], m.jnt_range[1:, 1]
    worst = 0.0
    for k in range(n):
        d.qpos[:] = m.qpos0
        d.qpos[:7] = [0, 0, 0, 1, 0, 0, 0]
        for j in range(3):
            d.qpos[adr[leg[k], j]] = q[k, j]
        mujoco.mj_kinematics(m, d)
        worst = max(
            worst,
            np.linalg.norm(d.site(f"{kinematics.LEG_NAMES[leg[k]]}_foot").xpos - targets[k]),
        )
        fk = np.asarray(kinematics.foot_position(int(leg[k]), jnp.asarray(q[k])))
        assert np.linalg.norm(fk - targets[k]) < 1e-9
    assert worst < 1e-5  # [m] (the MJCF stores 6 to 9 significant digits)
    assert np.all(q.min(0) > [lo[0], lo[1], lo[2]]) and np.all(
        q.max(0) < [hi[0], hi[1], hi[2]]
    )


def test_com_offset_matches_mujoco_subtree_com():
    """`kinematics.com_offset` (the planner's and executor's centre of mass with the legs'
    400 kg of moving links each) against MuJoCo's subtree centre of mass of the body, for
    random foot positions in the fans: the swinging leg moves it by centimetres."""
    m = model.load_model()
    d = mujoco.MjData(m)
    rng = np.random.default_rng(1)
    bid = m.body("body").id
    assert kinematics.total_mass() == m.body_subtreemass[bid]
    spread = []
    for _ in range(20):
        feet = kinematics.home_feet() + np.c_[rng.uniform(-0.6, 0.6, (4, 2)), rng.uniform(-0.3, 0.3, 4)]
        q, reach = kinematics.legs_inverse_kinematics(jnp.asarray(feet))
        assert np.all(np.asarray(reach) > 0)
        d.qpos[:] = m.qpos0
        d.qpos[:7] = [0, 0, 0, 1, 0, 0, 0]
        d.qpos[7:19] = np.asarray(q).reshape(-1)
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        com = np.asarray(kinematics.com_offset(jnp.asarray(feet)))
        np.testing.assert_allclose(com, d.subtree_com[bid], atol=1e-5)
        spread.append(com)
    assert np.ptp(np.asarray(spread)[:, :2], axis=0).max() > 0.03


def test_home_keyframe_matches_the_neutral_stance():
    m = model.load_model()
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_kinematics(m, d)
    feet = np.array([d.site(f"{leg}_foot").xpos for leg in kinematics.LEG_NAMES])
    assert np.allclose(feet[:, :2], np.asarray(params.NEUTRAL_FEET)[:, :2], atol=1e-4)
    assert np.allclose(feet[:, 2], kinematics.FOOT_RADIUS, atol=1e-4)


def test_tether_actuators_push_the_body_along_world_axes():
    """In zero gravity the tether ctrl (3,) [N] accelerates the body along the force in
    the WORLD frame whatever the body attitude (reference site in the world), by between
    F / M (rigid robot) and F / M_trunk (legs not yet following through their servos)."""
    m = model.load_model()
    m.opt.gravity[:] = 0.0
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    d.qpos[3:7] = [np.cos(0.3), 0.0, np.sin(0.3), 0.0]  # pitched by 0.6 rad
    force = np.array([3000.0, -1000.0, 2000.0])
    d.ctrl[12:] = force
    mujoco.mj_forward(m, d)
    acc = d.qacc[:3]  # free joint: linear acceleration of the body origin, world frame
    cos = acc @ force / np.linalg.norm(acc) / np.linalg.norm(force)
    assert cos > 0.999
    ratio = np.linalg.norm(acc) / (np.linalg.norm(force) / 7000.0)
    assert 1.0 <= ratio <= 7000.0 / model.TRUNK_MASS
