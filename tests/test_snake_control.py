"""T² Snake-3 task-space control law (Tanaka et al. 2019, Eqs. 12-20, Sec. IV-C5):

  * the masked weighted pseudo-inverse equals the paper's W^-1 B^T (B W^-1 B^T)^-1 of
    the compacted (paper-shaped) B~ for every mode, zero columns for eliminated rows;
  * Eq. 13 solves the mode's constraints for the closed loop of Eq. 15 (wrapped angle
    errors), with the least W-norm; Eq. 14 lies in the null space of B~, is the
    W-orthogonal projection of -k_eta eta (idempotent, W-self-adjoint) and makes the third
    term of Eq. 18 non-positive;
  * the cost (Eq. 19 / 20): Eq. 20's ||d|| recomputed from MuJoCo's wheel contact sites
    and subtree centre of mass with scipy's convex hull; the analytic COM against MuJoCo;
    eta = dV/dphi against finite differences; the control input's derivatives;
  * the mode schedule: commanded switching every Delta T, automatic switching with
    hysteresis (the SCP excepted, per-joint limits), jit / vmap over ControlParams;
  * the paper's K_V diagonal."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from jax.test_util import check_grads
from scipy.spatial import ConvexHull

from jaxloco.robots.snake import control, kinematics, params
from jaxloco.robots.snake import model as snake_model

MODES = np.asarray(params.MODES)
_AUG = jax.jit(kinematics.augmented_matrices, static_argnames="point")
_PINV = jax.jit(control.weighted_pinv)
_TERMS = jax.jit(control.control_terms, static_argnames="point")
_COST = jax.jit(control.cost, static_argnames="point")
_ETA = jax.jit(control.eta, static_argnames="point")
_COM = jax.jit(kinematics.center_of_mass)
_TIP = jax.jit(lambda base, phi: kinematics.tip_from_head(kinematics.base_frame_pose(base, phi)))


def _posture(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Random head-raising posture with a bent base flat on the ground: (base, phi, w)
    with w the gripper-tip pose (the controlled point)."""
    rng = np.random.default_rng(seed)
    phi = params.INITIAL_PHI + rng.uniform(-0.3, 0.3, params.N_PHI)
    phi[params.N_H :] = rng.uniform(-0.7, 0.7, params.N_B)
    base = np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-3, 3)])
    return base, phi, np.asarray(_TIP(jnp.asarray(base), jnp.asarray(phi)))


def _paper_pinv(Bc: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """B^{W#} = W^-1 B^T (B W^-1 B^T)^-1 (Sec. III-B) of a full-row-rank B, numpy."""
    Winv = np.diag(1.0 / weights)
    return Winv @ Bc.T @ np.linalg.inv(Bc @ Winv @ Bc.T)


def _wrap(x: np.ndarray) -> np.ndarray:
    return np.angle(np.exp(1j * x))


def _null_basis(Bc: np.ndarray) -> np.ndarray:
    _, s, vt = np.linalg.svd(Bc)
    rank = int(np.sum(s > 1e-10 * s[0]))
    return vt[rank:].T


# ------------------------------------------------------------ weighted pseudo-inverse
@pytest.mark.parametrize("seed", [0, 1])
def test_weighted_pinv_is_the_papers_formula_on_the_compacted_rows(seed):
    _, phi, w = _posture(seed)
    rng = np.random.default_rng(100 + seed)
    # the default W and a random positive diagonal one (W must enter as W^-1 on both sides)
    for weights in (
        np.asarray(control.default_weights()),
        np.asarray(control.default_weights()) * rng.uniform(0.2, 5.0, 19),
    ):
        for sigma in range(1, params.N_MODES + 1):
            g = MODES[sigma - 1]
            _, Bt = _AUG(jnp.asarray(w), jnp.asarray(phi), jnp.asarray(g))
            keep = np.asarray(control.keep_rows(jnp.asarray(g)))
            assert keep.sum() == 14  # 13 constraint rows + the SCP row (Eq. 10)
            got = np.asarray(_PINV(Bt, jnp.asarray(weights), jnp.asarray(keep)))
            Bc = kinematics.compact_rows(np.asarray(Bt), g, extra=1)  # (14, 19), the paper's shape
            expected = _paper_pinv(Bc, weights)
            assert got.shape == (19, 18)
            scale = np.abs(expected).max()
            np.testing.assert_allclose(got[:, keep], expected, rtol=0, atol=1e-9 * scale)
            assert np.all(got[:, ~keep] == 0.0)  # eliminated rows: zero columns
            np.testing.assert_allclose(Bc @ got[:, keep], np.eye(14), rtol=0, atol=1e-9)  # a right inverse


def test_the_wheel_weight_of_w_equal_to_the_identity_is_l2_over_r2():
    """`w_wheel` = l^2 / r^2 (3.28, the bound the docs read from the paper's Sec. III-B) makes
    W a multiple of I, so the weighted pseudo-inverse is the plain minimum-norm one (numpy's
    pinv of the paper's compacted rows); ours (1) is not."""
    _, phi, w = _posture(0)
    bound = float(params.LINK_LENGTH**2 / params.WHEEL_RADIUS**2)
    assert bound == pytest.approx(3.28, abs=0.005)
    g = MODES[1]
    _, Bt = _AUG(jnp.asarray(w), jnp.asarray(phi), jnp.asarray(g))
    keep = np.asarray(control.keep_rows(jnp.asarray(g)))
    plain = np.linalg.pinv(kinematics.compact_rows(np.asarray(Bt), g, extra=1))
    for w_wheel, same in ((bound, True), (1.0, False)):
        got = np.asarray(_PINV(Bt, control.default_weights(None, w_wheel), jnp.asarray(keep)))[:, keep]
        assert np.allclose(got, plain, rtol=0, atol=1e-9 * np.abs(plain).max()) == same


# -------------------------------------------------------------------- Eqs. 12 - 14, 18
def _case(seed: int, sigma: int):
    """A posture, a mode, a target (angles up to 2 pi away: wrapping), a target velocity,
    per-component gains and k_eta; returns everything plus the control terms."""
    _, phi, w = _posture(seed)
    rng = np.random.default_rng(200 + 10 * seed + sigma)
    g = MODES[sigma - 1]
    wt = np.concatenate([w, phi[params.SCP_INDEX : params.SCP_INDEX + 1]])
    wt_d = wt + np.concatenate([rng.uniform(-0.05, 0.05, 3), rng.uniform(-0.1, 0.1, 4)])
    wt_d[5] += 2 * math.pi * rng.choice([-1, 1])  # the yaw target one turn away
    wt_d_dot = rng.uniform(-0.1, 0.1, 7)
    cp = control.ControlParams(gain=jnp.asarray(rng.uniform(0.5, 3.0, 7)), k_eta=jnp.asarray(rng.uniform(0.1, 2.0)),
                         kv=jnp.asarray(rng.uniform(0.1, 10.0, 12)))
    terms = _TERMS(jnp.asarray(w), jnp.asarray(phi), jnp.asarray(wt_d), jnp.asarray(wt_d_dot), jnp.asarray(g), cp)
    At, Bt = (np.asarray(x) for x in _AUG(jnp.asarray(w), jnp.asarray(phi), jnp.asarray(g)))
    return {"w": w, "phi": phi, "g": g, "wt": wt, "wt_d": wt_d, "wt_d_dot": wt_d_dot, "cp": cp, "At": At,
            "Bt": Bt, "terms": jax.tree_util.tree_map(np.asarray, terms)}


CASES = [(seed, sigma) for seed in (0, 1) for sigma in range(1, params.N_MODES + 1)]


@pytest.mark.parametrize("seed, sigma", CASES)
def test_eq13_solves_the_constraints_for_the_closed_loop(seed, sigma):
    """B~ u_sigma = A~ v with v = w~_d_dot - K (w~ - w~_d) (angle errors wrapped): the
    mode's velocity constraints then give w~_dot - w~_d_dot + K e = 0 (Eq. 15); u_sigma has
    the least W-norm among the solutions (W-orthogonal to the null space of B~)."""
    c = _case(seed, sigma)
    t, cp = c["terms"], c["cp"]
    e = c["wt"] - c["wt_d"]
    e[3:] = _wrap(e[3:])
    np.testing.assert_allclose(t.error, e, rtol=0, atol=1e-12)
    assert np.abs(e[3:]).max() < 0.2  # wrapped, not 2 pi
    v = c["wt_d_dot"] - np.asarray(cp.gain) * e
    lhs, rhs = c["Bt"] @ t.u_task, c["At"] @ v
    np.testing.assert_allclose(lhs, rhs, rtol=0, atol=1e-10 * (1 + np.abs(rhs).max()))
    # Eq. 12 and the full input: the null-space part adds nothing to B~ u
    np.testing.assert_allclose(t.u, t.u_task + t.u_null, rtol=0, atol=1e-14)
    np.testing.assert_allclose(c["Bt"] @ t.u, rhs, rtol=0, atol=1e-10 * (1 + np.abs(rhs).max()))
    # least W-norm: orthogonal in the W inner product to every null-space direction
    Bc = kinematics.compact_rows(c["Bt"], c["g"], extra=1)
    N = _null_basis(Bc)
    assert N.shape[1] == 19 - 14
    W = np.asarray(cp.weights)
    assert np.abs(N.T @ (W * t.u_task)).max() < 1e-10 * np.abs(W * t.u_task).max()
    # and equal to the paper's formula applied to the compacted matrices
    Ac = kinematics.compact_rows(c["At"], c["g"], extra=1)
    np.testing.assert_allclose(t.u_task, _paper_pinv(Bc, W) @ (Ac @ v), rtol=0,
                               atol=1e-10 * np.abs(t.u_task).max())


@pytest.mark.parametrize("seed, sigma", CASES)
def test_eq14_null_space_term(seed, sigma):
    """B~ u_ker = 0; u_ker = -k_eta (I - B# B) eta with (I - B# B) the W-orthogonal
    projector onto the null space (idempotent, W (I - B# B) symmetric; u_ker + k_eta eta
    is W-orthogonal to the null space); Eq. 18's third term eta . u_ker
    = -k_eta eta^T (I - B# B) eta <= 0."""
    c = _case(seed, sigma)
    t, cp = c["terms"], c["cp"]
    k_eta, W = float(cp.k_eta), np.asarray(cp.weights)
    scale = np.abs(t.u_null).max()
    assert scale > 1e-3  # not trivially zero
    assert np.abs(c["Bt"] @ t.u_null).max() < 1e-10 * np.abs(c["Bt"]).max() * scale
    Bc = kinematics.compact_rows(c["Bt"], c["g"], extra=1)
    Pr = np.eye(19) - _paper_pinv(Bc, W) @ Bc
    np.testing.assert_allclose(Pr @ Pr, Pr, rtol=0, atol=1e-10)
    np.testing.assert_allclose(W[:, None] * Pr, (W[:, None] * Pr).T, rtol=0, atol=1e-10 * W.max())
    eta = t.eta
    np.testing.assert_allclose(t.u_null, -k_eta * Pr @ eta, rtol=0, atol=1e-10 * scale)
    N = _null_basis(Bc)
    assert np.abs(N.T @ (W * (t.u_null + k_eta * eta))).max() < 1e-9 * np.abs(W * eta).max() * max(k_eta, 1)
    third = eta @ t.u_null
    assert third <= 0.0
    assert third == pytest.approx(-k_eta * eta @ Pr @ eta, rel=1e-9)
    assert third < -1e-6  # strictly negative here: eta has a part in the null space


# ------------------------------------------------------------------------ cost (19, 20)
def _mujoco_support(model, data, phi, base, grounded):
    """From MuJoCo alone: the subtree COM of the root link and the support polygon of both
    wheels of every grounded base pair (MuJoCo's wheel body centres, r below them along
    the link z)."""
    qpos, _ = snake_model.pose_qpos_ctrl(model, phi, base)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    com = data.subtree_com[model.body("link1").id].copy()
    pts = []
    for i, pair in enumerate(params.BASE_PAIRS):
        if not grounded[i]:
            continue
        z = data.xmat[model.body(f"link{params.PAIR_LINKS[pair]}").id].reshape(3, 3)[:, 2]
        pts += [data.body(f"wheel{pair + 1}_{side}").xpos - params.WHEEL_RADIUS * z for side in ("active", "passive")]
    return com, np.array(pts)


def _hull_line_distances(q: np.ndarray, pts2: np.ndarray) -> np.ndarray:
    """Distances of q from the lines of the convex hull's sides (scipy / qhull: collinear
    points merged into one side)."""
    hull = ConvexHull(pts2)
    out = []
    for a, b in hull.simplices:
        e = pts2[b] - pts2[a]
        r = q - pts2[a]
        out.append(abs(e[0] * r[1] - e[1] * r[0]) / np.linalg.norm(e))
    return np.array(out)


@pytest.fixture(scope="module")
def mj():
    model = snake_model.load_model()
    return model, mujoco.MjData(model)


POSTURES = {"bent": 3, "straight": None}


@pytest.mark.parametrize("posture", list(POSTURES))
def test_center_of_mass_matches_mujoco(posture, mj):
    model, data = mj
    if POSTURES[posture] is None:
        base, phi = np.array([0.3, -0.2, 0.7]), params.INITIAL_PHI.copy()
    else:
        base, phi, _ = _posture(POSTURES[posture])
    com_mj, _ = _mujoco_support(model, data, phi, base, np.ones(7, bool))
    w_h = kinematics.base_frame_pose(jnp.asarray(base), jnp.asarray(phi))
    com = np.asarray(_COM(w_h, kinematics.full_joint_angles(jnp.asarray(phi))))
    np.testing.assert_allclose(com, com_mj, rtol=0, atol=1e-9)
    total = sum(model.body_mass[1:])
    assert total == pytest.approx(params.MASS, rel=1e-9)


@pytest.mark.parametrize("posture", list(POSTURES))
def test_cost_eq19_and_eq20_against_mujoco_and_scipy(posture, mj):
    """a2 = 0: V = phi^T K_V phi (Eq. 19). a2 > 0: V = a1 phi^T K_V phi + a2 / ||d||
    (Eq. 20), ||d|| over every side of the grounded wheels' support polygon, from
    MuJoCo's COM and wheel bodies and scipy's hull, for every mode. The straight base has
    collinear wheels along its sides: one side each, not one per wheel gap."""
    model, data = mj
    if POSTURES[posture] is None:
        base, phi = np.array([0.3, -0.2, 0.7]), params.INITIAL_PHI.copy()
        w = np.asarray(_TIP(jnp.asarray(base), jnp.asarray(phi)))
    else:
        base, phi, w = _posture(POSTURES[posture])
    kv = np.random.default_rng(7).uniform(0.1, 10.0, 12)
    a1, a2 = 0.7, 0.05
    joint = phi @ (kv * phi)
    for sigma in range(1, params.N_MODES + 1):
        g = MODES[sigma - 1]
        args = (jnp.asarray(w), jnp.asarray(phi), jnp.asarray(g))
        v19 = float(_COST(*args, control.ControlParams(kv=jnp.asarray(kv))))
        assert v19 == pytest.approx(joint, rel=1e-12)
        com, pts = _mujoco_support(model, data, phi, base, g)
        assert np.abs(pts[:, 2]).max() < 1e-9  # the wheels touch the ground
        d = _hull_line_distances(com[:2], pts[:, :2])
        if posture == "straight":  # collinear wheels (same track width) make one side, not one per gap
            normals = np.round(ConvexHull(pts[:, :2]).equations[:, :2], 9)
            assert len(d) == len(np.unique(normals, axis=0)) <= 6
        v20 = float(_COST(*args, control.ControlParams(kv=jnp.asarray(kv), a1=a1, a2=a2)))
        assert v20 == pytest.approx(a1 * joint + a2 / np.linalg.norm(d), rel=1e-9)
        # support_distances: the static margin is the distance to the nearest side when
        # P_G is inside the polygon (the signed distance otherwise)
        dd, E, margin = control.support_distances(kinematics.point_to_head(args[0], "tip"), args[1], args[2])
        inside = ConvexHull(pts[:, :2]).equations
        signed = -np.max(inside[:, :2] @ com[:2] + inside[:, 2])
        assert signed > 0  # P_G inside the polygon in these postures
        assert float(margin) == pytest.approx(d.min(), abs=1e-9)
        assert np.sum(np.asarray(dd)[np.asarray(E)] ** 2) == pytest.approx(np.sum(d**2), rel=1e-9)


@pytest.mark.parametrize("a2", [0.0, 0.05])
def test_eta_is_the_gradient_of_the_cost(a2):
    """Eq. 17: eta = dV/dvarphi, central finite differences in phi (float64), zeros for
    the wheel angles rho (V does not depend on them); with a2 = 0, 2 a1 K_V phi."""
    _, phi, w = _posture(4)
    g = jnp.asarray(MODES[2])
    kv = np.random.default_rng(8).uniform(0.1, 10.0, 12)
    cp = control.ControlParams(kv=jnp.asarray(kv), a1=0.7, a2=a2)
    eta = np.asarray(_ETA(jnp.asarray(w), jnp.asarray(phi), g, cp))
    assert eta.shape == (19,) and np.all(eta[12:] == 0.0)
    h = 1e-6
    fd = np.zeros(12)
    for i in range(12):
        dp = np.zeros(12)
        dp[i] = h
        fd[i] = (float(_COST(jnp.asarray(w), jnp.asarray(phi + dp), g, cp))
                 - float(_COST(jnp.asarray(w), jnp.asarray(phi - dp), g, cp))) / (2 * h)
    np.testing.assert_allclose(eta[:12], fd, rtol=1e-6, atol=1e-7)
    if a2 == 0.0:
        np.testing.assert_allclose(eta[:12], 2 * 0.7 * kv * phi, rtol=1e-12)
    else:
        assert np.abs(eta[:12] - 0.7 * 2 * kv * phi).max() > 1e-4  # the support term matters


def _v_of_a2(a2):
    _, phi, w = _posture(4)
    return _COST(jnp.asarray(w), jnp.asarray(phi), jnp.asarray(MODES[0]), control.ControlParams(a2=a2))


def test_cost_derivative_in_a2():
    """V is affine in a2 (Eq. 20): dV/da2 = 1/||d||, the slope between two values."""
    slope = float(_v_of_a2(0.05) - _v_of_a2(0.02)) / 0.03
    assert slope > 0.1
    assert float(jax.grad(_v_of_a2)(0.05)) == pytest.approx(slope, rel=1e-8)


def test_cost_derivative_in_a2_at_zero():
    """dV/da2 = 1/||d|| also at a2 = 0 (Eq. 19): gradient tuning of a2 can start there."""
    slope = float(_v_of_a2(1e-3) - _v_of_a2(0.0)) / 1e-3
    assert float(jax.grad(_v_of_a2)(0.0)) == pytest.approx(slope, rel=1e-8)


_CONTROL = jax.jit(control.control_input)


@pytest.mark.parametrize("a2", [0.0, 0.05])
def test_control_input_derivatives(a2):
    """jax.test_util.check_grads of u (Eq. 12) w.r.t. the pose w and the joints phi,
    forward and reverse mode (second derivatives of V inside eta), float64."""
    _, phi, w = _posture(5)
    rng = np.random.default_rng(9)
    g = jnp.asarray(MODES[4])
    wt_d = jnp.asarray(np.concatenate([w, phi[5:6]]) + rng.uniform(-0.05, 0.05, 7))
    wt_d_dot = jnp.asarray(rng.uniform(-0.1, 0.1, 7))
    cp = control.ControlParams(k_eta=0.5, a2=a2)

    def f(w_, phi_):
        return _CONTROL(w_, phi_, wt_d, wt_d_dot, g, cp)

    check_grads(f, (jnp.asarray(w), jnp.asarray(phi)), order=1, modes=("fwd", "rev"), atol=1e-5, rtol=1e-5)


# ----------------------------------------------------------------------- mode schedule
def _schedule(cp: control.ControlParams, ts: jax.Array, phis: jax.Array) -> tuple[jax.Array, jax.Array]:
    def step(state, x):
        state, sigma = control.update_mode(x[0], x[1], state, cp)
        return state, (sigma, state.switching)

    _, (sigma, switching) = jax.lax.scan(step, control.initial_mode_state(ts.dtype), (ts, phis))
    return sigma, switching


_SCHEDULE = jax.jit(_schedule)
_SCHEDULE_BATCH = jax.jit(jax.vmap(_schedule, in_axes=(0, None, None)))
TS = jnp.arange(120) * 0.1  # [s]


def test_commanded_switching_cycles_the_modes_every_delta_t():
    """switch_at = 2, Delta T = 1, automatic switching off (enter_ratio > 1): sigma = 1 for
    t < 2, then 2, 3, 4, 5, 6, 2, 3, ... on [2, 3), [3, 4), ... (Sec. V-B)."""
    cp = control.ControlParams(switch_at=2.0, delta_t=1.0, enter_ratio=2.0)
    phis = jnp.zeros((TS.shape[0], 12)).at[:, 7].set(control.PHI_LIMITS[7])  # at a limit: no effect
    sigma, switching = (np.asarray(x) for x in _SCHEDULE(cp, TS, phis))
    tenth = np.arange(120)
    expected = np.where(tenth < 20, 1, np.array([2, 3, 4, 5, 6])[np.maximum(tenth - 20, 0) // 10 % 5])
    assert sigma.tolist() == expected.tolist()
    assert switching.tolist() == (tenth >= 20).tolist()
    assert sigma[[19, 20, 30, 40, 50, 60, 70, 80]].tolist() == [1, 2, 3, 4, 5, 6, 2, 3]


def _ramp_phis() -> np.ndarray:
    """theta_5 (phi[7], yaw, negative side) at a ratio r(t) of its limit: 0.5 + 0.2 t up
    to 1.0 at t = 2.5, held to t = 4, down at 0.2 /s to 0.5 (t = 6.5), then from t = 7 up
    at 0.5 /s to 1.0 (t = 8) and held. psi_3 (the SCP) at 99.9 % of its limit and psi_1
    at 1.5 rad (beyond the yaw limit, 76 % of the pitch limit) all the time."""
    t = np.arange(120) * 0.1
    r = np.interp(t, [0.0, 2.5, 4.0, 6.5, 7.0, 8.0, 12.0], [0.5, 1.0, 1.0, 0.5, 0.5, 1.0, 1.0])
    phis = np.zeros((120, 12))
    phis[:, 7] = -r * params.YAW_LIMIT
    phis[:, params.SCP_INDEX] = 0.999 * params.PITCH_LIMIT
    phis[:, 1] = 1.5
    return phis


def _expected_auto(order: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """enter_ratio 0.99, exit_ratio 0.85, Delta T 0.5 on the ramp: enters at t = 2.5
    (r = 1.0; 0.98 at 2.4), stays while r > 0.85 (r = 0.86 at 4.7, 0.84 at 4.8), enters
    again at t = 8.0 (r = 0.95 at 7.9), counting Delta T from each entry."""
    tenth = np.arange(120)
    sw = ((tenth >= 25) & (tenth <= 47)) | (tenth >= 80)
    since = np.where(tenth >= 80, tenth - 80, tenth - 25)
    return np.where(sw, order[np.maximum(since, 0) // 5 % 5], 1), sw


def test_automatic_switching_with_hysteresis():
    order = np.array([6, 5, 4, 3, 2])
    cp = control.ControlParams(delta_t=0.5, enter_ratio=0.99, exit_ratio=0.85, mode_order=jnp.asarray(order))
    sigma, switching = (np.asarray(x) for x in _SCHEDULE(cp, TS, jnp.asarray(_ramp_phis())))
    expected_sigma, expected_sw = _expected_auto(order)
    assert switching.tolist() == expected_sw.tolist()
    assert sigma.tolist() == expected_sigma.tolist()
    # the SCP alone (at 99.9 % of its limit) never triggers, nor does a pitch joint at 76 %
    # of its own limit (above the yaw limit in radians); a pitch joint at 99.5 % does
    quiet = _ramp_phis()
    quiet[:, 7] = 0.0
    sigma_q, sw_q = (np.asarray(x) for x in _SCHEDULE(cp, TS, jnp.asarray(quiet)))
    assert not sw_q.any() and set(sigma_q.tolist()) == {1}
    quiet[60:, 1] = -0.995 * params.PITCH_LIMIT
    _, sw_p = (np.asarray(x) for x in _SCHEDULE(cp, TS, jnp.asarray(quiet)))
    assert sw_p.tolist() == (np.arange(120) >= 60).tolist()
    # the fixing state's mode is data too
    sigma_f, _ = _SCHEDULE(cp.with_(fixed_mode=4), TS, jnp.asarray(quiet))
    assert set(np.asarray(sigma_f)[:60].tolist()) == {4}


def test_schedule_vmapped_over_control_params_equals_a_loop():
    cps = [
        control.ControlParams(switch_at=2.0, delta_t=1.0, enter_ratio=2.0),
        control.ControlParams(delta_t=0.5, enter_ratio=0.99, exit_ratio=0.85, mode_order=jnp.array([6, 5, 4, 3, 2])),
        control.ControlParams(switch_at=5.0, delta_t=0.3, enter_ratio=0.9, exit_ratio=0.8,
                        mode_order=jnp.array([2, 4, 6, 3, 5]), fixed_mode=2),
        control.ControlParams(switch_at=1.0, delta_t=2.0, enter_ratio=0.95, exit_ratio=0.5),
    ]
    cps = [jax.tree_util.tree_map(lambda x: jnp.asarray(x, jnp.result_type(x)), cp) for cp in cps]
    batch = jax.tree_util.tree_map(lambda *xs: jnp.stack(xs), *cps)
    phis = jnp.asarray(_ramp_phis())
    sig_b, sw_b = _SCHEDULE_BATCH(batch, TS, phis)
    distinct = set()
    for i, cp in enumerate(cps):
        sig, sw = _SCHEDULE(cp, TS, phis)
        assert np.array_equal(sig_b[i], sig) and np.array_equal(sw_b[i], sw)
        distinct.add(tuple(np.asarray(sig).tolist()))
    assert len(distinct) == len(cps)
    order = np.array([6, 5, 4, 3, 2])
    assert np.asarray(sig_b[1]).tolist() == _expected_auto(order)[0].tolist()


# ------------------------------------------------------------------------------- K_V
def test_kv_diagonal_is_the_papers():
    paper = [15, 0.015, 15, 0.015, 15, 0.015, 9.6, 4.8, 2.4, 1.2, 0.6, 0.3]  # Sec. V-B
    np.testing.assert_allclose(np.asarray(control.kv_diagonal()), paper, rtol=1e-12)
    np.testing.assert_allclose(np.asarray(control.ControlParams().kv), paper, rtol=1e-12)
    np.testing.assert_allclose(np.asarray(control.kv_diagonal(1.0, 2.0, 8.0, 2.0)),
                               [1, 2, 1, 2, 1, 2, 8, 16, 32, 64, 128, 256], rtol=1e-12)
    # traceable: a gradient through the four numbers
    g = jax.grad(lambda b: jnp.sum(control.kv_diagonal(15.0, 0.015, b, 0.5)))(9.6)
    assert float(g) == pytest.approx(sum(0.5**k for k in range(6)))
