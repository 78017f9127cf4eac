"""The force-distribution QP (paper Eqs. 11-22): against clarabel, statics, the
rigid-block friction limit atan(mu), and the paper's example cycle (theta = pi/12,
psi = 0; Figs. 7-9)."""

import functools
import math

import clarabel
import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.sparse as sp

from jaxloco import qp
from jaxloco.robots.leggrope import forces, gait
from jaxloco.robots.leggrope.params import G as GRAVITY
from jaxloco.robots.leggrope.params import default_params

P = default_params()
CFG = gait.WalkConfig()
WALK = gait.WalkParams()
SET = forces.QPSettings()
WEIGHT = float(P.total_mass) * GRAVITY


def _step_problem(theta, psi, i, params=P, tau_b=None):
    """The step QP (Q, q, A, b, G, h), dynamics, step info and leg modes of step `i` of
    the cycle planned on the slope (theta, psi), as one jitted program (op by op it
    compiled ~800 one-operation programs)."""
    return _step_problem_jit(theta, psi, i, params, np.zeros(12) if tau_b is None else tau_b)


@jax.jit
def _step_problem_jit(theta, psi, i, params, tau_b):
    terrain = gait.simple_slope(theta, psi)
    plan = gait.plan_cycle(params, WALK, terrain, CFG)
    info = gait.step_info(i, CFG, params.dt)
    dyn = forces.step_dynamics(params, WALK, plan, terrain, info, CFG)
    ramp = jnp.where(info.phase == 1, 15.0 * (1 - info.fraction), 0.5 * WEIGHT * jnp.cos(theta) * info.fraction)
    modes = forces.leg_modes(info, ramp)
    r_ref = 0.5 * WEIGHT * jnp.cos(theta)
    A, b, Gm, h = forces.build_constraints(params, dyn, modes, r_ref, jnp.asarray(-SET.s_tol * WEIGHT))
    Q, q = forces.controller_cost(params, dyn, tau_b, jnp.asarray(params.h_c, jnp.float64), SET)
    return (Q, q, A, b, Gm, h), dyn, info, modes


def _solve(problem, params=P, iterations=SET.iterations):
    """`qp.solve` of a step problem (jitted) with the controller's scaling and tolerance."""
    return _solve_jit(problem, forces.x_scale(params, jnp.float64), iterations)


@functools.partial(jax.jit, static_argnums=2)
def _solve_jit(problem, x_scale, iterations):
    return qp.solve(*problem, x_scale=x_scale, iterations=iterations, tol=SET.tol)


def _clarabel(Q, q, A, b, Gm, h):
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = 1e-10
    P_ = sp.csc_matrix(np.triu(np.asarray(Q)))
    M = sp.csc_matrix(np.vstack([np.asarray(A), np.asarray(Gm)]))
    cones = [clarabel.ZeroConeT(A.shape[0]), clarabel.NonnegativeConeT(Gm.shape[0])]
    sol = clarabel.DefaultSolver(
        P_, np.asarray(q), M, np.concatenate([np.asarray(b), np.asarray(h)]), cones, settings
    ).solve()
    return sol


@pytest.mark.parametrize("step", [5, 60, 105, 140, 170, 185, 410])  # phases A, A, B, C, C, D, C
def test_step_qp_matches_clarabel(step):
    problem, _, info, _ = _step_problem(0.2, 0.5, step, tau_b=jnp.linspace(-1.0, 1.0, 12))
    ours = _solve(problem)
    ref = _clarabel(*problem)
    assert bool(ours.ok) and "Solved" in str(ref.status)
    # forces, s and r agree to a millionth of the robot's weight
    np.testing.assert_allclose(np.asarray(ours.x[:14]) / WEIGHT, np.asarray(ref.x[:14]) / WEIGHT, atol=1e-6)


def test_static_step_wrench_is_the_weight_about_the_cog():
    """Nothing moves in phase B: the ground must carry exactly the weight, with the
    moment of the weight acting at the whole-body COG (computed independently)."""
    _, dyn, _, _ = _step_problem(0.3, 0.8, 105)
    np.testing.assert_allclose(dyn.wrench[:3], [0.0, 0.0, WEIGHT], atol=1e-9)
    expected = np.cross(np.asarray(dyn.cog - dyn.origin), [0.0, 0.0, WEIGHT])
    np.testing.assert_allclose(dyn.wrench[3:], expected, atol=1e-9)


def test_moving_body_needs_its_inertial_force():
    """Early in phase A the body accelerates at a_max: the horizontal ground force is the
    mass times acceleration of body and legs (legs move less than the body)."""
    _, dyn, _, _ = _step_problem(0.0, 0.0, 2)
    horizontal = float(jnp.linalg.norm(dyn.wrench[:2]))
    assert float(P.body_mass) * float(P.a_max) * 0.99 < horizontal < WEIGHT / GRAVITY * float(P.a_max) * 1.01


@pytest.mark.parametrize("mu", [0.45, 0.7])
def test_static_friction_limit_is_atan_mu(mu):
    """At rest on four legs (first step of phase B) a slip-free distribution exists iff
    tan(theta) <= mu: the rigid-block limit the paper compares with."""
    params = P.with_(mu=mu)
    limit = math.atan(mu)
    for theta, feasible in ((limit - 0.004, True), (limit + 0.004, False)):
        problem, _, info, _ = _step_problem(theta, 0.0, 100, params=params)
        assert int(info.phase) == 1
        sol = _solve(problem, params, iterations=30)
        assert bool(sol.ok) == feasible, (mu, theta)


@pytest.fixture(scope="module")
def paper_cycle():
    """One cycle at theta = pi/12, psi = 0 (the paper's Figs. 7-9), recorded."""
    terrain = gait.simple_slope(jnp.asarray(math.pi / 12), jnp.asarray(0.0))
    return jax.jit(lambda: forces.simulate_cycle(P, WALK, terrain, CFG, SET, record=True))()


def test_paper_cycle_is_slip_free_and_probes_every_foothold(paper_cycle):
    plan, summary, trace = paper_cycle
    ok = np.asarray(trace["ok"])
    assert ok.all() and int(summary.n_qp_failed) == 0
    f = np.asarray(trace["forces"])
    r_ref = float(trace["r_ref"][0])
    assert r_ref == pytest.approx(0.5 * WEIGHT * math.cos(math.pi / 12))
    s = np.asarray(trace["s"])
    assert s.min() >= -SET.s_tol * WEIGHT - 1e-9  # Fig. 8: s never (meaningfully) below 0
    phase, grope = np.asarray(trace["phase"]), np.asarray(trace["grope"])
    for k, leg in enumerate(CFG.order):
        in_d = np.nonzero((grope == k) & (phase == 3))[0]
        in_c = (grope == k) & (phase == 2)
        # the groping leg presses up to R_ref (within the reported relaxation) ...
        relax = float(summary.max_overshoot)
        assert f[in_d[-1], leg, 2] == pytest.approx(r_ref, abs=relax + 1e-6)
        # ... and is in the air during its swing
        np.testing.assert_allclose(f[in_c, leg], 0.0, atol=1e-9)
    # every other normal force stays within R_ref up to the small relaxation
    free = np.asarray(trace["free"])
    assert f[..., 2][free].max() <= r_ref * 1.1
    assert float(summary.max_overshoot) < 0.1 * r_ref
    # unilateral contact and friction pyramid of every loaded leg
    loaded = free | np.asarray(trace["ramp"])
    assert (f[..., 2][loaded] >= -1e-9).all()
    use = np.abs(f[..., 0]) + np.abs(f[..., 1]) - P.mu * f[..., 2]
    assert use[loaded].max() <= 2 * SET.s_tol * WEIGHT * math.sqrt(2) + 1e-9


def test_paper_cycle_torques_are_smooth(paper_cycle):
    """Fig. 9: torque continuity (h_c = 80) keeps step-to-step changes small."""
    _, _, trace = paper_cycle
    tau = np.asarray(trace["tau"])
    assert np.abs(tau).max() < 10.0
    assert np.abs(np.diff(tau, axis=0)).max() < 1.0


def test_paper_cycle_keeps_static_stability(paper_cycle):
    _, summary, trace = paper_cycle
    assert float(summary.min_static_margin) > 0.0
    assert float(summary.min_ne_margin) > 0.0
    assert float(summary.min_reach) > 0.0
