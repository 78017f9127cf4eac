"""The TITAN XI planner's footsteps executed in MuJoCo: two gait
cycles over the Section 7 frames (0.2 m frames on a 2.0 m grid) and two on the Section
8.4 slope (30 deg, 0.2 m frames every 1.5 m, tethers on), one batch of two simulations;
plus the planner -> executor plan conversion and the start-pose search."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxloco.robots.titan import gait as titan_gait
from jaxloco.robots.titan import maps, scenarios, walk
from jaxloco.robots.titan import params as titan_params
from jaxloco.sim.rollout import rollout

THETA = float(titan_params.SLOPE_ANGLE)
N_CYCLES = 2


def _line_distance(x, spacing):
    """Distance from x to the nearest simulated beam centre line (spacing/2 + k spacing)."""
    u = np.mod(x - 0.5 * spacing, spacing)
    return np.minimum(u, spacing - u)


@pytest.fixture(scope="module")
def walks():
    flat = walk.plan_walk((-3.0, 0.3), N_CYCLES, 0.0, titan_params.FRAME_SMALL, titan_params.GRID_SMALL)
    slope = walk.plan_walk((-2.5, 0.0), N_CYCLES, 0.0, titan_params.SLOPE_FRAME, titan_params.SLOPE_GRID, THETA)
    return flat, slope


@pytest.fixture(scope="module")
def runs(walks):
    (flat, _, sc_flat), (slope, _, sc_slope) = walks
    sc = scenarios.make_scenario(flat.n_steps, beam_width=titan_params.FRAME_SMALL)
    p = scenarios.params_batch(
        [flat, slope],
        **{k: np.array([sc_flat[k], sc_slope[k]]) for k in sc_flat},
    )
    return rollout(sc, p, nthread=2)


def test_planned_footholds_avoid_the_simulated_frames(walks):
    # the grid maps of walk.sim_map line up with the simulated beams: every planned
    # foothold keeps its pad (P.FOOT_RADIUS) off the beams (half width 0.1 m)
    for (plan, _, sc), spacing in zip(walks, (titan_params.GRID_SMALL, titan_params.SLOPE_GRID), strict=True):
        gmap = walk.sim_map(sc["beam_height"], spacing, sc["theta"])
        inv = np.linalg.inv(np.asarray(maps.map_to_world(gmap, jnp.eye(3))))
        for feet in (plan.feet0[None], plan.feet):
            local = feet @ inv  # back to the map (slope) frame
            d = np.minimum(
                _line_distance(local[..., 0], spacing),
                _line_distance(local[..., 1], spacing),
            )
            assert d.min() > 0.5 * titan_params.FRAME_SMALL + titan_params.FOOT_RADIUS


def test_executor_plan_follows_the_planner(walks):
    plan, gait, _ = walks[0]
    assert plan.n_steps == 6 * N_CYCLES
    assert np.array_equal(plan.swing, np.asarray(gait.swing_leg))
    assert plan.cycle_end.sum() == N_CYCLES and plan.cycle_end[5] and plan.cycle_end[-1]
    # each cycle's path starts at the COG of the cycle start, along +x
    assert np.allclose(plan.path_origin[0], plan.body0)
    assert np.allclose(plan.path_origin[6], plan.body[5])
    assert np.allclose(plan.path_dir, [1.0, 0.0, 0.0], atol=1e-6)
    # the swing tops clear the 0.2 m frames by the planner's clearance
    tops = plan.swing_top[plan.swing >= 0]
    assert np.all(tops >= titan_params.FRAME_SMALL) and np.all(
        np.isinf(plan.swing_top[plan.swing < 0])
    )


def test_clear_start_moves_feet_off_the_frames():
    params = titan_params.default_params()
    dense = walk.sim_map(titan_params.SLOPE_FRAME, titan_params.SLOPE_GRID)
    start = walk.clear_start(params, dense, (0.0, 0.0))
    assert not np.asarray(maps.sample_forbidden(dense, start.feet[:, :2])).any()
    # the COG stays H_g above the feet's virtual plane
    nrm, off = titan_gait.virtual_plane(start.feet)
    assert float(
        start.cog[2] - titan_gait.plane_height(nrm, off, start.cog[:2])
    ) == pytest.approx(float(titan_params.H_G), abs=1e-5)
    # a map that is all frame: a clear one-line error, not a loop
    blocked = maps.GridMap(
        dense.height,
        jnp.ones_like(dense.forbidden),
        dense.origin,
        dense.cell,
        dense.slope,
    )
    with pytest.raises(ValueError, match="no free cell"):
        walk.clear_start(params, blocked, (0.0, 0.0))


@pytest.mark.parametrize("row", [0, 1], ids=["section7_frames", "slope_30deg"])
def test_planned_walk_runs_in_mujoco(runs, row):
    m = runs.row(row)
    assert runs.status[row] == "ok", m
    assert m["completed"] and not m["fell"]
    # the NE margin stays at S_NE^c in simulation (whole-robot COG, measured feet)
    assert m["min_nesm"] >= titan_params.S_NE_C
    # no leg touches a frame while swinging, no foot lands on one
    assert not m["swing_collision"] and m["min_swing_clearance"] > 0.0
    assert not m["forbidden_landing"]
    # the feet land where planned and the COG comes back to the path at each cycle end
    assert m["max_touchdown_error"] < 0.08
    assert m["max_cycle_error"] < 0.08 and m["max_path_deviation"] < 0.08
    # and it walks: about the planned distance
    assert m["final_progress"] > 0.8 * N_CYCLES * 0.7


def _beam_distance(xy, n_lines, spacing):
    """Distance from points (..., 2) to the beams of a square field of n_lines x n_lines
    centre lines every `spacing` m, centred on the origin (segments, not infinite lines)."""
    c = (np.arange(n_lines) - 0.5 * (n_lines - 1)) * spacing
    half = c[-1]
    x, y = xy[..., 0], xy[..., 1]
    dx = np.min(np.abs(x[..., None] - c), axis=-1)  # to the lines x = c (running along y)
    dy = np.min(np.abs(y[..., None] - c), axis=-1)
    along_y = np.hypot(dx, np.maximum(np.abs(y) - half, 0.0))
    along_x = np.hypot(dy, np.maximum(np.abs(x) - half, 0.0))
    return np.minimum(along_x, along_y)


def test_a_surveyed_map_with_noise_plans_off_the_true_frames():
    """Sec. 8.2.1 end to end on a 5 x 5 beam field (1.5 m): a total-station survey with 5 mm
    noise, the maps made from it, a plan on them. Every cell the true frames forbid is
    forbidden on the surveyed map too (its 5 cm placement margin covers the noise), and
    every planned foothold keeps its pad off the true beams."""
    field = scenarios.FrameField(n_along=5, n_across=5, max_spacing=1.5, half_length=12.0, half_width=12.0)
    noisy = walk.surveyed_map(field, 1.5, titan_params.FRAME_SMALL, 0.005, jax.random.PRNGKey(3), shape=walk.SIM_SHAPE)
    exact = walk.surveyed_map(field, 1.5, titan_params.FRAME_SMALL, shape=walk.SIM_SHAPE, margin=0.0)
    assert bool(jnp.all(noisy.forbidden | ~exact.forbidden))
    assert int(exact.forbidden.sum()) > 1000
    par = titan_params.default_params()
    start = walk.clear_start(par, noisy, (-3.0, 0.4), 0.0)
    gait = walk._plan_cycles(par, noisy, start, n_cycles=N_CYCLES, direction=jnp.zeros(N_CYCLES))
    assert int(gait.n_failures) == 0 and float(gait.min_nesm) >= titan_params.S_NE_C - 1e-9
    feet = np.concatenate([np.asarray(start.feet)[None], np.asarray(gait.feet)])[..., :2]
    assert _beam_distance(feet, 5, 1.5).min() > 0.5 * titan_params.FRAME_SMALL + titan_params.FOOT_RADIUS
    assert float(gait.cog[-1, 0] - start.cog[0]) > 0.5 * N_CYCLES
