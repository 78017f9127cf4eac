"""T² Snake-3 MJCF model (`models/t2snake3.xml`): the file in sync with its generator,
Table I mass, joint ranges and dimensions, and the chain's forward kinematics
(`kinematics.link_frames`, `wheel_pairs`, `tip_from_head`) against MuJoCo's."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from jaxloco.robots.snake import kinematics, model, params
from jaxloco.sim import terrain as tr


def test_model_file_is_in_sync_with_the_generator():
    assert model.MODEL_PATH.read_text() == model.xml_text()


def test_mass_joints_and_wheels_follow_table_1():
    m = model.load_model()
    assert abs(m.body_subtreemass[m.body("link1").id] - 10.0) < 1e-9
    assert (model.ROBOT_CONTYPE, model.ROBOT_CONAFFINITY) == (
        tr.ROBOT_CONTYPE,
        tr.ROBOT_CONAFFINITY,
    )
    names = [f"theta{i}" for i in range(1, 10)] + [f"psi{i}" for i in range(1, 9)]
    assert sorted(params.JOINT_NAMES) == sorted(names)
    for name in names:
        lim = np.deg2rad(113.0 if name.startswith("psi") else 65.0)
        assert np.allclose(m.joint(name).range, [-lim, lim], atol=1e-5), name
        assert m.jnt_limited[m.joint(name).id]
    wheels = [
        m.geom(f"wheel{i}_{s}") for i in range(1, 10) for s in ("active", "passive")
    ]
    assert np.allclose([g.size[0] for g in wheels], 0.050)  # r = 50 mm
    assert m.nu == 17 + 9
    assert params.MODULE_LENGTH == 2 * params.LINK_LENGTH == 0.181 and params.N_MODULES == 9


def test_straight_pose_dimensions_follow_table_1():
    """Straight on z = 0: joints l = 90.5 mm apart (module 181 mm), gripper tip to tail
    1729 mm, wheels' outer faces 175 mm apart, all 18 wheels touch the ground."""
    m = model.load_model()
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("straight").id)
    mujoco.mj_kinematics(m, d)
    anchors = np.array([d.xanchor[m.joint(n).id] for n in params.JOINT_NAMES])
    assert np.allclose(np.diff(anchors[:, 0]), -0.0905, atol=1e-9)
    tail_end = d.xpos[m.body("link18").id][0] - params.LINK_LENGTH
    assert abs(d.site("tip").xpos[0] - tail_end - 1.729) < 1e-6
    ys = [
        d.geom(f"wheel{i}_{s}").xpos[1]
        for i in range(1, 10)
        for s in ("active", "passive")
    ]
    assert abs(max(ys) - min(ys) + 2 * params.WHEEL_HALF_WIDTH - 0.175) < 1e-9
    contacts = np.array([d.site(f"pair{i}_contact").xpos for i in range(1, 10)])
    assert np.allclose(contacts[:, 2], 0.0, atol=1e-9)
    # the only geoms reaching the ground are the wheels (links 10 mm clear)
    for g in range(m.ngeom):
        if not m.geom(g).name.startswith("wheel"):
            R = d.geom_xmat[g].reshape(3, 3)
            assert d.geom_xpos[g][2] - np.abs(R[2]) @ m.geom_size[g] > 0.009 or (
                m.geom_type[g] == mujoco.mjtGeom.mjGEOM_CAPSULE
            )


def test_base_pairs_1_3_5_are_wider_with_a_battery_beside_the_passive_wheel():
    """Sec. IV-A, reading (a) of `params`: the wheels of base pairs 1, 3, 5 (pairs 3, 5, 7
    of the model) are farther apart than the others', and a battery sits in the space
    between the link and the passive wheel, touching neither."""
    m = model.load_model()
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("straight").id)
    mujoco.mj_kinematics(m, d)
    track = {i: d.body(f"wheel{i}_active").xpos[1] - d.body(f"wheel{i}_passive").xpos[1] for i in range(1, 10)}
    wide = {int(k) + 1 for k in params.WIDE_PAIRS}
    assert wide == {int(params.BASE_PAIRS[k]) + 1 for k in (0, 2, 4)} == {3, 5, 7}
    assert min(track[i] for i in wide) > max(track[i] for i in set(track) - wide) + 0.015
    for i in range(1, 10):
        inner = 0.5 * track[i] - params.WHEEL_HALF_WIDTH  # the wheels' inner faces clear the links
        assert inner > params.LINK_HALF[1]
        if i in wide:
            g = m.geom(f"battery{i}")
            y = d.geom_xpos[g.id][1]
            assert -inner < y - g.size[1] and y + g.size[1] < -params.LINK_HALF[1] + 1e-12  # passive (right) side
            assert m.geom_contype[g.id] == 0
            assert m.body_mass[g.bodyid[0]] == pytest.approx(params.LINK_MASS + params.BATTERY_MASS, abs=1e-12)


def test_longer_pair_gaps_along_the_body_would_not_fit_table_1():
    """Reading (b) of Sec. IV-A (longer gaps *between* pairs 1-2, 3-4, 5-6 along the body)
    is not the model: Table I's nine 181 mm modules and the 90 mm gripper leave 10 mm of
    its 1729 mm length, less than one battery (`params` docstring)."""
    spare = params.SIZE_HWL[2] - params.N_MODULES * params.MODULE_LENGTH - params.GRIPPER_LENGTH
    assert spare == pytest.approx(0.010, abs=1e-9)
    assert 3 * 2 * params.BATTERY_HALF[0] > spare


def test_initial_keyframe_is_sec_5a_posture_with_the_base_on_the_ground():
    m = model.load_model()
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("initial").id)
    mujoco.mj_kinematics(m, d)
    z = np.array([d.site(f"pair{i}_contact").xpos[2] for i in range(1, 10)])
    assert np.allclose(z[params.BASE_PAIRS], 0.0, atol=1e-6)  # base pairs 1..7 grounded
    assert np.all(z[:2] > 0.2)  # head pairs lifted
    assert abs(d.qpos[m.joint("psi3").qposadr[0]] - 1.9) < 1e-12
    head_R = d.xmat[m.body("link1").id].reshape(3, 3)
    assert np.allclose(head_R, np.eye(3), atol=1e-5)  # -0.8 - 1.1 + 1.9 = 0: level head


def test_forward_kinematics_matches_mujoco():
    """Random head poses and joint angles within Table I's ranges: link frames, head,
    gripper tip, axle and contact sites agree with mj_kinematics."""
    m = model.load_model()
    d = mujoco.MjData(m)
    rng = np.random.default_rng(1)
    n = 20
    lim = np.where(params.JOINT_IS_PITCH, params.PITCH_LIMIT, params.YAW_LIMIT)
    joints = rng.uniform(-lim, lim, (n, params.N_JOINTS))
    w_h = np.concatenate(
        [rng.uniform(-1, 1, (n, 3)), rng.uniform(-1.2, 1.2, (n, 3))], axis=1
    )
    Rs, ps = jax.vmap(kinematics.link_frames)(jnp.asarray(w_h), jnp.asarray(joints))
    axle, contact, _ = jax.vmap(kinematics.wheel_pairs)(jnp.asarray(w_h), jnp.asarray(joints))
    tip = jax.vmap(kinematics.tip_from_head)(jnp.asarray(w_h))
    adr = [m.joint(name).qposadr[0] for name in params.JOINT_NAMES]
    for k in range(n):
        d.qpos[:] = m.qpos0
        d.qpos[:3] = w_h[k, :3]
        d.qpos[3:7] = model.rpy_to_quat(w_h[k, 3:])
        d.qpos[adr] = joints[k]
        mujoco.mj_kinematics(m, d)
        for j in range(params.N_LINKS):
            b = m.body(f"link{j + 1}").id
            assert np.allclose(d.xpos[b], ps[k, j], atol=1e-9)
            assert np.allclose(d.xmat[b].reshape(3, 3), Rs[k, j], atol=1e-9)
        assert np.allclose(d.site("tip").xpos, tip[k, :3], atol=1e-9)
        assert np.allclose(d.site("head").xpos, w_h[k, :3], atol=1e-9)
        for i in range(params.N_PAIRS):
            assert np.allclose(d.site(f"pair{i + 1}_axle").xpos, axle[k, i], atol=1e-9)
            assert np.allclose(
                d.site(f"pair{i + 1}_contact").xpos, contact[k, i], atol=1e-9
            )
