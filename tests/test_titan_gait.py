"""TITAN XI grid step over intermittent crawl gait (Hodoshima et al. 2007, Sec. 5-6):
geometry helpers, domain prescribing and foothold search on hand-built maps, the
standard intermittent crawl gait on flat ground against closed-form margins, the frame
scenarios of Sec. 7 and 8.4, and vmap == loop."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxloco import stability as stab
from jaxloco.robots.titan import gait, kinematics, params
from jaxloco.robots.titan import maps as titan_maps

PAR = params.default_params()
SHAPE = (130, 130)  # 13 m x 13 m, 0.1 m cells
ORIGIN = jnp.zeros(2)
N_CYC = 3
CELL = jnp.asarray(params.CELL)


def _plan(gmap, start, dirs):
    return gait.plan_cycles(PAR, gmap, start, N_CYC, dirs)


plan_one = jax.jit(_plan)
plan_many = jax.jit(jax.vmap(_plan))

# (name, map kind, frame size, interval, frame offset, start xy, directions [deg])
SCEN = [
    ("flat", 0.0, 2.0, 1.0, (4.0, 6.5), (0, 0, 0)),
    ("frames 0.2 m / 2.0 m", params.FRAME_SMALL, params.GRID_SMALL, 1.0, (3.0, 6.0), (0, 0, 0)),
    ("frames 0.3 m / 3.0 m", params.FRAME_LARGE, params.GRID_LARGE, 1.5, (5.3, 5.5), (0, 0, 0)),
    (
        "slope 30 deg, 0.2 m / 1.5 m",
        params.SLOPE_FRAME,
        params.SLOPE_GRID,
        0.75,
        (3.0, 6.0),
        (0, 0, 0),
    ),
    ("left", params.FRAME_SMALL, params.GRID_SMALL, 1.0, (6.5, 3.0), (90, 90, 90)),
    ("backwards", params.FRAME_SMALL, params.GRID_SMALL, 1.0, (10.0, 6.5), (180, 180, 180)),
    ("right", params.FRAME_SMALL, params.GRID_SMALL, 1.0, (6.5, 10.0), (270, 270, 270)),
    ("turning", params.FRAME_SMALL, params.GRID_SMALL, 1.0, (3.0, 6.0), (0, 15, 0)),
    # off the body axes (gait.directional_stride): the diagonals, where the square stance
    # gets least from the lateral shift
    ("diagonal, flat", 0.0, 2.0, 1.0, (3.5, 3.5), (45, 45, 45)),
    ("diagonal, 0.2 m / 2.0 m", params.FRAME_SMALL, params.GRID_SMALL, 1.0, (3.5, 3.5), (45, 45, 45)),
    ("135 deg, 0.3 m / 3.0 m", params.FRAME_LARGE, params.GRID_LARGE, 1.5, (9.5, 3.5), (135, 135, 135)),
    ("255 deg, 0.2 m / 2.0 m", params.FRAME_SMALL, params.GRID_SMALL, 1.0, (8.0, 9.5), (255, 255, 255)),
]


_standard_start = jax.jit(gait.standard_start)  # one program, not one per operation


def _map(size, interval, off, slope=0.0):
    return titan_maps.frame_grid_map(
        SHAPE, ORIGIN, CELL, size, interval, jnp.array([off, off]), slope
    )


@pytest.fixture(scope="module")
def scenarios():
    maps, starts, dirs = [], [], []
    for name, size, interval, off, xy, deg in SCEN:
        g = _map(
            size, interval, off, params.SLOPE_ANGLE if name.startswith("slope") else 0.0
        )
        d = jnp.radians(jnp.array(deg, float))
        maps.append(g)
        starts.append(_standard_start(PAR, g, jnp.array(xy), d[0]))
        dirs.append(d)
    stack = lambda xs: jax.tree_util.tree_map(lambda *a: jnp.stack(a), *xs)
    gm, st, dr = stack(maps), stack(starts), jnp.stack(dirs)
    return gm, st, dr, plan_many(gm, st, dr)


def _take(tree, k):
    return jax.tree_util.tree_map(lambda a: a[k], tree)


# ------------------------------------------------------------------------ geometry
def test_virtual_plane_matches_numpy_lstsq():
    rng = np.random.default_rng(1)
    feet = rng.normal(size=(4, 3)) * np.array([2.0, 2.0, 0.2])
    n, off = gait.virtual_plane(jnp.asarray(feet))
    A = np.c_[np.ones(4), feet[:, :2]]
    c, *_ = np.linalg.lstsq(A, feet[:, 2], rcond=None)
    xy = rng.normal(size=(5, 2))
    np.testing.assert_allclose(
        gait.plane_height(n, off, jnp.asarray(xy)), c[0] + xy @ c[1:], atol=1e-12
    )
    assert float(n[2]) > 0


def test_fan_exit_distance_matches_ray_marching():
    rng = np.random.default_rng(2)
    checked = 0
    for _ in range(40):
        leg = int(rng.integers(4))
        q0 = np.asarray(params.NEUTRAL_FEET[leg, :2] - params.PIVOTS[leg, :2]) + rng.uniform(
            -0.8, 0.8, 2
        )
        u = rng.normal(size=2)
        u /= np.linalg.norm(u)
        t = float(gait.fan_exit_distance(jnp.asarray(q0), jnp.asarray(u), leg, PAR))
        ts = np.linspace(0.0, 5.0, 50001)
        inside = np.asarray(gait.in_fan(jnp.asarray(q0[None] + ts[:, None] * u), leg, PAR))
        if not inside[0]:
            assert t == 0.0
            continue
        t_ref = ts[np.argmin(inside)] if not inside.all() else 5.0
        assert abs(t - t_ref) < 2e-4
        checked += 1
    assert checked > 20


def test_search_order_of_section_5_3():
    offs = gait.search_offsets(2, 2)
    assert offs.shape == (25, 2)
    # I_u first, then +y / -y equidistantly along the row, then rows in -x, then +x
    np.testing.assert_array_equal(
        offs[:6], [[0, 0], [0, 1], [0, -1], [0, 2], [0, -2], [-1, 0]]
    )
    rows = offs[::5, 0]
    np.testing.assert_array_equal(rows, [0, -1, -2, 1, 2])


def test_leg_roles_follow_section_5_1():
    feet_b = jnp.asarray(params.NEUTRAL_FEET[:, :2]).at[3, 0].add(-0.3)  # RR farthest back
    roles, n_r = gait.leg_roles(feet_b, jnp.array([1.0, 0.0]))
    np.testing.assert_array_equal(
        roles, [3, 1, 2, 0]
    )  # r = RR, f = RF, r-bar = LR, f-bar = LF
    np.testing.assert_allclose(n_r, [0.0, -1.0])  # W towards the side of r
    roles, _ = gait.leg_roles(feet_b, jnp.array([1.0, 0.0]), prev=2)  # later cycles keep r
    np.testing.assert_array_equal(roles, [2, 0, 3, 1])
    roles, n_r = gait.leg_roles(
        jnp.asarray(params.NEUTRAL_FEET[:, :2]), jnp.array([0.0, 1.0])
    )  # walking left
    assert set(np.asarray(roles)[[0, 2]].tolist()) == {
        1,
        3,
    }  # the right legs are the rear legs


# ------------------------------------------------- standard gait on flat ground (Sec. 4.4)
def _closed_form_swing_margins(L, w, h):
    """NESM and longitudinal margin, by hand, of the standard intermittent crawl gait while
    the first rear leg (LR) swings. Body frame at the COG, flat ground, feet at z = 0:
    LF at its return start (x - L), RF and RR at mid stroke, all shifted by +w laterally
    (the COG is w to the right of the foot centre line)."""
    lf = (2.1 - L, 2.2 + w)
    rf = (2.1, -2.2 + w)
    rr = (-2.1, -2.2 + w)

    def rho(a, b):  # horizontal distance from the COG (origin) to the line a-b
        return abs(a[0] * b[1] - b[0] * a[1]) / math.hypot(b[0] - a[0], b[1] - a[1])

    nesm = min(
        math.sqrt(rho(a, b) ** 2 + h * h) - h for a, b in ((lf, rf), (rf, rr), (rr, lf))
    )

    def x_cross(a, b):  # where the edge a-b crosses the travel line y = 0
        return a[0] - a[1] * (b[0] - a[0]) / (b[1] - a[1])

    lon = min(
        abs(x_cross(lf, rf)), abs(x_cross(rr, lf))
    )  # front edge, rear (diagonal) edge
    return nesm, lon


def _closed_form_shift_margins(L, w, h):
    """Four-leg support during the COG shift G = (L, 2w): the side edges are 2.2 - w from
    the COG at both ends of the shift (the nearest edges)."""
    return math.sqrt((2.2 - w) ** 2 + h * h) - h


def test_flat_ground_gives_the_standard_intermittent_crawl_gait(scenarios):
    _, st, _, plans = scenarios
    plan, start = _take(plans, 0), _take(st, 0)
    L, W = params.L_STD, params.W_STD
    assert int(plan.n_failures) == 0 and int(plan.n_modifications) == 0
    np.testing.assert_allclose(plan.cycle_w, W)
    np.testing.assert_allclose(plan.cycle_l, L)
    np.testing.assert_array_equal(
        plan.swing_leg[:6], [2, 0, -1, 3, 1, -1]
    )  # LR LF shift RR RF shift
    np.testing.assert_array_equal(plan.swing_leg[6:12], plan.swing_leg[:6])
    # COG: (L, W) then (L, -W): back on the path after every cycle, 2 L_std per cycle
    c0 = np.asarray(start.cog)
    np.testing.assert_allclose(plan.cog[2] - c0, [L, W, 0.0], atol=1e-12)
    np.testing.assert_allclose(plan.cog[5] - c0, [2 * L, 0.0, 0.0], atol=1e-12)
    for k in range(N_CYC):
        np.testing.assert_allclose(
            plan.feet[6 * k + 5] - start.feet,
            np.array([2 * L * (k + 1), 0, 0]) * np.ones((4, 1)),
            atol=1e-12,
        )
    assert float(plan.distance_per_cycle) == pytest.approx(2 * L)
    assert float(plan.path_deviation) == pytest.approx(0.0, abs=1e-12)
    # the start pose is the standard one, built here by hand (body frame at the COG)
    w = W / 2
    hand = np.array(
        [[2.1 - L, 2.2 + w], [2.1, -2.2 + w], [-2.1 - L, 2.2 + w], [-2.1, -2.2 + w]]
    )
    np.testing.assert_allclose(np.asarray(start.feet[:, :2]) - c0[:2], hand, atol=1e-12)


def test_standard_gait_margins_match_closed_form(scenarios):
    plan = _take(scenarios[3], 0)
    L, w, h = params.L_STD, params.W_STD / 2, params.H_G
    # a swing's margin takes the whole-robot COM with the leg raised (gait.swing_cog)
    nesm, lon = _closed_form_swing_margins(L, w, h + kinematics.swing_com_height())
    swing = np.asarray(plan.swing_leg) >= 0
    np.testing.assert_allclose(plan.nesm[swing], nesm, rtol=1e-9)
    np.testing.assert_allclose(plan.long_margin[swing], lon, rtol=1e-9)
    np.testing.assert_allclose(
        plan.nesm[~swing], _closed_form_shift_margins(L, w, h), rtol=1e-9
    )
    assert nesm > params.S_NE_C  # the chosen W_std keeps the standard gait above S_NE^c
    # and the core kernels agree with the hand formulas on the same support
    feet = jnp.array(
        [
            [2.1 - L, 2.2 + w, 0],
            [2.1, -2.2 + w, 0],
            [-2.1 - L, 2.2 + w, 0],
            [-2.1, -2.2 + w, 0],
        ]
    )
    mask = jnp.array([True, True, False, True])
    cog = jnp.array([0.0, 0.0, h + kinematics.swing_com_height()])
    assert float(stab.ne_stability_margin(cog, feet, mask)) == pytest.approx(
        nesm, rel=1e-12
    )
    assert float(
        stab.longitudinal_margin(cog, feet, mask, jnp.array([1.0, 0.0]))
    ) == pytest.approx(lon, rel=1e-12)


# ----------------------------------------------------------- frame scenarios (Sec. 7, 8.4)
def _clearance(xy, size, interval, off):
    u = np.mod(xy - off, interval)
    return np.min(np.minimum(u, interval - u), axis=-1) - size / 2


def test_frame_scenarios_are_safe(scenarios):
    gm, _st, _dr, plans = scenarios
    for k, (name, size, interval, off, _, _) in enumerate(SCEN):
        plan = _take(plans, k)
        legs = np.asarray(plan.swing_leg)
        ok = legs >= 0
        landed = np.asarray(plan.feet)[ok, legs[ok]]
        # S_NE^c along the whole plan (held steps stand on four legs)
        assert float(plan.min_nesm) >= params.S_NE_C - 1e-9, name
        if size > 0:
            # frames never under a foot pad
            assert (
                _clearance(landed[:, :2], size, interval, off).min() > params.FOOT_RADIUS
            ), name
            # rectangular swings: vertical up, horizontal return clearing every frame the
            # pad passes over by the swing clearance, vertical down (Sec. 6.4.1)
            path = np.asarray(plan.swing_path)[ok]
            np.testing.assert_allclose(path[:, 1, 2], path[:, 2, 2])
            np.testing.assert_allclose(path[:, 0, :2], path[:, 1, :2])
            np.testing.assert_allclose(path[:, 3, :2], path[:, 2, :2])
            s = np.linspace(0.0, 1.0, 200)
            for w in path:
                line = w[1, None, :2] + s[:, None] * (w[2, :2] - w[1, :2])[None]
                if _clearance(line, size, interval, off).min() < 0:  # crosses a frame
                    assert w[1, 2] >= size + params.SWING_CLEARANCE - 1e-9, name
        # landed heights come from the unevenness map (Sec. 6.2)
        g = _take(gm, k)
        np.testing.assert_allclose(
            landed[:, 2], titan_maps.sample_height(g, jnp.asarray(landed[:, :2]))
        )


def test_paper_scenarios_walk(scenarios):
    _, _, _dr, plans = scenarios
    names = [s[0] for s in SCEN]
    for name in names[1:]:
        plan = _take(plans, names.index(name))
        assert int(plan.n_failures) == 0, name
        assert float(plan.distance_per_cycle) > 0.5, (
            name
        )  # at least half the standard 1.0 m
        # |W-bar| = |W| (Sec. 5.5): the COG is back on each cycle's path
        assert float(plan.path_deviation) < 1e-9, name
    # walking directions: progress along each commanded direction
    k = names.index("left")
    plan = _take(plans, k)
    assert float(plan.cog[-1, 1] - plan.cog[0, 1]) > 1.5


def test_slope_map_frame_and_world_output(scenarios):
    _gm, _, _, plans = scenarios
    k = [s[0] for s in SCEN].index("slope 30 deg, 0.2 m / 1.5 m")
    plan = _take(plans, k)
    a = params.SLOPE_ANGLE
    R = np.array([[np.cos(a), 0, -np.sin(a)], [0, 1, 0], [np.sin(a), 0, np.cos(a)]])
    np.testing.assert_allclose(plan.cog_world, np.asarray(plan.cog) @ R.T, atol=1e-12)
    # climbing: the world height of the COG grows with the distance walked up the slope
    dz = float(plan.cog_world[-1, 2] - plan.cog_world[0, 2])
    dx = float(plan.cog[-1, 0] - plan.cog[0, 0])
    assert dz == pytest.approx(dx * np.sin(a), rel=0.05)


# --------------------------------------------------- foothold search on hand-built maps
half_jit = jax.jit(gait.half_cycle)


def _flat_half(forbidden=None):
    g = titan_maps.flat_map(SHAPE, ORIGIN)
    if forbidden is not None:
        g = titan_maps.GridMap(g.height, forbidden, g.origin, g.cell, g.slope)
    s = gait.standard_start(PAR, g, jnp.array([5.0, 6.5]))
    d_b = jnp.array([1.0, 0.0])
    roles, n_r = gait.leg_roles((s.feet[:, :2] - s.cog[:2]), d_b, s.rear)
    up = jnp.array([0.0, 0.0, 1.0])
    h = half_jit(
        PAR,
        g,
        s.feet,
        s.cog,
        s.yaw,
        d_b,
        roles,
        n_r,
        PAR.l_std,
        PAR.w_std,
        jnp.asarray(True),
        up,
    )
    return g, h


def test_foothold_search_avoids_forbidden_cell_at_initial_position():
    _g, h = _flat_half()
    assert bool(h.ok)
    np.testing.assert_allclose(
        h.j_r[:2], h.i_r, atol=1e-12
    )  # free map: J_u = I_u (step 1)
    # forbid the cells around I_r (the foot pad would touch them)
    c = titan_maps.cell_centres(SHAPE, ORIGIN, CELL)
    forb = jnp.linalg.norm(c - h.i_r, axis=-1) < 0.16
    g2, h2 = _flat_half(forb)
    assert bool(h2.found_r)
    assert not bool(titan_maps.sample_forbidden(g2, h2.j_r[:2]))
    delta = np.asarray(h2.j_r[:2] - h.i_r)
    # same row (step 2), nearest lateral point in the +y/-y order
    assert abs(delta[0]) < 1e-9
    assert abs(abs(delta[1]) - 0.2) < 1e-9 and delta[1] > 0


def test_foothold_search_moves_rows_backwards_first():
    _g, h = _flat_half()
    c = titan_maps.cell_centres(SHAPE, ORIGIN, CELL)
    # forbid the whole row of I_r inside the reachable area: the search goes to row -1
    forb = jnp.abs(c[..., 0] - h.i_r[0]) < 0.06
    g2, h2 = _flat_half(forb)
    assert bool(h2.found_r)
    delta = np.asarray(h2.j_r[:2] - h.i_r)
    assert delta[0] < -0.05  # behind I_u (towards -x)
    assert not bool(titan_maps.sample_forbidden(g2, h2.j_r[:2]))


def test_impossible_map_reports_failure_and_stops():
    g = titan_maps.flat_map(SHAPE, ORIGIN)
    start = gait.standard_start(PAR, g, jnp.array([5.0, 6.5]))
    blocked = titan_maps.GridMap(g.height, jnp.ones(SHAPE, bool), g.origin, g.cell, g.slope)
    plan = plan_one(blocked, start, jnp.zeros(N_CYC))
    assert int(plan.n_failures) == N_CYC
    assert bool(jnp.all(plan.failed)) and bool(jnp.all(plan.swing_leg == -1))
    np.testing.assert_allclose(plan.feet[-1], start.feet)  # the robot holds still
    np.testing.assert_allclose(plan.cog[-1, :2], start.cog[:2])
    _, h = _flat_half(jnp.ones(SHAPE, bool))
    assert not bool(h.found_r) and not bool(h.ok)


# ------------------------------------------------------------------------ transforms
def test_vmap_over_maps_equals_loop(scenarios):
    gm, st, dr, plans = scenarios
    for k in (1, 3):
        one = plan_one(_take(gm, k), _take(st, k), dr[k])
        for a, b in zip(
            jax.tree_util.tree_leaves(one), jax.tree_util.tree_leaves(_take(plans, k))
        ):
            np.testing.assert_allclose(a, b, atol=1e-9)


def test_sweep_point_vmaps_over_parameters_and_maps():
    """`sweep_metrics`: vmap over L_std, W_std and the frame size ==
    a loop of single calls; flat ground gives 2 L_std per cycle."""

    def run(l_std, w_std, size):
        par = PAR.with_(l_std=l_std, w_std=w_std)
        return gait.sweep_metrics(par, size, 2.0, 0.0, 0.0, 1, shape=(90, 70))

    ls, ws = jnp.array([0.4, 0.5, 0.6]), jnp.array([1.0, 1.1, 1.2])
    sizes = jnp.array([0.0, 0.0, 0.2])
    batched = jax.jit(jax.vmap(run))(ls, ws, sizes)
    single = jax.jit(run)
    for k in range(3):
        one = single(ls[k], ws[k], sizes[k])
        for key, v in one.items():
            np.testing.assert_allclose(batched[key][k], v, atol=1e-12)
    # flat ground: the standard gait, 2 L_std per cycle, on the path
    np.testing.assert_allclose(
        batched["distance_per_cycle"][:2], 2 * ls[:2], atol=1e-12
    )
    np.testing.assert_allclose(batched["n_failures"], 0)
    assert float(jnp.min(batched["min_nesm"])) >= params.S_NE_C


def test_grad_of_standard_stance_margin_wrt_lateral_shift():
    g = titan_maps.flat_map((90, 70), ORIGIN)

    def margin(w_std):
        par = PAR.with_(w_std=w_std)
        s = gait.standard_start(par, g, jnp.array([3.0, 3.5]))
        mask = jnp.array([True, True, False, True])  # LR about to swing
        return stab.ne_stability_margin(s.cog, s.feet, mask)

    gr = jax.jit(jax.grad(margin))(1.0)  # jitted: one program, not one per operation
    margin = jax.jit(margin)
    fd = (margin(1.0 + 1e-6) - margin(1.0 - 1e-6)) / 2e-6
    assert float(gr) > 0  # a larger zigzag moves the COG away from the diagonal
    assert float(gr) == pytest.approx(float(fd), rel=1e-6)


def test_swing_path_of_a_foot_that_stays_has_finite_derivatives():
    """A leg whose landing equals its lift-off (a held cycle: no horizontal return) has a
    swing path whose derivatives are finite in forward and reverse mode (the return
    direction divides by |dv| floored at 1e-9 m; the norm's own derivative is 0/0 there);
    away from that point they match central differences. No NaN even inside (`debug_nans`):
    a NaN that a later selection drops is 0 * NaN away from breaking every gradient of
    a plan."""
    g = titan_maps.flat_map((90, 70), ORIGIN)
    s = gait.standard_start(PAR, g, jnp.array([3.0, 3.5]))

    def path(shift):
        after = s.feet.at[1, 0].add(shift)
        return gait.swing_path(PAR, g, s.feet, after, jnp.asarray(1))

    for jac in (jax.jacfwd(path), jax.jacrev(path)):
        with jax.debug_nans(True):
            held = jac(0.0)
        assert bool(jnp.all(jnp.isfinite(held)))
        np.testing.assert_allclose(held[2:, 0], 1.0)  # the touch-down points move with the foot
        moved = jac(0.1)
        np.testing.assert_allclose(moved, (path(0.1 + 1e-6) - path(0.1 - 1e-6)) / 2e-6, atol=1e-6)


def test_direction_changes_across_rear_pairs_use_a_transition_shift():
    """Reversing or turning by 90 deg changes the rear pair: neither new rear leg can lift
    at the old cycle-start pose, so the planner makes one transition COG shift (no swing)
    and then walks the new direction; never a step below S_NE^c."""
    g = titan_maps.flat_map(SHAPE, ORIGIN)
    start = gait.standard_start(PAR, g, jnp.array([6.5, 6.5]))
    for new, axis, sign in ((180.0, 0, -1.0), (90.0, 1, 1.0)):
        plan = plan_one(g, start, jnp.radians(jnp.array([0.0, new, new])))
        assert int(plan.n_failures) == 0
        assert float(plan.min_nesm) >= params.S_NE_C
        np.testing.assert_array_equal(plan.swing_leg[6:12], -1)  # the transition cycle
        np.testing.assert_allclose(plan.feet[11], plan.feet[5])
        assert bool(plan.modified[6]) and not bool(plan.modified[12])
        np.testing.assert_array_equal(
            np.asarray(plan.swing_leg[12:]) >= 0, [1, 1, 0, 1, 1, 0]
        )
        moved = float(plan.cog[-1, axis] - plan.cog[11, axis]) * sign
        assert (
            moved > 0.5 * 2 * params.L_STD
        )  # then walking (feet not yet in the standard stance)


def test_gait_converges_back_to_the_standard_gait_after_the_frames():
    # Fig. 5: 0.2 m frames on a 2.0 m grid up to x = 8 m, flat ground beyond. Walking
    # through, the planner adapts (shortened strides); once every foot is past the
    # frames its cycles are standard again: |L| = L_std, |W| = W_std, no modification,
    # and the same stance about the COG every cycle, the standard one up to a constant
    # shift along the strokes (phase-reserved positioning keeps the legs' relative
    # phases, not where on its stroke each foot is: 4.4 cm here in float64, 0 in float32)
    shape = (200, 100)
    frames = titan_maps.frame_grid_map(
        shape, ORIGIN, CELL, params.FRAME_SMALL, params.GRID_SMALL, jnp.array([1.0, 1.0])
    )
    flat = titan_maps.flat_map(shape, ORIGIN)
    band = titan_maps.cell_centres(shape, ORIGIN, CELL)[..., 0] < 8.0
    gmap = titan_maps.GridMap(
        jnp.where(band, frames.height, flat.height),
        jnp.where(band, frames.forbidden, flat.forbidden),
        ORIGIN,
        CELL,
        frames.slope,
    )
    start = gait.standard_start(PAR, gmap, jnp.array([3.0, 5.0]), 0.0)
    n = 11
    plan = jax.jit(gait.plan_cycles, static_argnames="n_cycles")(
        PAR, gmap, start, n_cycles=n, direction=0.0
    )
    assert int(plan.n_failures) == 0
    cog, feet = np.asarray(plan.cog), np.asarray(plan.feet)
    ends = 6 * np.arange(n) + 5
    off_frames = feet[ends, :, 0].min(axis=1) > 8.0 + params.FOOT_RADIUS
    assert off_frames[-3:].all()
    deviation = []
    for k in ends:
        std = np.asarray(gait.standard_start(PAR, flat, jnp.asarray(cog[k, :2]), 0.0).feet)
        deviation.append(np.abs(feet[k, :, :2] - std[:, :2]).max())
    deviation = np.asarray(deviation)
    assert deviation[1:-3].max() > 0.1  # the frames pushed it off the standard gait
    assert deviation[off_frames].max() < 0.1
    rel = feet[ends][off_frames] - cog[ends][off_frames][:, None]
    np.testing.assert_allclose(rel, rel[0][None].repeat(len(rel), 0), atol=1e-6)
    last = off_frames.nonzero()[0]
    np.testing.assert_allclose(np.asarray(plan.cycle_w)[last], params.W_STD, atol=1e-9)
    np.testing.assert_allclose(np.asarray(plan.cycle_l)[last], params.L_STD, atol=1e-9)
    assert (np.asarray(plan.cycle_trials)[last] == 0).all()


# ------------------------------------------------------------------- every direction
def test_directional_stride_lengthens_the_stride_off_the_body_axes():
    for deg, m in ((0.0, 1.0), (90.0, 1.0), (180.0, 1.0), (45.0, math.sqrt(0.5)), (120.0, math.cos(math.radians(30)))):
        d = gait._unit(jnp.radians(deg))
        assert float(gait.directional_stride(PAR, d)) == pytest.approx(
            params.L_STD / m**params.STRIDE_EXPONENT, rel=1e-12
        )
        assert float(gait.directional_stride(PAR.with_(stride_exponent=0.0), d)) == pytest.approx(params.L_STD)


def _start_lift_margin(exponent, deg):
    """NESM of the first swing (leg r lifted) at the standard start for the heading."""
    par = PAR.with_(stride_exponent=exponent)
    g = titan_maps.flat_map((90, 90), ORIGIN)
    d = jnp.radians(deg)
    st = gait.standard_start(par, g, jnp.array([4.5, 4.5]), d)
    return float(stab.ne_stability_margin(st.cog, st.feet, jnp.arange(4) != st.rear))


def test_the_diagonal_needs_the_longer_stride():
    """Why `directional_stride`: at 45 deg the rear leg's swing is supported across the
    diagonal normal to the path, so only the stride moves the COG off it. With the same
    stride as along an axis (k = 0) or the same body-axis component (k = 1) the first
    swing of the standard gait is below S_NE^c; with k = 1.5 it is above, and along an
    axis nothing changes (the W_std zigzag carries the margin there)."""
    assert _start_lift_margin(0.0, 45.0) < _start_lift_margin(1.0, 45.0) < params.S_NE_C
    assert _start_lift_margin(params.STRIDE_EXPONENT, 45.0) >= params.S_NE_C
    assert _start_lift_margin(0.0, 0.0) == pytest.approx(_start_lift_margin(params.STRIDE_EXPONENT, 0.0), rel=1e-12)


def test_diagonal_walks_plan_every_cycle(scenarios):
    """Off the body axes (Sec. 7: "walks in all directions"): the standard gait on flat
    ground at 45 deg (no modification, 2 L_std(45 deg) per cycle, back on the path every
    cycle) and the frame fields at 45, 135 and 255 deg, every step >= S_NE^c."""
    _, _, _, plans = scenarios
    names = [s[0] for s in SCEN]
    flat = _take(plans, names.index("diagonal, flat"))
    assert int(flat.n_failures) == 0 and int(flat.n_modifications) == 0
    l45 = params.L_STD / math.sqrt(0.5) ** params.STRIDE_EXPONENT
    # |L| = min(L_std(45 deg), the reach limit of Sec. 5.2.3): |L-bar| is 1.2 % shorter here
    steps = np.asarray(flat.cycle_l)
    assert (steps <= l45 + 1e-12).all() and steps.min() > 0.98 * l45
    assert float(flat.distance_per_cycle) == pytest.approx(steps.sum(axis=1).mean(), rel=1e-9)
    assert float(flat.path_deviation) == pytest.approx(0.0, abs=1e-9)
    assert float(flat.min_nesm) >= params.S_NE_C
    for name in ("diagonal, 0.2 m / 2.0 m", "135 deg, 0.3 m / 3.0 m", "255 deg, 0.2 m / 2.0 m"):
        plan = _take(plans, names.index(name))
        assert int(plan.n_failures) == 0, name
        assert float(plan.min_nesm) >= params.S_NE_C - 1e-9, name
        assert float(plan.distance_per_cycle) > 0.5, name


def test_lateral_trials_widen_first_then_narrow():
    w = [float(gait.trial_lateral(PAR, i)) for i in range(params.N_W + params.N_W_DOWN)]
    up = [params.W_STD + i * params.DW for i in range(params.N_W)]
    down = [params.W_STD - k * params.DW for k in range(1, params.N_W_DOWN + 1)]
    np.testing.assert_allclose(w, up + down, rtol=1e-12)
