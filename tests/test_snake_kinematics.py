"""T² Snake-3 velocity constraints (Eqs. 2-11, Table II modes): shapes and block
structure, rank per mode, modes as data (vmap == loop), and the no-slip meaning checked
in MuJoCo: a generalized velocity in a mode's null space moves the model with no side
slip at any grounded wheel (mj_jac at the wheel contact points), one outside it slips."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from jaxloco import geometry as geo
from jaxloco.robots.snake import kinematics, model, params

MODES = np.asarray(params.MODES)
ALL_GROUNDED = np.ones(params.N_PAIRS_BASE, bool)
_C = jax.jit(kinematics.constraint_on_velocity, static_argnames="point")
_AUG = jax.jit(kinematics.augmented_matrices, static_argnames="point")
# jitted: one program each, not one per operation (~20 ms each in a new process)
_CONSTRAINTS = jax.jit(kinematics.constraint_matrices)
_BASE_POSE = jax.jit(kinematics.base_frame_pose)
_TIP = jax.jit(kinematics.tip_from_head)


def _config(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Random head-raising posture, base flat on the ground: (w_h, phi)."""
    rng = np.random.default_rng(seed)
    phi = params.INITIAL_PHI + rng.uniform(-0.3, 0.3, params.N_PHI)
    phi[params.N_H :] = rng.uniform(-0.7, 0.7, params.N_B)  # bent base
    base = np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-3, 3)])
    w_h = np.asarray(_BASE_POSE(jnp.asarray(base), jnp.asarray(phi)))
    return w_h, phi


def _null_space(C: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    _, s, vt = np.linalg.svd(C)
    rank = int(np.sum(s > tol * s[0]))
    return vt[rank:].T


def test_shapes_and_block_structure():
    w_h, phi = _config(0)
    w = np.asarray(_TIP(jnp.asarray(w_h)))
    A, B = _CONSTRAINTS(jnp.asarray(w), jnp.asarray(phi))
    assert A.shape == (17, 6) and B.shape == (
        17,
        19,
    )  # (n_b+n_w+4) x 6, x (n_h+n_b+n_w)
    B = np.asarray(B)
    assert np.all(B[:10, 12:] == 0)  # Eq. 6: side slip and plane rows have no rho_dot
    assert np.allclose(B[10:, 12:], params.WHEEL_RADIUS * np.eye(7))  # rolling: r rho_dot
    At, Bt = _AUG(jnp.asarray(w), jnp.asarray(phi), jnp.asarray(MODES[0]))
    At, Bt = np.asarray(At), np.asarray(Bt)
    assert At.shape == (18, 7) and Bt.shape == (18, 19)
    assert np.array_equal(At[17], [0, 0, 0, 0, 0, 0, 1]) and np.all(At[:17, 6] == 0)
    assert np.array_equal(Bt[17], np.eye(19)[5])  # S selects psi_3 = phi[5]
    # Table II mode 1 lifts pairs 3 and 6: their side-slip and rolling rows are zero
    lifted = [2, 5, 10 + 2, 10 + 5]
    assert np.all(At[lifted] == 0) and np.all(Bt[lifted] == 0)
    # compacted to the paper's shapes (Eqs. 8, 10, 11): 13 + m rows
    assert kinematics.compact_rows(At, MODES[0], extra=1).shape == (14, 7)
    assert kinematics.compact_rows(Bt, MODES[0], extra=1).shape == (14, 19)
    assert kinematics.compact_rows(np.asarray(A), MODES[0]).shape == (13, 6)


@pytest.mark.parametrize("seed", [0, 1])
def test_rank_per_mode(seed):
    """Every mode of Table II lifts 2 pairs: 13 independent rows, redundancy
    19 - 13 = 6 = n_h + n_bar + n_tilde - 4; all grounded: 17. A_tilde has full
    column rank (not singular), as Eq. 15 needs."""
    w_h, phi = _config(seed)
    w = _TIP(jnp.asarray(w_h))
    C_all = np.asarray(_C(w, jnp.asarray(phi), jnp.asarray(ALL_GROUNDED)))
    assert np.linalg.matrix_rank(C_all) == 17
    for sigma in range(params.N_MODES):
        g = jnp.asarray(MODES[sigma])
        C = np.asarray(_C(w, jnp.asarray(phi), g))
        At, Bt = (np.asarray(x) for x in _AUG(w, jnp.asarray(phi), g))
        assert np.linalg.matrix_rank(C) == 13
        assert np.linalg.matrix_rank(At[:, :6][:17]) == 6
        assert np.linalg.matrix_rank(At) == 7
        assert np.linalg.matrix_rank(Bt) == 14  # 13 + the SCP row
        assert 19 - np.linalg.matrix_rank(C[:, 6:]) == params.N_H + 2 + 2 - 4


def test_modes_are_data_vmap_equals_loop():
    w_h, phi = _config(2)
    w, phi = _TIP(jnp.asarray(w_h)), jnp.asarray(phi)
    f = jax.jit(jax.vmap(lambda g: kinematics.augmented_matrices(w, phi, g)))
    At_v, Bt_v = f(jnp.asarray(MODES))
    for sigma in range(params.N_MODES):
        At, Bt = _AUG(w, phi, jnp.asarray(MODES[sigma]))
        assert np.allclose(At_v[sigma], At, atol=1e-12)
        assert np.allclose(Bt_v[sigma], Bt, atol=1e-12)
    assert not np.allclose(Bt_v[0], Bt_v[1])


def _mujoco_state(m, d, w_h, phi):
    d.qpos[:] = m.qpos0
    d.qpos[:3] = w_h[:3]
    d.qpos[3:7] = model.rpy_to_quat(w_h[3:])
    joints = np.asarray(kinematics.full_joint_angles(jnp.asarray(phi)))
    for k, name in enumerate(params.JOINT_NAMES):
        d.qpos[m.joint(name).qposadr[0]] = joints[k]
    mujoco.mj_kinematics(m, d)
    mujoco.mj_comPos(m, d)


def _qvel(m, w_h, wdot_h, phidot, rhodot):
    """MuJoCo qvel of (head pose rate, phi_dot, rho_dot of the base's active wheels)."""
    rpy = jnp.asarray(w_h[3:])
    R = np.asarray(geo.rpy_to_matrix(*rpy))
    dR = np.asarray(jax.jacfwd(lambda a: geo.rpy_to_matrix(a[0], a[1], a[2]))(rpy))
    Wx = np.einsum("ijk,k->ij", dR, wdot_h[3:]) @ R.T
    omega = np.array([Wx[2, 1], Wx[0, 2], Wx[1, 0]])
    qvel = np.zeros(m.nv)
    qvel[:3] = wdot_h[:3]
    qvel[3:6] = R.T @ omega  # free joint: angular velocity in the body frame
    for i, k in enumerate(params.PHI_JOINTS):
        qvel[m.joint(params.JOINT_NAMES[k]).dofadr[0]] = phidot[i]
    for i, pair in enumerate(params.BASE_PAIRS):
        qvel[m.joint(f"wheel{pair + 1}_active").dofadr[0]] = rhodot[i]
    return qvel


def _contact_velocities(m, d, qvel):
    """Per pair (9) and side (active, passive): velocity of the wheel's material point
    at the ground contact in the carrying link's axes (forward, lateral, up)."""
    out = np.zeros((params.N_PAIRS, 2, 3))
    jacp, jacr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
    for i in range(params.N_PAIRS):
        R = d.xmat[m.body(f"link{params.PAIR_LINKS[i]}").id].reshape(3, 3)
        for s, side in enumerate(("active", "passive")):
            b = m.body(f"wheel{i + 1}_{side}").id
            point = d.xpos[b] - params.WHEEL_RADIUS * R[:, 2]
            mujoco.mj_jac(m, d, jacp, jacr, point, b)
            out[i, s] = R.T @ (jacp @ qvel)
    return out


@pytest.mark.parametrize("point", ["head", "tip"])
def test_null_space_velocity_moves_the_robot_without_side_slip(point):
    """For each mode: random velocities (w_dot, u) in the null space of C_sigma make
    every grounded wheel contact of the MuJoCo model move with zero lateral and zero
    vertical velocity, and the grounded active wheels roll without slip; a velocity
    outside the null space slips sideways at some grounded wheel."""
    m = model.load_model()
    d = mujoco.MjData(m)
    rng = np.random.default_rng(3)
    to_head = jax.jit(jax.jacfwd(kinematics.head_from_tip))
    for seed in (4, 5):
        w_h, phi = _config(seed)
        _mujoco_state(m, d, w_h, phi)
        w = w_h if point == "head" else np.asarray(_TIP(jnp.asarray(w_h)))
        J = np.eye(6) if point == "head" else np.asarray(to_head(jnp.asarray(w)))
        for sigma in range(params.N_MODES):
            grounded = MODES[sigma]
            C = np.asarray(
                _C(jnp.asarray(w), jnp.asarray(phi), jnp.asarray(grounded), point=point)
            )
            N = _null_space(C)
            assert N.shape[1] == 25 - 13
            v = N @ rng.normal(size=N.shape[1])
            v /= np.abs(v).max()
            qvel = _qvel(m, w_h, J @ v[:6], v[6:18], v[18:])
            vel = _contact_velocities(m, d, qvel)[params.BASE_PAIRS]  # (7, 2, 3)
            g = grounded
            assert np.abs(vel[g][:, :, 1]).max() < 1e-9  # no side slip
            assert np.abs(vel[g][:, :, 2]).max() < 1e-9  # base stays on the plane
            assert np.abs(vel[g][:, 0, 0]).max() < 1e-9  # active wheels roll
            # the lifted pairs are free to slide: in general they do
            assert np.abs(vel[~g][:, :, 1]).max() > 1e-4
            # outside the null space: some grounded wheel slips sideways
            bad = rng.normal(size=25)
            bad -= N @ (N.T @ bad)  # orthogonal to the null space
            bad /= np.abs(bad).max()
            qvel = _qvel(m, w_h, J @ bad[:6], bad[6:18], bad[18:])
            vel = _contact_velocities(m, d, qvel)[params.BASE_PAIRS]
            residual = np.concatenate(
                [vel[g][:, :, 1].ravel(), vel[g][:, :, 2].ravel(), vel[g][:, 0, 0]]
            )
            assert np.abs(residual).max() > 1e-3


def test_null_space_motion_integrated_keeps_the_wheels_on_their_tracks():
    """Integrate qpos for 0.2 s (2 ms steps, mj_integratePos) with the null-space
    velocity of mode 1 closest to a constant drive command, re-solved at every step:
    the grounded contact sites stay on the ground and their step displacements across
    the axle (MuJoCo site positions before / after, projected on the mean axle
    direction) add up to the Euler integration error only (O(dt), < 1 % of the travel);
    the lifted pairs do slide sideways."""
    m = model.load_model()
    d = mujoco.MjData(m)
    w_h, phi = _config(6)
    grounded = MODES[0]
    command = np.zeros(25)
    command[18:] = 4.0  # drive the base's active wheels forward [rad/s]
    command[6:12] = 0.5  # and move the head joints
    C_fn = jax.jit(
        lambda w, p: kinematics.constraint_on_velocity(w, p, jnp.asarray(grounded), point="head")
    )
    dt, steps = 0.002, 100
    lateral = np.zeros(params.N_PAIRS_BASE)
    travel = np.zeros(params.N_PAIRS_BASE)
    sites = [f"pair{i + 1}_contact" for i in params.BASE_PAIRS]
    links = [m.body(f"link{params.PAIR_LINKS[i]}").id for i in params.BASE_PAIRS]

    def contacts():
        return (
            np.array([d.site(s).xpos for s in sites]),
            np.array([d.xmat[b].reshape(3, 3)[:, 1] for b in links]),
        )

    _mujoco_state(m, d, w_h, phi)
    for _ in range(steps):
        c0, y0 = contacts()
        N = _null_space(np.asarray(C_fn(jnp.asarray(w_h), jnp.asarray(phi))))
        v = N @ (N.T @ command)
        qvel = _qvel(m, w_h, v[:6], v[6:18], v[18:])
        qpos = d.qpos.copy()
        mujoco.mj_integratePos(m, qpos, qvel, dt)
        # back to (w_h, phi): head pose from the free joint, phi from the hinges
        R = np.zeros(9)
        mujoco.mju_quat2Mat(R, qpos[3:7])
        w_h = np.concatenate(
            [qpos[:3], np.asarray(geo.matrix_to_rpy(jnp.asarray(R.reshape(3, 3))))]
        )
        phi = np.array(
            [qpos[m.joint(params.JOINT_NAMES[k]).qposadr[0]] for k in params.PHI_JOINTS]
        )
        _mujoco_state(m, d, w_h, phi)
        c1, y1 = contacts()
        lateral += np.abs(np.einsum("ik,ik->i", c1 - c0, y0 + y1)) / 2
        travel += np.linalg.norm(c1 - c0, axis=1)
    assert travel[grounded].min() > 0.02  # [m]
    # measured: grounded <= 1.1e-4 m (halves with dt: 5.5e-5 at 1 ms, 2.7e-5 at 0.5 ms),
    # lifted pair 6 slides 6.3e-3 m whatever dt
    assert lateral[grounded].max() < 0.01 * travel[grounded].min()
    assert lateral[~grounded].max() > 20 * lateral[grounded].max()  # lifted pairs slide
    z = np.array([d.site(s).xpos[2] for s in sites])
    assert np.abs(z[grounded]).max() < 1e-3  # measured 2.5e-4 m (Euler drift, O(dt))
