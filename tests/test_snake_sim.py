"""T² Snake-3 closed loop in MuJoCo (`jaxloco.robots.snake.scenarios`): wheel lifting by
the base pitch joints per Table II mode (kinematics, then held in MuJoCo), the actuator
command's ordering, the state geometry (slip, clearance, poses) against MuJoCo's own
site velocities, and driving straight at r rho_dot (native backend)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from jaxloco import geometry as geo
from jaxloco.robots.snake import kinematics, model, scenarios
from jaxloco.robots.snake import params as snake_params
from jaxloco.sim import terrain as tr
from jaxloco.sim.rollout import rollout

LIFT = 0.02


def _placed(phi, grounded, lift=LIFT):
    """Joint angles (17,) and head pose w_h (6,) of the commanded posture on the ground."""
    q = scenarios.joint_targets(jnp.asarray(phi), grounded, lift)
    pos, quat = scenarios.placed_head_pose(jnp.zeros(3), q, grounded, lift)
    return q, jnp.concatenate([pos, geo.matrix_to_rpy(tr.quat_to_matrix(quat))])


@pytest.mark.parametrize("bend", [0.0, 0.6])
def test_lift_angles_put_each_modes_wheels_at_their_heights(bend):
    """Every Table II mode, straight base (INITIAL_PHI) and a base bent +-0.6 rad: with
    link 7 on the ground, the axles of grounded pairs are at r, lifted ones at r +
    lift_height (exact); the link-fixed contact points of `kinematics.wheel_pairs` are
    within 0.7 mm of that; the head part keeps its attitude (level head, as without
    lifting, also in mode 6 where the first base segment tilts); jit + vmap over the
    modes equals the loop."""
    phi = np.array(snake_params.INITIAL_PHI)
    phi[snake_params.N_H:] = bend * np.array([1, -1, 1, -1, 1, -1])
    fn = jax.jit(jax.vmap(lambda g: scenarios.lift_angles(g, LIFT, phi[snake_params.N_H:])))
    psi_v, d3_v = fn(jnp.asarray(snake_params.MODES))
    for i, g in enumerate(snake_params.MODES):
        psi_b, d3 = scenarios.lift_angles(g, LIFT, phi[snake_params.N_H:])
        np.testing.assert_allclose(psi_v[i], psi_b, atol=1e-12)
        np.testing.assert_allclose(d3_v[i], d3, atol=1e-12)
        assert np.all(np.abs(psi_b) < 0.3)  # small pitch angles (Sec. II-A)
        q, w_h = _placed(phi, g)
        np.testing.assert_allclose(q[snake_params.PSI_B_JOINTS], psi_b, atol=1e-12)
        assert float(q[5]) == pytest.approx(phi[5] + float(d3), abs=1e-12)
        axle, contact, _ = kinematics.wheel_pairs(w_h, q)
        want = np.where(g, 0.0, LIFT)
        np.testing.assert_allclose(axle[snake_params.BASE_PAIRS, 2] - snake_params.WHEEL_RADIUS, want, atol=1e-9)
        np.testing.assert_allclose(contact[snake_params.BASE_PAIRS, 2], want, atol=7e-4)
        np.testing.assert_allclose(w_h[3:5], 0.0, atol=1e-9)  # the head stays level
    # mode 6 lifts pair 2: link 7 tilts, and psi_3 turns by as much the other way
    assert d3_v[5] > 0.1 and np.allclose(d3_v[:5], 0.0, atol=1e-12)


def test_actuator_command_follows_the_model_actuators():
    m = model.load_model()
    rng = np.random.default_rng(0)
    phi = rng.uniform(-0.5, 0.5, snake_params.N_PHI)
    rho = rng.uniform(-3, 3, snake_params.N_W)
    g = snake_params.MODES[0]
    ctrl = np.asarray(scenarios.actuator_command(phi, rho, g, LIFT))
    psi_b, d3 = scenarios.lift_angles(g, LIFT, phi[snake_params.N_H:])
    assert ctrl.shape == (m.nu,)
    names = [m.actuator(a).name for a in range(m.nu)]
    joint = dict(zip(snake_params.JOINT_NAMES, kinematics.full_joint_angles(phi, psi_b).at[5].add(d3), strict=True))
    for a, name in enumerate(names):
        if name.startswith("wheel"):
            i = int(name[5:]) - 1  # model pair
            want = rho[i - 2] if i >= 2 else 0.0  # base pairs 1..7 = model pairs 3..9
        else:
            want = joint[name]
        assert ctrl[a] == pytest.approx(float(want), abs=1e-12), name
    assert ctrl[m.actuator("psi3").id] == pytest.approx(phi[5] + float(d3))
    # jit / vmap over modes
    batched = jax.jit(jax.vmap(scenarios.actuator_command, in_axes=(None, None, 0, None)))(
        phi, rho, snake_params.MODES, LIFT
    )
    assert batched.shape == (snake_params.N_MODES, m.nu)


@pytest.mark.parametrize("twist", [0.0, 0.05])
def test_state_geometry_matches_mujoco_sites(twist):
    """Random state (pose, joints, velocities; on the twisting base the twist too):
    head / tip poses, wheel clearances and the pairs' lateral and rolling slip from
    `state_geometry` equal MuJoCo's site positions, frames and `mj_objectVelocity` of
    the contact sites."""
    m = model.load_model()
    if twist:
        spec = model.load_spec()
        scenarios.twisting_base(spec, twist)
        m = spec.compile()
        assert m.nq == model.load_model().nq + snake_params.N_B  # a twist hinge behind each base yaw joint
        for name in scenarios.TWIST_JOINTS:
            assert m.jnt_stiffness[m.joint(name).id] == pytest.approx(1 / twist)
    layout = scenarios.layout_of(m)
    assert ("twist_qpos" in layout) == bool(twist)
    d = mujoco.MjData(m)
    rng = np.random.default_rng(3)
    for _ in range(3):
        d.qpos[:] = m.qpos0
        d.qpos[:3] = rng.uniform(-1, 1, 3)
        d.qpos[3:7] = model.rpy_to_quat(rng.uniform(-0.4, 0.4, 3))
        for name in snake_params.JOINT_NAMES + (scenarios.TWIST_JOINTS if twist else ()):
            d.qpos[m.joint(name).qposadr[0]] = rng.uniform(-0.5, 0.5)
        d.qvel[:] = rng.normal(0, 1, m.nv)
        mujoco.mj_forward(m, d)
        g = scenarios.state_geometry(jnp.asarray(d.qpos), jnp.asarray(d.qvel), layout=layout)
        np.testing.assert_allclose(g["head"][:3], d.site("head").xpos, atol=1e-9)
        np.testing.assert_allclose(g["tip"][:3], d.site("tip").xpos, atol=1e-9)
        R = d.site("head").xmat.reshape(3, 3)
        np.testing.assert_allclose(geo.rpy_to_matrix(*g["head"][3:]), R, atol=1e-9)
        vel = np.zeros(6)
        for i in range(snake_params.N_PAIRS):
            site = d.site(f"pair{i + 1}_contact")
            mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_SITE, site.id, vel, 0)
            Rs = site.xmat.reshape(3, 3)
            assert g["slip"][i] == pytest.approx(vel[3:] @ Rs[:, 1], abs=1e-9)
            # active wheel: material point of the wheel at its contact, forward velocity
            body = m.body(f"wheel{i + 1}_active").id
            point = d.xpos[body] - snake_params.WHEEL_RADIUS * Rs[:, 2]
            jacp = np.zeros((3, m.nv))
            mujoco.mj_jac(m, d, jacp, None, point, body)
            assert g["roll_slip"][i] == pytest.approx((jacp @ d.qvel) @ Rs[:, 0], abs=1e-9)
            # clearance: lowest point of the two wheel cylinders
            low = []
            for side in ("active", "passive"):
                geom = d.geom(f"wheel{i + 1}_{side}")
                a = geom.xmat.reshape(3, 3)[:, 2]  # cylinder axis
                low.append(
                    geom.xpos[2]
                    - snake_params.WHEEL_RADIUS * np.sqrt(1 - a[2] ** 2)
                    - snake_params.WHEEL_HALF_WIDTH * abs(a[2])
                )
            assert g["clearance"][i] == pytest.approx(min(low), abs=1e-9)


# one rollout for the MuJoCo tests: 6 sims hold each mode, 3 drive straight
N_HOLD, DRIVE_RHO, DRIVE_MU = snake_params.N_MODES, np.array([2.0, -2.0, 4.0]), np.array([1.0, 0.5, 0.5])


@pytest.fixture(scope="module")
def closed_loop():
    sc = scenarios.snake_scenario(horizon_s=2.0, record_every=5)
    n = N_HOLD + len(DRIVE_RHO)
    params = scenarios.params_batch(
        n,
        mode=np.concatenate([np.arange(1, 7), [1, 1, 2]]),
        rho_dot=np.concatenate([np.zeros(N_HOLD), DRIVE_RHO]),
        mu=np.concatenate([np.ones(N_HOLD), DRIVE_MU]),
        lift_height=LIFT,
    )
    return sc, rollout(sc, params, nthread=2)


def test_each_mode_lifts_its_wheels_and_the_raised_robot_stays_upright(closed_loop):
    """Initial posture of Sec. V-A (head raised, psi_3 = 1.9 rad), each Table II mode held
    2 s: over the last second the lifted pairs' wheels are > 12 mm off the ground (20 mm
    commanded; the cantilevered tail of mode 2 sags most) and the grounded ones touch;
    the base stays flat and upright; the measured head pose equals the kinematics of the
    measured joint angles on a flat base (the head part sags under its servos: the
    steady error of Sec. IV-C2)."""
    sc, r = closed_loop
    late = r.times >= 1.0
    assert (r.status == "ok").all()
    for i, g in enumerate(snake_params.MODES):
        clear = r.records["clearance"][i][late][:, snake_params.BASE_PAIRS]
        assert clear[:, ~g].min() > 0.012, (i + 1, clear[:, ~g].min())
        assert np.abs(clear[:, g]).max() < 1e-3
        assert r.records["contact"][i][late].sum(-1).min() == g.sum()
        np.testing.assert_array_equal(r.records["contact"][i, -1], g)
        assert (r.records["clearance"][i][late][:, :2] > 0.15).all()  # head pairs up high
        base = r.records["base"][i, -1]
        assert abs(base[2] - snake_params.WHEEL_RADIUS) < 1e-3 and abs(base[3]) < 1e-3  # on the ground, no roll
        assert r.metrics["max_tilt"][i] < 0.13 and not r.metrics["fell"][i]
        assert np.abs(r.records["base"][i, -1, :2]).max() < 0.005  # stood still
        # head from the measured joints (base on the ground) = measured head
        q = jnp.asarray(r.records["joints"][i, -1])
        pos, quat = scenarios.placed_head_pose(jnp.asarray([base[0], base[1], base[5]]), q, g, LIFT)
        np.testing.assert_allclose(r.records["head"][i, -1, :3], pos, atol=2e-3)
        # the command was held: phi_cmd = INITIAL_PHI, base joints on target
        np.testing.assert_allclose(r.records["phi_cmd"][i, -1], snake_params.INITIAL_PHI)
        target = np.asarray(scenarios.joint_targets(snake_params.INITIAL_PHI, g, LIFT))
        np.testing.assert_allclose(r.records["joints"][i, -1, snake_params.N_H:], target[snake_params.N_H:], atol=0.03)
    # the head sags under its servos: below the commanded pose, nose down
    sag = r.records["head"][:N_HOLD, -1, 2] - float(_placed(snake_params.INITIAL_PHI, snake_params.MODES[0])[1][2])
    assert (sag < -0.005).all(), sag
    assert (r.records["head"][:N_HOLD, -1, 4] > 0.02).all(), r.records["head"][:N_HOLD, -1, 4]  # nose down


def test_driving_straight_at_r_rho_dot(closed_loop):
    """All base wheels at rho_dot in the straight posture (INITIAL_PHI): the base moves
    along its heading at r rho_dot (within 5 %), forwards and backwards, mu 0.5 and 1,
    in modes 1 and 2, without side slip or turning."""
    sc, r = closed_loop
    t = r.times
    a, b = np.searchsorted(t, 0.5), len(t) - 1
    for k, rho in enumerate(DRIVE_RHO):
        i = N_HOLD + k
        base = r.records["base"][i]
        v = (base[b, 0] - base[a, 0]) / (t[b] - t[a])
        assert v == pytest.approx(snake_params.WHEEL_RADIUS * rho, rel=0.05), (k, v)
        assert abs(base[b, 1]) < 0.01 and abs(base[b, 5]) < 0.02
        assert r.status[i] == "ok" and r.metrics["max_slip"][i] < 0.05
        np.testing.assert_allclose(r.records["rho_dot_cmd"][i, -1], rho)
    assert r.records["head"].shape == (len(r.status), sc.n_records, 6)
    assert r.records["slip"].shape == r.records["contact"].shape == (len(r.status), sc.n_records, snake_params.N_W)


def test_make_controller_switches_modes_in_the_papers_order():
    """A stateful policy through `make_controller`: modes 2, 3, ..., 6 for 0.5 s each
    (Sec. IV-C5's switching order), wheels at rest; at the end of each period the
    measured contacts are the commanded mode's grounded pairs, and the robot stays up."""

    def policy(p, k, obs):
        mode = 2 + (k // 25) % 5
        return k + 1, jnp.asarray(snake_params.INITIAL_PHI), jnp.zeros(snake_params.N_W), scenarios.mode_mask(mode)

    ctrl = scenarios.make_controller(lambda p, obs: jnp.zeros((), jnp.int32), policy, name="switch")
    sc = scenarios.snake_scenario(horizon_s=2.5, controller=ctrl)
    r = rollout(sc, scenarios.params_batch(1, mode=2), nthread=1)
    assert r.status[0] == "ok" and r.metrics["min_contacts"][0] >= 3
    for j, mode in enumerate(range(2, 7)):
        k = 25 * j + 24
        np.testing.assert_array_equal(r.records["grounded_cmd"][0, k], snake_params.MODES[mode - 1])
        np.testing.assert_array_equal(r.records["contact"][0, k], snake_params.MODES[mode - 1])
