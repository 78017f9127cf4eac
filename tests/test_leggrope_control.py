"""The leg-grope controller's pure parts: the A' COG inside pi_g (`control.swing_cog`),
the four-leg twist relief (`control.twist_mode`, `control.twist_relief`) and the in-plane
load sharing (`control.shear_relief`), checked against closed forms (barycentric
statics, a rigid plate on four springs)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxloco.robots.leggrope import control, gait
from jaxloco.robots.leggrope.params import default_params

jax.config.update("jax_enable_x64", True)

RECT = np.array([[0.15, 0.1], [0.15, -0.1], [-0.15, -0.1], [-0.15, 0.1]])


def test_twist_mode_is_a_unit_null_load_with_alternating_signs():
    xy = RECT + np.random.default_rng(0).normal(0, 0.01, (4, 2))
    n = np.asarray(control.twist_mode(jnp.asarray(xy)))
    A = np.vstack([np.ones(4), xy.T])
    assert np.allclose(A @ n, 0.0, atol=1e-12)  # no net force, no moment about x or y
    assert np.linalg.norm(n) == pytest.approx(1.0)
    assert np.all(np.sign(n) == np.sign(n[0]) * np.array([1, -1, 1, -1]))  # diagonals share a sign


def _plate_loads(xy: np.ndarray, offsets: np.ndarray, cog: np.ndarray, weight: float, k: float) -> np.ndarray:
    """Vertical loads of a rigid plate (heave z, slopes a, b) on four legs of vertical
    stiffness k whose toes are commanded `offsets` [m] up from an even stance: a raised
    toe shortens its leg, f_i = -k (z + a x_i + b y_i + offsets_i) (all legs loaded), in
    equilibrium with `weight` at `cog`."""
    B = np.column_stack([np.ones(4), xy])  # f = -k (B s + offsets), s = (z, a, b)
    A = np.vstack([np.ones(4), xy.T])  # A f = (W, W x_c, W y_c)
    s = -np.linalg.solve(A @ B, np.array([weight, weight * cog[0], weight * cog[1]]) / k + A @ offsets)
    return -k * (B @ s + offsets)


def test_twist_relief_drives_a_twisted_stance_to_the_least_squares_loads():
    """A plate on four stiff springs with one foot 3 mm too low carries a twist; the relief,
    applied period after period, raises the overloaded diagonal until the loads are the
    twist-free (minimum-norm) distribution, with the same resultant throughout."""
    k, weight, cog = 7500.0, 70.0, np.array([0.02, 0.01])
    offsets = np.array([-0.003, 0.0, 0.0, 0.0])  # foot 0 pushed 3 mm into the ground
    f0 = _plate_loads(RECT, offsets, cog, weight, k)
    A = np.vstack([np.ones(4), RECT.T])
    least_squares = np.linalg.pinv(A) @ np.array([weight, weight * cog[0], weight * cog[1]])
    assert np.max(np.abs(f0 - least_squares)) > 5.0  # a real twist to start from
    gain = 0.02 * 0.02 / weight  # the walk's default: 0.02 m/s per M g, 20 ms periods
    for _ in range(300):
        f = _plate_loads(RECT, offsets, cog, weight, k)
        offsets = offsets + np.asarray(control.twist_relief(jnp.asarray(f), jnp.asarray(RECT), gain))
    assert np.allclose(A @ f, A @ f0)
    assert np.max(np.abs(f - least_squares)) < 0.01 * weight


def test_twist_relief_raises_the_toes_that_carry_the_twist():
    """Sign convention: the offsets are toe height changes (up positive) that unload the
    diagonal carrying the excess."""
    n = np.asarray(control.twist_mode(jnp.asarray(RECT)))
    f = 20.0 + 5.0 * n  # a positive twist on top of an even stance
    dz = np.asarray(control.twist_relief(jnp.asarray(f), jnp.asarray(RECT), 1e-4))
    assert np.all(np.sign(dz) == np.sign(n))


def _plate_shear(xy: np.ndarray, offsets: np.ndarray, total: np.ndarray, k: float) -> np.ndarray:
    """In-plane reactions (4, 2) on four fixed toes of a rigid plate (translation u,
    rotation phi about the toes' centroid) whose legs, of in-plane stiffness k, pull each
    toe towards its command, moved by `offsets` (4, 2): f_i = -k (offsets_i + u + phi t_i),
    t_i the rotation direction, with resultant `total` and no moment about the normal
    axis."""
    c = xy - xy.mean(axis=0)
    t = np.column_stack([-c[:, 1], c[:, 0]])
    # unknowns (u_x, u_y, phi): sum f = total, sum t . f = 0
    B = np.zeros((4, 2, 3))
    B[:, 0, 0] = B[:, 1, 1] = 1.0
    B[:, :, 2] = t
    lhs = np.einsum("lij,lik->jk", B, B)  # rows: sum of f (x, y) and the moment, per unit k
    rhs = -np.einsum("lij,li->j", B, offsets) - np.concatenate([total, [0.0]]) / k
    s = np.linalg.solve(lhs, rhs)
    return -k * (offsets + np.einsum("lij,j->li", B, s))


def test_shear_relief_shares_the_in_plane_load_by_normal_load():
    """A plate on four stiff legs shares a slope's tangential load equally by stiffness;
    with unequal normal loads the lightest toe then uses most of its friction cone. The
    relief, applied period after period, drives the toes to the shares N_i / sum N of the
    resultant (up to the rotation the plate's moment balance fixes), keeping the
    resultant: the friction ratios equalize."""
    k, weight = 4000.0, 70.0
    normal = np.array([10.0, 25.0, 20.0, 15.0])
    total = np.array([18.0, 0.0])  # M g sin(pi/12) up the slope
    offsets = np.zeros((4, 2))
    f0 = _plate_shear(RECT, offsets, total, k)
    ratio0 = np.linalg.norm(f0, axis=1) / normal
    gain = 0.1 * 0.02 / weight  # the walk's default: 0.1 m/s per M g, 20 ms periods
    for _ in range(400):
        f = _plate_shear(RECT, offsets, total, k)
        force = np.column_stack([f, normal])
        offsets = offsets + np.asarray(control.shear_relief(jnp.asarray(force), jnp.asarray(np.column_stack(
            [RECT, np.zeros(4)])), gain))[:, :2]
    assert np.allclose(f.sum(axis=0), total)
    # the fixed point: the shares by normal load plus a rotation (the moment balance)
    c = RECT - RECT.mean(axis=0)
    t = np.column_stack([-c[:, 1], c[:, 0]])
    excess = f - normal[:, None] / normal.sum() * total
    excess -= np.sum(excess * t) / np.sum(t * t) * t
    assert np.max(np.abs(excess)) < 1e-3 * np.linalg.norm(total)
    ratio = np.linalg.norm(f, axis=1) / normal
    assert np.ptp(ratio0) > 0.2  # unequal to start from
    assert np.ptp(ratio) < 0.3 * np.ptp(ratio0)
    assert np.max(ratio) < np.max(ratio0) - 0.1


def test_shear_relief_moves_an_overloaded_toe_along_its_excess_and_sums_to_zero():
    normal = np.full(4, 20.0)
    f = np.tile([4.0, 0.0], (4, 1))
    f[0] += [3.0, 1.0]  # toe 0 carries more than its share
    f[2] -= [3.0, 1.0]  # the diagonal toe less (no net change)
    toes = np.column_stack([RECT, np.zeros(4)])
    off = np.asarray(control.shear_relief(jnp.asarray(np.column_stack([f, normal])), jnp.asarray(toes), 1e-3))
    assert np.allclose(off.sum(axis=0), 0.0, atol=1e-15)
    assert np.allclose(off[:, 2], 0.0)
    assert off[0, :2] @ np.array([3.0, 1.0]) > 0 > off[2, :2] @ np.array([3.0, 1.0])  # along the excess


def test_a_probed_toe_returns_from_its_push_at_v_release():
    """The toe command's return from the push: straight, at most v_release * dt per period,
    all of what is left once that is shorter; nothing moves where nothing is left."""
    settings = control.GropeSettings()
    step = settings.v_release * settings.control_dt  # 2 mm at 0.1 m/s, 20 ms periods
    push = np.array([0.0, 0.003, 0.004])  # 5 mm back up along a tilted normal
    release = np.zeros((4, 3))
    release[1] = push
    toe, periods = np.zeros((4, 3)), 0
    while np.any(release != 0.0):
        d = np.asarray(control.release_step_of(jnp.asarray(release), step))
        assert np.linalg.norm(d[1]) <= step + 1e-15 and np.all(d[[0, 2, 3]] == 0.0)
        assert np.allclose(np.cross(d[1], push), 0.0) and d[1] @ push > 0  # along the return
        toe, release, periods = toe + d, release - d, periods + 1
        assert periods <= 10
    assert np.allclose(toe[1], push) and periods == 3  # 2 + 2 + 1 mm


def _barycentric(p: np.ndarray, tri: np.ndarray) -> np.ndarray:
    T = np.column_stack([tri[0] - tri[2], tri[1] - tri[2]])
    w = np.linalg.solve(T, p - tri[2])
    return np.array([w[0], w[1], 1.0 - w.sum()])


@pytest.mark.parametrize("factor", [0.4, 0.5])
def test_swing_cog_keeps_every_stance_load_within_r_ref(factor):
    """Paper, step A' (Fig. 10): the COG moves inside pi_g of the three legs that stay
    down, so that each carries at most R_ref when the groping leg lifts. Checked by
    statics: the COG's barycentric weights in the stance triangle (the vertical loads
    / M g) are at most h_ref = R_ref / (M g cos theta_n) for every grope of the forward
    crawl at pi/12. At 1/2 the design's safe_blend already suffices."""
    design = gait.DESIGNS["mirrored"]
    robot = default_params().with_(r_ref_factor=factor)
    terrain = gait.simple_slope(jnp.float64(np.pi / 12), jnp.float64(0.0))
    plan = jax.jit(gait.plan_cycle, static_argnums=3)(robot, design.walk(), terrain, design.config())
    swing_cog = jax.jit(control.swing_cog, static_argnums=3)
    overloaded = False
    for k in range(4):
        g = design.order[k]
        cog = np.asarray(swing_cog(robot, terrain, plan, design.order, k, 0.4, 0.005))
        stance = [n for n in range(4) if n != g]
        w = _barycentric(cog, np.asarray(plan.feet[k, stance, :2]))
        assert np.all(w > 0) and np.all(w <= factor + 1e-9), (k, w)
        blended = np.asarray(plan.cog_target[k + 1]) + 0.4 * (
            np.asarray(plan.feet[k, stance, :2]).mean(0) - np.asarray(plan.cog_target[k + 1]))
        if factor == 0.5:
            assert np.allclose(cog, blended)
        else:  # the rule is needed: the blend alone overloads a stance leg in some grope
            overloaded = overloaded or np.max(_barycentric(blended, np.asarray(plan.feet[k, stance, :2]))) > factor
    assert factor == 0.5 or overloaded


def test_touchdown_slows_only_near_the_mapped_surface():
    """C* lowers the toe at v_touch, at v_contact within touch_band of the surface the
    map predicts (clearance below the swing's end point), and at v_touch again below it
    (a collapsed pad: the toe must reach probe_depth before the phase times out)."""
    s = control.GropeSettings()
    n = jnp.array([0.0, -np.sin(0.3), np.cos(0.3)])
    above = jnp.array([0.1, 0.2, 0.05])
    for depth, speed in [(0.0, s.v_touch), (s.clearance - 0.5 * s.touch_band, s.v_contact),
                         (s.clearance + 0.5 * s.touch_band, s.v_contact), (s.clearance + 2 * s.touch_band, s.v_touch)]:
        toe = above - depth * n
        step = np.asarray(toe - control.touch_command(toe, above, n, s))
        np.testing.assert_allclose(step, speed * s.control_dt * np.asarray(n), atol=1e-12)
    assert s.v_contact < s.v_touch
    # a toe that finds nothing reaches probe_depth below the surface well inside the phase
    # timeout; lowered at v_contact all the way it would not (the walk timed out instead of
    # regroping a fallback)
    band = 2 * s.touch_band
    assert (s.clearance + s.probe_depth - band) / s.v_touch + band / s.v_contact < 0.6 * s.phase_timeout
    assert (s.clearance + s.probe_depth) / s.v_contact >= s.phase_timeout

