"""T² Snake-3 kinematic closed loop (`kinsim.rollout`) under the task-space controller:

  * Eq. 15: from an offset target the task error decays as explicit Euler of
    e_dot = -K e, (1 - K dt)^k per component (feedback; and the feedforward controller's
    own estimate, identical to the plant while nothing saturates);
  * the null-space term (Eq. 14) changes phi, not the controlled variable;
  * tracking a moving target with an O(dt) error; the base stays on the plane and the
    grounded wheels do not slip sideways;
  * the joint-limit experiment (Sec. V-B) under jit: the mode schedule, V decreasing,
    the gripper tip held;
  * vmap over control parameters and targets equals a loop;
  * the servo speed limit: feedforward's true error grows while its estimate converges,
    feedback converges (Sec. IV-C2, Fig. 7);
  * Table III in the kinematic model (no slip): every error far below 0.1 %.

Every rollout here has the same static shape (121 periods of 50 ms, gripper tip) and its
pytrees are made of strongly typed arrays, so that each compiled program is shared."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxloco.robots.snake import control, experiments, kinematics, kinsim, params

DT, STEPS = 0.05, 121  # 6 s
CFG_FB = kinsim.RolloutConfig(steps=STEPS, dt=DT, feedback=True)
CFG_FF = kinsim.RolloutConfig(steps=STEPS, dt=DT, feedback=False)
_FB = jax.jit(lambda x0, tg, cp, plant: kinsim.rollout(x0, tg, cp, CFG_FB, plant))
_FF = jax.jit(lambda x0, tg, cp, plant: kinsim.rollout(x0, tg, cp, CFG_FF, plant))
_FB_BATCH = jax.jit(jax.vmap(lambda x0, tg, cp, plant: kinsim.rollout(x0, tg, cp, CFG_FB, plant), (None, 0, 0, None)))
TIMES = np.arange(STEPS) * DT


def _strong(tree):
    """Every leaf a strongly typed array (float64 / int64): one compiled program for all
    the Python-float and array variants of the same pytree."""
    return jax.tree_util.tree_map(lambda x: jnp.asarray(np.asarray(x)), tree)


def _np(recs):
    return {k: np.asarray(v) for k, v in recs.items()}


def _run(fn, x0, target, cp, plant=None):
    return _np(fn(_strong(x0), _strong(target), _strong(cp), _strong(plant or kinsim.PlantParams())))


# a bent base (+-0.4 rad, 35 % of the yaw limit), head raised (Sec. V-A posture)
_PHI = params.INITIAL_PHI.copy()
_PHI[params.N_H :] = 0.4 * (-1.0) ** np.arange(params.N_B)
X0 = kinsim.initial_state(jnp.asarray(_PHI), jnp.array([0.1, -0.2, 0.3]))
W0 = np.asarray(kinsim.hold_target(X0).w0)  # w~ of X0: [gripper-tip pose, psi_3]
GAIN = np.array([1.0, 2.0, 1.5, 1.0, 2.5, 0.5, 1.2])  # K per controlled variable [1/s]
OFFSET = np.array([0.03, -0.02, 0.02, 0.05, -0.05, 0.05, 0.03])  # w~_d - w~(0) [m, rad]
NO_LIMITS = kinsim.PlantParams(joint_speed_max=100.0, wheel_speed_max=100.0)


def _offset_target() -> kinsim.Target:
    return kinsim.Target(jnp.asarray(W0 + OFFSET), jnp.zeros(7), 0.0, 1.0)


# ------------------------------------------------------------------ Eq. 15, null space
@pytest.mark.parametrize("feedback", [True, False])
def test_task_error_decays_as_explicit_euler_of_eq15(feedback):
    """e_{k+1} = (1 - K dt) e_k: the controller's u solves the mode's constraints for
    w~_dot = w~_d_dot - K e and the plant's w_dot (least squares of the same
    constraints) equals it, so only the plant's second-order remainder (w recomputed
    from the Euler-integrated base pose and phi) separates e_k from (1 - K dt)^k e_0:
    measured 7e-3 |e_0| (3e-3 at dt = 0.02, 1.4e-3 at 0.01: O(dt) accumulated), bound
    0.2 dt max|e_0|. Feedforward: its estimate ("ctrl_error") follows the same law and
    equals the plant while nothing saturates."""
    cp = control.ControlParams(gain=jnp.asarray(GAIN), k_eta=0.0, enter_ratio=2.0)
    recs = _run(_FB if feedback else _FF, X0, _offset_target(), cp)
    seen = recs["error"] if feedback else recs["ctrl_error"]
    e0 = seen[0]
    np.testing.assert_allclose(e0, -OFFSET, rtol=0, atol=1e-12)
    euler = (1.0 - GAIN * DT)[None, :] ** np.arange(STEPS)[:, None] * e0
    dev = np.abs(seen - euler).max(axis=0)
    assert dev.max() < 0.2 * DT * np.abs(e0).max(), dev
    assert dev[6] < 1e-12  # psi_3 is a joint: integrated exactly
    # it did converge: the slowest component (K = 0.5) to e^-3 of its start
    assert np.all(np.abs(seen[-1]) <= 1.1 * np.exp(-GAIN * TIMES[-1]) * np.abs(e0) + 1e-4)
    assert np.all(recs["sigma"] == 1) and not recs["switching"].any()
    if not feedback:
        np.testing.assert_allclose(recs["error"], recs["ctrl_error"], rtol=0, atol=1e-12)


def test_null_space_term_does_not_disturb_the_task():
    """The same rollout with k_eta = 0 and k_eta = 0.5 (servo limits out of reach, no
    joint near a limit): the controlled variable's trajectories agree to the plant's
    integration error (measured 5.2e-4 m / rad at dt = 0.05, 1.6e-4 at 0.02, 7e-5 at
    0.01: O(dt); bound 1e-3, 2 % of the 0.05 initial error) while phi
    differs by tenths of a radian and V falls further with the null-space term."""
    cp = control.ControlParams(gain=jnp.asarray(GAIN), k_eta=0.0, enter_ratio=2.0)
    a = _run(_FB, X0, _offset_target(), cp, NO_LIMITS)
    b = _run(_FB, X0, _offset_target(), cp.with_(k_eta=0.5), NO_LIMITS)
    assert np.abs(a["error"] - b["error"]).max() < 1e-3
    assert np.abs(a["phi"] - b["phi"]).max() > 0.2
    assert b["V"][-1] < 0.6 * a["V"][-1]
    assert b["limit_ratio"].max() < 0.9  # no joint stop involved
    assert np.abs(b["u"][:, :12]).max() < 4.7  # nor the real servos' limit


# --------------------------------------------------------------------------- tracking
DELTA = np.array([0.1, -0.05, 0.03, 0.1, -0.1, 0.3, 0.0])  # [m, rad]
T0, RAMP = 0.5, 3.0


@pytest.fixture(scope="module")
def tracking():
    cp = control.ControlParams(enter_ratio=2.0)  # K = 1, k_eta = 0.1, sigma = 1
    return _run(_FB, X0, kinsim.Target(jnp.asarray(W0), jnp.asarray(DELTA), T0, RAMP), cp)


def test_tracking_a_moving_target(tracking):
    """w~_d moves by DELTA along a smooth step over RAMP. Explicit Euler of
    e_dot = -K e leaves per step the target's own remainder r_k = w_d(t_k) + dt w_d_dot
    (t_k) - w_d(t_k+1), |r_k| <= dt^2 max|w_d_ddot| / 2 with max|w_d_ddot| =
    2 pi |delta| / RAMP^2, so |e| <= dt pi |delta| / (K RAMP^2) = O(dt); the plant's own
    second-order remainder is of the same order: bound twice that (measured <= 0.89 of
    it; the error halves with dt). After the target stops the error decays (K = 1:
    e^-2.5 of its peak)."""
    e = np.abs(tracking["error"])
    bound = DT * np.pi * np.abs(DELTA) / (1.0 * RAMP**2)
    assert np.all(e.max(axis=0) <= 2.0 * bound + 1e-12), (e.max(axis=0), bound)
    moving = e[(TIMES > T0) & (TIMES < T0 + RAMP)]
    assert moving[:, :6].max() > 0.1 * bound[:6].max()  # the bound is not vacuous
    assert np.all(e[-1] <= 0.15 * e.max(axis=0) + 1e-12)
    # the controlled point did move by DELTA
    w = tracking["w"]
    np.testing.assert_allclose(w[-1, :3] - w[0, :3], DELTA[:3], atol=2e-4)


def _grounded_contacts(recs):
    """Contact points (n, 7, 3) and axle directions (n, 7, 3) of the base pairs at the
    recorded gripper-tip poses and joints."""

    def one(w, phi):
        _, contact, R = kinematics.wheel_pairs(kinematics.head_from_tip(w), kinematics.full_joint_angles(phi))
        return contact[params.BASE_PAIRS], R[params.BASE_PAIRS][:, :, 1]

    c, y = jax.jit(jax.vmap(one))(jnp.asarray(recs["w"]), jnp.asarray(recs["phi"]))
    return np.asarray(c), np.asarray(y)


def test_base_stays_on_the_plane_and_grounded_wheels_do_not_slip(tracking):
    """At every recorded (w, phi) the base pairs' contact points lie on z = 0 and the
    base's link 7 pose is the recorded base; per step, the grounded pairs move along
    their axles only by the Euler remainder (O(dt^2) per step, O(dt) summed): the summed
    lateral displacement is under 1.5 % of the distance travelled (measured 0.64 % at
    dt = 0.05, 0.31 % at 0.025, 0.15 % at 0.0125), while the lifted pairs 3 and 6 of mode
    1 slide sideways (20 % and 53 % of their travel, whatever dt)."""
    c, y = _grounded_contacts(tracking)
    assert np.abs(c[:, :, 2]).max() < 1e-12
    base = np.asarray(jax.vmap(lambda w, phi: kinematics.base_of(kinematics.head_from_tip(w), phi))(
        jnp.asarray(tracking["w"]), jnp.asarray(tracking["phi"])))
    np.testing.assert_allclose(base, tracking["base"], rtol=0, atol=1e-12)
    g = params.MODES[0]
    step = c[1:] - c[:-1]
    lateral = np.abs(np.einsum("nik,nik->ni", step, 0.5 * (y[1:] + y[:-1]))).sum(axis=0)
    travel = np.linalg.norm(step, axis=-1).sum(axis=0)
    assert travel[g].min() > 0.02  # [m]
    assert lateral[g].max() < 0.015 * travel[g].min(), (lateral, travel)
    assert np.all(lateral[~g] > 0.1 * travel[~g])


# ---------------------------------------------------------------- joint-limit experiment
@pytest.fixture(scope="module")
def limit_run():
    x0, target = experiments.limit_setup()
    return _run(_FF, x0, target, experiments.limit_params())


def test_joint_limit_experiment_switches_modes_and_lowers_v(limit_run):
    """Sec. V-B for 6 s: sigma = 1 for t < 2, then 2, 3, 4, 5, 6 every second; V falls.
    With the target held (w_d_dot = 0) dV/dt = eta . u_task + eta . u_ker, the second
    term <= 0 (Eq. 18), the first only the psi_3 catch-up (2 K_V[psi_3] psi_3 K e_psi3
    ~ 1e-3 /s) and O(dt^2) remainders: V may not rise by more than 1e-3 per step where
    no joint sits at its stop (a stop can break the descent direction); measured: it
    falls at every step. The gripper tip stays within 2 cm (no servo clipping here; the
    joint stops, where the plant's step is inconsistent, move it)."""
    r = limit_run
    k = np.arange(STEPS)  # t = k dt, 20 periods per second
    expected = np.where(k < 40, 1, np.array([2, 3, 4, 5, 6])[np.maximum(k - 40, 0) // 20 % 5])
    assert r["sigma"].tolist() == expected.tolist()
    assert r["sigma"][[39, 40, 60, 80, 100, 120]].tolist() == [1, 2, 3, 4, 5, 6]
    assert r["switching"].tolist() == (TIMES >= 2.0 - 1e-9).tolist()
    V = r["V"]
    assert V[0] == pytest.approx(
        float(control.cost_joint(jnp.asarray(experiments.zigzag_phi()), control.kv_diagonal())), rel=1e-12
    )
    assert V[-1] < 0.8 * V[0]
    at_stop = np.any(np.abs(r["phi"]) >= control.PHI_LIMITS - 1e-12, axis=1)
    assert at_stop.any()  # the exception is not hypothetical: theta_7, theta_8 reach their stops
    rise = np.diff(V)
    free = ~(at_stop[:-1] | at_stop[1:])
    assert rise[free].max() < 1e-3, rise[free].max()
    assert np.abs(r["u"][:, :12]).max() < kinsim.JOINT_SPEED_MAX  # no servo clipping
    # where a joint sits at its stop the plant cannot follow the command without the
    # wheels skidding: the tip moves (measured 7 mm); elsewhere it stays put
    assert np.abs(r["error"][:, :3]).max() < 0.02  # [m]
    assert np.abs(r["error"][:, 3:6]).max() < 0.05  # [rad]
    # psi_3 converges to its SCP target 110 deg at K = 1
    assert abs(r["error"][-1, 6]) < 1.1 * np.exp(-TIMES[-1]) * abs(r["error"][0, 6])
    # the base joints come down from the limits (0.97 -> 0.92 of the limit in 6 s)
    assert experiments.base_limit_ratio(r["phi"][-1]) < 0.95 < experiments.base_limit_ratio(r["phi"][0])


def test_base_stays_on_the_plane_in_the_joint_limit_experiment(limit_run):
    """Even where the joint stops make the Euler step inconsistent with the wheels, the
    base is integrated as a planar pose: every base contact point stays on z = 0."""
    c, _ = _grounded_contacts(limit_run)
    assert np.abs(c[:, :, 2]).max() < 1e-12


# ------------------------------------------------------------------------ vmap == loop
def test_rollout_vmapped_over_control_params_and_targets_equals_a_loop():
    x0, hold = experiments.limit_setup()
    cps = [
        experiments.limit_params(),
        experiments.limit_params(k_eta=0.5, switch_at=1.0, delta_t=0.5, mode_order=jnp.array([6, 5, 4, 3, 2])),
        experiments.limit_params(gain=jnp.full(7, 2.0), kv=control.kv_diagonal(1.0, 0.1, 20.0, 1.0), switch_at=jnp.inf,
                       enter_ratio=0.99, exit_ratio=0.9),
    ]
    targets = [
        hold,
        kinsim.Target(hold.w0, jnp.array([0.05, 0.0, 0.0, 0.0, 0.0, 0.2, 0.0]), 0.5, 2.0),
        kinsim.Target(hold.w0, jnp.array([0.0, 0.03, -0.02, 0.1, 0.0, 0.0, 0.0]), 1.0, 3.0),
    ]
    cps, targets = _strong(cps), _strong(targets)

    def stack(xs):
        return jax.tree_util.tree_map(lambda *a: jnp.stack(a), *xs)

    plant = _strong(kinsim.PlantParams())
    batch = _np(_FB_BATCH(_strong(x0), stack(targets), stack(cps), plant))
    sigmas = set()
    for i in range(3):
        one = _np(_FB(_strong(x0), targets[i], cps[i], plant))
        for key, value in one.items():
            np.testing.assert_allclose(batch[key][i], value, rtol=1e-9, atol=1e-11, err_msg=key)
        sigmas.add(tuple(one["sigma"].tolist()))
    assert len(sigmas) == 3  # the three schedules differ (commanded at 2 s, at 1 s, automatic)


# ------------------------------------------------------ feedforward vs feedback (IV-C2)
BETA_TARGET = kinsim.Target(jnp.asarray(W0), jnp.array([0.0, 0.0, 0.0, 0.0, -0.3, 0.0, 0.0]), 0.5, 1.0)


def test_feedforward_equals_feedback_while_nothing_saturates():
    cp = control.ControlParams(enter_ratio=2.0)
    ff, fb = _run(_FF, X0, BETA_TARGET, cp), _run(_FB, X0, BETA_TARGET, cp)
    assert np.abs(fb["u"][:, :12]).max() < kinsim.JOINT_SPEED_MAX  # unclipped
    for key in ("w", "phi", "base", "error", "u", "V"):
        np.testing.assert_allclose(ff[key], fb[key], rtol=0, atol=1e-12, err_msg=key)
    np.testing.assert_allclose(ff["ctrl_error"], ff["error"], rtol=0, atol=1e-12)


def test_servo_limit_feedforward_lags_then_catches_up_feedback_winds_up():
    """beta of the gripper tip changed by -0.3 rad in 1 s needs psi_1, psi_2 at 1.7 and
    1.1 rad/s; servos limited to 0.5 rad/s lag behind their target angles (the
    integrated commands). Feedforward: its own estimate follows the target (ctrl_error
    < 0.02 rad) while the true beta lags by > 0.1 rad during the change; once the target
    stops, the position servos reach their targets and the true error vanishes (< 1e-3).
    Feedback reads the lagging plant and keeps integrating joint targets: they wind up
    and the tip overshoots after the change (> 0.1 rad off 1.5 s after it), converging
    much later: one reason to run the robot feedforward (Sec. IV-C2)."""
    cp = control.ControlParams(enter_ratio=2.0)
    slow = kinsim.PlantParams(joint_speed_max=0.5)
    ff, fb = _run(_FF, X0, BETA_TARGET, cp, slow), _run(_FB, X0, BETA_TARGET, cp, slow)
    assert np.abs(fb["u"][:, :12]).max() == pytest.approx(0.5)  # it did clip
    assert np.abs(ff["u"][:, :12]).max() == pytest.approx(0.5)
    ff_true = np.abs(ff["error"]).max(axis=1)
    assert np.abs(ff["ctrl_error"]).max() < 0.02
    assert ff_true.max() > 0.1 and np.abs(ff["error"][:, 4]).max() > 0.2  # beta lags
    assert ff_true[-1] < 1e-3  # caught up
    end = float(BETA_TARGET.t0 + BETA_TARGET.duration)
    fb_true = np.abs(fb["error"]).max(axis=1)
    assert fb_true[TIMES > end + 1.0].max() > 0.1  # wound-up targets overshoot
    assert fb_true[-1] < 0.05 and fb_true[-1] > 10 * ff_true[-1]


# ------------------------------------------------------------------- Table III (V-A)
def test_table3_relative_accuracy_in_the_kinematic_model():
    """The six experiments of Table III (head controlled, each component changed alone):
    without wheel slip the error of the changed component is the Euler integration
    error only (measured <= 0.0025 %; the paper's robot: up to 34 % from slip), every
    other component stays within 0.03 mm / mrad, the fixing state sigma = 1 throughout."""
    out = experiments.run_accuracy_kinematic()
    err, disp = out["error"], out["displacement"]
    assert err.shape == (6,) and np.all(err < 0.1), err
    off = disp - np.diag(np.diagonal(disp))
    assert np.abs(off).max() < 1e-4, off
    np.testing.assert_allclose(np.diagonal(disp), experiments.ACCURACY_DELTAS, rtol=1e-3)
    recs = out["records"]
    assert np.all(np.asarray(recs["sigma"]) == 1)
    assert np.asarray(recs["t"]).shape == (6, 501)
