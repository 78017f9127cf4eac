"""The leg-grope walk cycle plan and motion: the forward-walk impossibility, motion
limits, plan invariance on slopes, body placement, continuity of the motion."""

from dataclasses import replace

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxloco import geometry as geo
from jaxloco.robots.leggrope import gait
from jaxloco.robots.leggrope.params import default_params

P = default_params()
CFG = gait.WalkConfig()
WALK = gait.WalkParams()


@pytest.fixture(scope="module")
def plans():
    """Plans on a few slopes and directions (one compiled, vmapped planner)."""
    th = jnp.array([0.0, 0.25, -0.4, 0.4, 0.1])
    ps = jnp.array([0.0, 0.7, -1.2, 1.5707963, -1.5707963])
    f = jax.jit(jax.vmap(lambda t, p: gait.plan_cycle(P, WALK, gait.simple_slope(t, p), CFG)))
    return th, ps, f(th, ps)


@jax.jit
@jax.vmap
def _antimedial_margin(target, stance):
    """Margin of a groped foothold inside pi_grp,all of the three stance feet, which for
    h_ref = 1/2 is the triangle with the stance feet at its edge midpoints (tested in
    test_leggrope_regions.py)."""
    a, b, c = stance
    tri, ok = geo.convex_hull(jnp.stack([b + c - a, c + a - b, a + b - c]), jnp.ones(3, bool))
    return geo.polygon_signed_distance(target, tri, ok)


def test_forward_walk_with_paper_order_is_impossible():
    """With L1..L4 clockwise from the left front and groping order L2, L1, L3, L4, a walk
    along x_R cannot have both front gropes admissible (h_ref = 1/2): checked on random
    stances and sideways shifts."""
    rng = np.random.default_rng(0)
    # L1 left-front, L2 right-front, L3 right-rear, L4 left-rear, in (x_R, y_R)
    base = np.array([[0.2, 0.2], [0.2, -0.2], [-0.2, -0.2], [-0.2, 0.2]])
    n = 2000
    feet = base + rng.normal(0.0, 0.05, (n, 4, 2))
    step = np.array([0.05, 0.0])
    lat = rng.normal(0.0, 0.04, (n, 2))
    t2 = feet[:, 1] + step + np.column_stack([np.zeros(n), lat[:, 0]])
    ok2 = np.asarray(_antimedial_margin(jnp.asarray(t2), jnp.asarray(feet[:, [0, 2, 3]]))) > 0
    after = feet.copy()
    after[:, 1] = t2
    t1 = feet[:, 0] + step + np.column_stack([np.zeros(n), lat[:, 1]])
    ok1 = np.asarray(_antimedial_margin(jnp.asarray(t1), jnp.asarray(after[:, [1, 2, 3]]))) > 0
    assert ok2.sum() > 50 and ok1.sum() > 50  # each grope alone is often admissible ...
    assert not np.any(ok1 & ok2)  # ... but never both: L1 cannot move away from line L3-L4


def test_sideways_walk_plan_is_at_the_knife_edge(plans):
    """The designed sideways walk is (nearly) admissible on every slope: the smallest
    margin is the design value (about -1.7 mm), far from the forward walk's failure."""
    _, _, pl = plans
    assert float(jnp.min(jax.vmap(lambda p: p.margin)(pl))) > -2.5e-3
    assert float(jnp.min(pl.reach_margin)) > 0.005


def test_plan_is_invariant_on_slopes(plans):
    """Planning in slope coordinates with the COG's vertical projection makes the plan's
    geometry affine-invariant: with massless legs (no swing shift of the COG) every margin
    is the same on every slope and direction; with the real legs the swinging leg's mass
    moves them by millimetres."""
    th, ps, pl = plans
    massless = P.with_(link_masses=np.zeros(3))
    f = jax.jit(jax.vmap(lambda t, p: gait.plan_cycle(massless, WALK, gait.simple_slope(t, p), CFG)))
    ideal = f(th, ps)
    for m in (ideal.cog_margin, ideal.grope_margin):
        np.testing.assert_allclose(m, np.broadcast_to(m[0], m.shape), atol=1e-9)
    margins = jax.vmap(lambda p: p.margin)(pl)
    assert float(jnp.max(margins) - jnp.min(margins)) < 3e-3


def test_footsteps_and_body_placement(plans):
    th, ps, pl = plans
    for k in range(len(th)):
        terrain = gait.simple_slope(th[k], ps[k])
        plan = jax.tree_util.tree_map(lambda x: x[k], pl)
        # every foot moved once: stride forward plus its designed sideways shift
        uv = lambda p: gait.world_xy_to_uv(terrain, p[:2])  # noqa: E731
        for leg in range(4):
            d = uv(plan.feet[4][leg]) - uv(plan.feet[0][leg])
            np.testing.assert_allclose(d, [WALK.stride, WALK.lateral[leg]], atol=1e-12)
        # feet on the slope plane, body at body_height above it
        n = gait.slope_rotation(terrain.theta)[:, 2]
        np.testing.assert_allclose(plan.feet @ n, 0.0, atol=1e-12)
        np.testing.assert_allclose(plan.body @ n, P.body_height, atol=1e-12)
        # the whole-body COG projects vertically onto each target
        for i in range(1, 5):
            cog = gait.whole_body_cog(P, plan.R_GR, plan.body[i], plan.feet[i])
            np.testing.assert_allclose(cog[:2], plan.cog_target[i], atol=1e-10)


def test_trapezoid_profile_limits():
    a, v = 0.15, 0.1
    for d in (0.01, 0.0667, 0.08):
        t = jnp.linspace(0.0, 3.0, 3001)
        s, total = gait.trapezoid(t, jnp.asarray(d), a, v)
        vel = jax.vmap(jax.grad(lambda x: gait.trapezoid(x, jnp.asarray(d), a, v)[0]))(t)
        acc = jax.vmap(jax.grad(jax.grad(lambda x: gait.trapezoid(x, jnp.asarray(d), a, v)[0])))(t)
        assert float(jnp.max(jnp.abs(vel))) <= v + 1e-12
        assert float(jnp.max(jnp.abs(acc))) <= a + 1e-12
        assert float(s[-1]) == pytest.approx(d)
        expected = 2 * np.sqrt(d / a) if d < v * v / a else d / v + v / a
        assert float(total) == pytest.approx(expected)
        assert np.all(np.diff(np.asarray(s)) >= -1e-15)


def test_step_info_covers_the_cycle():
    infos = jax.vmap(lambda i: gait.step_info(i, CFG, P.dt))(jnp.arange(CFG.n_steps))
    counts = np.zeros((4, 4), int)
    np.add.at(counts, (np.asarray(infos.grope), np.asarray(infos.phase)), 1)
    assert (counts == np.array(CFG.phase_lengths())[None, :]).all()
    np.testing.assert_array_equal(np.asarray(infos.leg)[:: CFG.steps_per_grope], CFG.order)
    assert float(jnp.max(infos.fraction)) == 1.0


def test_motion_is_continuous_and_rests_between_phases(plans):
    _, _, pl = plans
    plan = jax.tree_util.tree_map(lambda x: x[1], pl)
    for k in range(4):
        base = k * CFG.steps_per_grope
        end_a = gait.step_info(jnp.asarray(base + CFG.n_move - 1), CFG, P.dt)
        body, feet = gait.pose_at(P, WALK, plan, end_a, end_a.tau, CFG)
        np.testing.assert_allclose(body, plan.body[k + 1], atol=1e-12)
        vel = jax.jacfwd(lambda t: gait.pose_at(P, WALK, plan, end_a, t, CFG)[0])(end_a.tau)
        np.testing.assert_allclose(vel, 0.0, atol=1e-12)
        end_c = gait.step_info(jnp.asarray(base + CFG.n_move + CFG.n_unload + CFG.n_swing - 1), CFG, P.dt)
        _, feet = gait.pose_at(P, WALK, plan, end_c, end_c.tau, CFG)
        np.testing.assert_allclose(feet, plan.feet[k + 1], atol=1e-12)


def test_planner_vmap_equals_loop(plans):
    th, ps, pl = plans
    single = jax.jit(lambda t, p: gait.plan_cycle(P, WALK, gait.simple_slope(t, p), CFG))(th[2], ps[2])
    np.testing.assert_allclose(single.body, pl.body[2], atol=1e-10)
    np.testing.assert_allclose(single.cog_margin, pl.cog_margin[2], atol=1e-10)


def test_irregular_slope_keeps_inclination():
    t = gait.irregular_slope(jnp.asarray(0.3), jnp.asarray(0.0), jnp.asarray(0.8), jax.random.PRNGKey(3))
    np.testing.assert_allclose(jnp.arccos(t.normals[..., 2]), 0.3, atol=1e-12)
    assert float(jnp.std(jnp.arctan2(t.normals[..., 1], t.normals[..., 0]))) > 0.05
    same = replace(t, normals=gait.simple_slope(jnp.asarray(0.3), jnp.asarray(0.0)).normals)
    np.testing.assert_allclose(same.normals[..., 2], np.cos(0.3))


# ------------------------------------------------------- the mirrored numbering ---------
MIRRORED = gait.DESIGNS["mirrored"]


@pytest.fixture(scope="module")
def mirrored_plans():
    """The mirrored design's plans on level ground and the pi/12 slope (psi = 0) with its
    collapse-safe COG rule, and the literal design's with the same rule (one compile each)."""
    th = jnp.array([0.0, np.pi / 12])

    def plans_of(design):
        walk, cfg = design.walk(), replace(design.config(), cog_rule="collapse_safe")
        return jax.jit(jax.vmap(lambda t: gait.plan_cycle(P, walk, gait.simple_slope(t, 0.0), cfg)))(th)

    return th, plans_of(MIRRORED), plans_of(gait.DESIGNS["literal"])


def test_mirrored_numbering_crawls_forward_along_x_r(mirrored_plans):
    """L1 left front, L2 left rear, L3 right rear, L4 right front (seen from above): the
    order L2, L1, L3, L4 is physical legs 3, 0, 2, 1 (each side rear then front, the
    classical crawl), and one cycle carries the body `stride` along +x_R."""
    assert MIRRORED.order == (3, 0, 2, 1) and gait.DESIGNS["literal"].order == (1, 0, 2, 3)
    _, pl, _ = mirrored_plans
    for i in range(2):
        R_GR = pl.R_GR[i]
        d_body = (pl.body[i, 4] - pl.body[i, 0]) @ R_GR  # body frame
        assert d_body[0] > 0.8 * MIRRORED.walk().stride and abs(d_body[1]) < 0.3 * d_body[0]
        d_feet = (pl.feet[i, 4] - pl.feet[i, 0]) @ R_GR
        np.testing.assert_allclose(d_feet[:, 0], MIRRORED.walk().stride, atol=1e-12)


def _max_grope_share(feet_uv: np.ndarray, g: int, c: np.ndarray, h_ref: float) -> float:
    """Independent oracle (scipy's LP): the largest share h_g of the weight the groping leg
    g can take with the COG at c while the other legs carry between 0 and h_ref (vertical
    forces, the paper's Eqs. 2-8 with any float leg)."""
    from scipy.optimize import linprog

    a_eq = np.vstack([np.ones(4), feet_uv.T])
    bounds = [(0.0, 1.0) if n == g else (0.0, h_ref) for n in range(4)]
    res = linprog(-np.eye(4)[g], A_eq=a_eq, b_eq=np.concatenate([[1.0], c]), bounds=bounds, method="highs")
    return -res.fun if res.success else -np.inf


def test_collapse_safe_design_gropes_to_r_ref_inside_the_other_three_legs(mirrored_plans):
    """The designer: at every grope of the mirrored design the groping leg can
    take R_ref (checked by an LP, not by the planner's regions) while the COG stays at
    least 10 mm inside the triangle of the other three legs (so a collapse leaves the
    robot standing); the literal design with the same rule reaches under 5 mm."""
    th, pl, lit = mirrored_plans
    for i in range(len(th)):
        terrain = gait.simple_slope(th[i], 0.0)
        uv = lambda p: np.asarray(gait.world_xy_to_uv(terrain, p[:2]))  # noqa: E731
        for k, g in enumerate(MIRRORED.order):
            feet = np.stack([uv(f) for f in pl.feet[i, k + 1]])  # the groped foot landed
            c = uv(pl.cog_target[i, k + 1])
            h_ref = float(pl.h_ref[i, 1, g])
            assert _max_grope_share(feet, g, c, h_ref) > h_ref + 0.01
            others = feet[[n for n in range(4) if n != g]]
            cross = lambda a, b: a[0] * b[1] - a[1] * b[0]  # noqa: E731
            area2 = cross(others[1] - others[0], others[2] - others[0])
            dists = [np.sign(area2) * cross(others[(j + 1) % 3] - others[j], c - others[j])
                     / np.linalg.norm(others[(j + 1) % 3] - others[j]) for j in range(3)]
            assert min(dists) == pytest.approx(float(pl.triangle_margin[i, k]), abs=1e-9)
            assert min(dists) > 0.010
    assert float(jnp.min(pl.rule_margin("collapse_safe"))) > 0.010
    assert float(jnp.min(jax.vmap(lambda p: p.rule_margin("collapse_safe"))(lit))) < 0.005


def test_designer_starts_from_the_shipped_design_and_keeps_its_score():
    """`design.search_footsteps(objective="collapse")` scores the shipped mirrored design at
    `gait.MIRRORED_DESIGN_MARGIN` and never returns a worse one (the best so far is kept)."""
    from jaxloco.robots.leggrope import design

    with pytest.raises(ValueError, match="unknown objective"):
        design.search_footsteps(objective="fastest")
    stance, lateral, score = design.search_footsteps(
        P, MIRRORED.walk(), MIRRORED.config(), objective="collapse", iterations=1, population=4, elite=2
    )
    assert score >= gait.MIRRORED_DESIGN_MARGIN - 5e-5
    assert stance.shape == (4, 2) and lateral.shape == (4,)
