"""TITAN XI grid maps (Hodoshima et al. 2007, Sec. 8.2.1): survey-based map generation
against the analytic frame maps, the conservative forbidden-foothold map, lookups."""

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco.robots.titan import maps, params

SHAPE = (60, 50)
ORIGIN = jnp.array([-3.0, -2.0])


def _frame_clearance(xy, size, interval, offset):
    """Distance from points (n, 2) to the nearest frame edge (analytic frame grid)."""
    u = np.mod(xy - offset, interval)
    return np.min(np.minimum(u, interval - u), axis=-1) - size / 2


def test_survey_map_matches_analytic_frames():
    offset = jnp.array(
        [1.0, 0.0]
    )  # frame lines at x = -3, -1, 1, 3 and y = -2, 0, 2, 4 (the survey covers the map)
    ref = maps.frame_grid_map(SHAPE, ORIGIN, jnp.asarray(params.CELL), 0.2, 2.0, offset)
    nodes, centres = maps.survey_points((4, 4), 2.0, ORIGIN, 0.2)
    gen = maps.map_from_survey(nodes, centres, 0.2, 0.2, SHAPE, ORIGIN)
    np.testing.assert_allclose(gen.height, ref.height, atol=1e-9)
    assert bool(jnp.all(gen.forbidden == ref.forbidden))
    # with the +-5 mm total-station error the maps barely change
    nodes, centres = maps.survey_points(
        (4, 4), 2.0, ORIGIN, 0.2, noise=0.005, key=jax.random.PRNGKey(0)
    )
    noisy = maps.map_from_survey(nodes, centres, 0.2, 0.2, SHAPE, ORIGIN)
    assert float(jnp.mean(noisy.forbidden != ref.forbidden)) < 0.03
    assert float(jnp.max(jnp.abs(noisy.height - ref.height) * (~ref.forbidden))) < 0.03


def test_survey_map_on_uneven_ground_interpolates_centres():
    def ground(xy):
        return 0.05 * xy[..., 0] + 0.02 * xy[..., 1]  # a plane: interpolation is exact

    nodes, centres = maps.survey_points((4, 4), 2.0, ORIGIN, 0.2, ground_fn=ground)
    gen = maps.map_from_survey(nodes, centres, 0.2, 0.2, SHAPE, ORIGIN)
    c = maps.cell_centres(SHAPE, ORIGIN, jnp.asarray(params.CELL))
    free = np.asarray(
        _frame_clearance(np.asarray(c).reshape(-1, 2), 0.2, 2.0, np.array([1.0, 0.0]))
        > 0.05
    )
    # frame base = top - height along the local normal: a tilted plane shifts the base
    # sideways by h sin(tilt), so allow a few mm
    err = np.abs(np.asarray(gen.height).ravel() - np.asarray(ground(c)).ravel())[free]
    assert err.max() < 5e-3


def test_forbidden_map_is_conservative_for_the_foot_pad():
    size, interval, off = 0.3, 3.0, np.array([0.5, 0.5])
    g = maps.frame_grid_map(
        SHAPE, ORIGIN, jnp.asarray(params.CELL), size, interval, jnp.asarray(off)
    )
    rng = np.random.default_rng(0)
    pts = rng.uniform([-3.0, -2.0], [3.0, 3.0], (4000, 2))
    free = ~np.asarray(maps.sample_forbidden(g, jnp.asarray(pts)))
    clear = _frame_clearance(pts, size, interval, off)
    assert free.sum() > 500
    assert (
        clear[free].min() > params.FOOT_RADIUS
    )  # any point of a free cell keeps the pad off frames
    # and frames are in the unevenness map
    on = (
        clear < -0.075
    )  # deeper than half a cell diagonal: the cell centre is on the frame too
    np.testing.assert_allclose(
        np.asarray(maps.sample_height(g, jnp.asarray(pts[on]))), size
    )


def test_lookups_outside_and_world_frame():
    g = maps.slope_map(SHAPE, ORIGIN)
    out = jnp.array([[-10.0, 0.0], [0.0, 50.0]])
    assert bool(jnp.all(maps.sample_forbidden(g, out)))
    np.testing.assert_allclose(maps.sample_height(g, out), 0.0)
    a = params.SLOPE_ANGLE
    np.testing.assert_allclose(
        maps.map_to_world(g, jnp.array([1.0, 0.0, 0.0])),
        [np.cos(a), 0.0, np.sin(a)],
        atol=1e-12,
    )
    np.testing.assert_allclose(
        maps.map_to_world(g, jnp.array([0.0, 0.0, 1.0])),
        [-np.sin(a), 0.0, np.cos(a)],
        atol=1e-12,
    )


def test_frame_map_vmaps_over_frame_parameters():
    f = jax.jit(
        jax.vmap(
            lambda s, i: maps.frame_grid_map(SHAPE, ORIGIN, jnp.asarray(params.CELL), s, i)
        )
    )
    sizes, ints = jnp.array([0.0, 0.2, 0.3]), jnp.array([2.0, 2.0, 3.0])
    gb = f(sizes, ints)
    for k in range(3):
        g = maps.frame_grid_map(SHAPE, ORIGIN, jnp.asarray(params.CELL), sizes[k], ints[k])
        assert bool(jnp.all(gb.forbidden[k] == g.forbidden))
        np.testing.assert_allclose(gb.height[k], g.height)
    assert not bool(jnp.any(gb.forbidden[0]))  # no frames: flat ground everywhere free


def test_mixed_field_alternates_the_two_frame_grids_in_blocks():
    """`mixed_frame_map`: block 0 is `frame_grid_map` of field A exactly; with blocks, each
    block carries its own field's frames (heights and forbidden cells), checkerboard."""
    cell = jnp.asarray(params.CELL)
    a = (params.FRAME_SMALL, params.GRID_SMALL, jnp.array([1.0, 1.0]))
    b = (params.FRAME_LARGE, params.GRID_LARGE, jnp.array([1.5, 1.5]))
    shape = (120, 120)
    plain = maps.frame_grid_map(shape, ORIGIN, cell, *a)
    same = maps.mixed_frame_map(shape, ORIGIN, cell, a, b, 0.0)
    np.testing.assert_array_equal(same.height, plain.height)
    np.testing.assert_array_equal(same.forbidden, plain.forbidden)
    mixed = maps.mixed_frame_map(shape, ORIGIN, cell, a, b, 6.0)
    other = maps.frame_grid_map(shape, ORIGIN, cell, *b)
    c = np.asarray(maps.cell_centres(shape, ORIGIN, cell))
    k = np.floor(c / 6.0).astype(int)
    in_b = (k[..., 0] + k[..., 1]) % 2 == 1
    assert in_b.any() and (~in_b).any()
    np.testing.assert_array_equal(np.asarray(mixed.height)[in_b], np.asarray(other.height)[in_b])
    np.testing.assert_array_equal(np.asarray(mixed.height)[~in_b], np.asarray(plain.height)[~in_b])
    assert set(np.unique(np.asarray(mixed.height)[in_b]).tolist()) == {0.0, params.FRAME_LARGE}
    # forbidden cells: each block's own frames, away from the block edges
    inner = np.all(np.abs(c / 6.0 - np.round(c / 6.0)) * 6.0 > 0.5, axis=-1)
    np.testing.assert_array_equal(np.asarray(mixed.forbidden)[in_b & inner], np.asarray(other.forbidden)[in_b & inner])
    np.testing.assert_array_equal(np.asarray(mixed.forbidden)[~in_b & inner],
                                  np.asarray(plain.forbidden)[~in_b & inner])
