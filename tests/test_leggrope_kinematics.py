"""Leg kinematics of the leg-grope quadruped: closed form vs D-H vs MuJoCo's own
kinematics, Jacobians closed form vs autodiff, inverse kinematics, batching."""

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from jaxloco.robots.leggrope import kinematics
from jaxloco.robots.leggrope.params import default_params

P = default_params()
RNG = np.random.default_rng(0)
Q_SAMPLES = np.column_stack(
    [RNG.uniform(-1.2, 1.2, 40), RNG.uniform(-0.5, 1.2, 40), RNG.uniform(-2.8, -0.2, 40)]
)


def test_table1_masses_and_hips():
    assert float(P.total_mass) == pytest.approx(7.06, abs=1e-9)
    hips = np.asarray(P.hips())
    # L1 left-front, L2 right-front, L3 right-rear, L4 left-rear (clockwise from above)
    assert np.all(np.sign(hips[:, :2]) == [[1, 1], [1, -1], [-1, -1], [-1, 1]])
    np.testing.assert_allclose(np.abs(hips[:, :2]), [[0.145, 0.075]] * 4)


@pytest.mark.parametrize("leg", range(4))
def test_closed_form_equals_dh_chain(leg):
    for q in Q_SAMPLES:
        q = jnp.asarray(q)
        np.testing.assert_allclose(kinematics.foot_position(P, leg, q), kinematics.foot_position_dh(P, leg, q),
                                   atol=1e-12)


@pytest.mark.parametrize("leg", range(4))
def test_jacobian_closed_form_equals_autodiff(leg):
    for q in Q_SAMPLES:
        q = jnp.asarray(q)
        np.testing.assert_allclose(kinematics.foot_jacobian(P, leg, q), kinematics.foot_jacobian_autodiff(P, leg, q),
                                   atol=1e-12)


def test_jacobian_singular_at_straight_knee():
    q = jnp.array([0.3, 0.4, 0.0])  # theta_i3 = 0: the paper's singular configuration
    assert abs(float(jnp.linalg.det(kinematics.foot_jacobian(P, 0, q)))) < 1e-12
    q = jnp.array([0.3, 0.4, -1.5])
    assert abs(float(jnp.linalg.det(kinematics.foot_jacobian(P, 0, q)))) > 1e-4


def _mujoco_leg(leg: int) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """One leg built independently in MuJoCo: hinge z (yaw), then two hinges about -y
    (positive lifts), link lengths along x, a site at the toe and at each link middle."""
    l1, l2, l3 = (float(v) for v in P.link_lengths)
    hip = np.asarray(P.hips()[leg], float)
    mount = float(P.mount_angles()[leg])
    spec = mujoco.MjSpec()
    base = spec.worldbody.add_body(name="hip", pos=hip, quat=[np.cos(mount / 2), 0, 0, np.sin(mount / 2)])
    b1 = base.add_body(name="link1")
    b1.add_joint(name="j1", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 0, 1])
    b1.add_geom(size=[0.01, 0, 0], mass=0.03)
    b1.add_site(name="m1", pos=[l1 / 2, 0, 0])
    b2 = b1.add_body(name="link2", pos=[l1, 0, 0])
    b2.add_joint(name="j2", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, -1, 0])
    b2.add_geom(size=[0.01, 0, 0], mass=0.35)
    b2.add_site(name="m2", pos=[l2 / 2, 0, 0])
    b3 = b2.add_body(name="link3", pos=[l2, 0, 0])
    b3.add_joint(name="j3", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, -1, 0])
    b3.add_geom(size=[0.01, 0, 0], mass=0.25)
    b3.add_site(name="m3", pos=[l3 / 2, 0, 0])
    b3.add_site(name="toe", pos=[l3, 0, 0])
    model = spec.compile()
    return model, mujoco.MjData(model)


@pytest.mark.parametrize("leg", range(4))
def test_against_mujoco_kinematics(leg):
    model, data = _mujoco_leg(leg)
    for q in Q_SAMPLES:
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        toe = data.site("toe").xpos
        mids = np.stack([data.site(n).xpos for n in ("m1", "m2", "m3")])
        np.testing.assert_allclose(kinematics.foot_position(P, leg, jnp.asarray(q)), toe, atol=1e-12)
        np.testing.assert_allclose(kinematics.link_com_positions(P, leg, jnp.asarray(q)), mids, atol=1e-12)
        # translational Jacobian of the toe site
        jacp = np.zeros((3, model.nv))
        mujoco.mj_comPos(model, data)
        mujoco.mj_jacSite(model, data, jacp, None, model.site("toe").id)
        np.testing.assert_allclose(kinematics.foot_jacobian(P, leg, jnp.asarray(q)), jacp, atol=1e-12)


@pytest.mark.parametrize("leg", range(4))
def test_inverse_kinematics_round_trip(leg):
    for q in Q_SAMPLES:
        toe = kinematics.foot_position(P, leg, jnp.asarray(q))
        q_ik, reach = kinematics.inverse_kinematics(P, leg, toe)
        assert float(reach) > -1e-12
        np.testing.assert_allclose(kinematics.foot_position(P, leg, q_ik), toe, atol=1e-9)
        assert float(q_ik[2]) < 0  # knee-up branch


def test_inverse_kinematics_flags_unreachable_targets():
    hip = P.hips()[0]
    far = hip + jnp.array([0.5, 0.2, -0.1])
    q, reach = kinematics.inverse_kinematics(P, 0, far)
    assert float(reach) < 0 and bool(jnp.all(jnp.isfinite(q)))


def test_float32_and_vmap():
    qs = jnp.asarray(Q_SAMPLES)
    batched = jax.vmap(lambda q: kinematics.foot_position(P, 2, q))(qs)
    looped = jnp.stack([kinematics.foot_position(P, 2, q) for q in qs])
    np.testing.assert_allclose(batched, looped, atol=1e-14)
    P32 = P.astype(jnp.float32)
    f32 = jax.vmap(lambda q: kinematics.foot_position(P32, 2, q))(qs.astype(jnp.float32))
    assert f32.dtype == jnp.float32
    np.testing.assert_allclose(f32, batched, atol=1e-5)
