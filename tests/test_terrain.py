"""Terrains as mocap boxes: geometry against closed forms (MuJoCo's own ray casting), per-simulation
parameters in one compiled model (mujoco.batch), purity of `place` (jit, vmap, grad), input
errors, fragile footholds with touch sensors, and `combine`."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import mujoco
import mujoco.batch
import numpy as np
import pytest
from jax.test_util import check_grads

from jaxloco.errors import SpecError
from jaxloco.sim import terrain as sim_terrain

DOWN = np.array([0.0, 0.0, -1.0])
TOP = 20.0  # ray origins' height [m]


def build(terrain: sim_terrain.Terrain, values=None, key=None, prefix: str = "terrain"):
    """Compile the terrain alone, write the placement of `values` to the mocap state, mj_forward."""
    spec = mujoco.MjSpec()
    terrain.add_to(spec, prefix=prefix)
    model = spec.compile()
    data = mujoco.MjData(model)
    pos, quat = terrain.place(values, key)
    ids = sim_terrain.mocap_ids(model, terrain, prefix)
    data.mocap_pos[ids] = np.asarray(pos)
    data.mocap_quat[ids] = np.asarray(quat)
    mujoco.mj_forward(model, data)
    return model, data


def ray(model, data, origin, direction=DOWN):
    """(distance, geom id, surface normal) of MuJoCo's ray cast; distance -1 for a miss."""
    geomid = np.zeros(1, np.int32)
    normal = np.zeros(3)
    dist = mujoco.mj_ray(model, data, np.asarray(origin, float), np.asarray(direction, float), None, True, -1,
                         geomid, normal)
    return dist, int(geomid[0]), normal


def hit_z(model, data, x, y):
    """Height of the first surface hit by a vertical ray at (x, y)."""
    dist, geom, _ = ray(model, data, [x, y, TOP])
    assert geom >= 0, f"ray at ({x}, {y}) missed"
    return TOP - dist


def plane_z(theta, direction, x, y):
    return math.tan(theta) * (x * math.cos(direction) + y * math.sin(direction))


def slope_point(theta, direction, u, v):
    """World point with slope-frame coordinates (u uphill, v across) on the plane through 0."""
    c, s = math.cos(direction), math.sin(direction)
    return np.array([u * math.cos(theta) * c - v * s, u * math.cos(theta) * s + v * c, u * math.sin(theta)])


# ----------------------------------------------------------------------------- geometry
def test_flat_top_face_at_height():
    model, data = build(sim_terrain.flat(), {"height": 0.3})
    for x, y in [(0.0, 0.0), (4.0, -7.0), (-9.5, 9.5)]:
        assert hit_z(model, data, x, y) == pytest.approx(0.3, abs=1e-12)


@pytest.mark.parametrize("theta,direction", [(0.3, 0.7), (-0.5, 2.5), (1.2, -1.0)])
def test_slope_is_the_plane(theta, direction):
    terrain = sim_terrain.slope()
    model, data = build(terrain, {"theta": theta, "direction": direction})
    for x, y in [(0.0, 0.0), (1.0, 0.5), (-1.3, 1.1), (0.8, -1.5)]:
        assert hit_z(model, data, x, y) == pytest.approx(plane_z(theta, direction, x, y), abs=1e-9)
    _, _, normal = ray(model, data, [0.2, 0.1, TOP])
    expected = np.asarray(sim_terrain.slope_normal(theta, direction))
    np.testing.assert_allclose(normal, expected, atol=1e-12)
    # the box's x axis points uphill (half_length is along the gradient)
    xaxis = data.geom_xmat[model.geom("terrain/ground").id].reshape(3, 3)[:, 0]
    np.testing.assert_allclose(xaxis, slope_point(theta, direction, 1.0, 0.0), atol=1e-12)


def test_irregular_slope_tiles():
    theta, direction, spread = 0.35, 0.6, 0.9
    rows, cols, tile = 3, 4, 0.3
    terrain = sim_terrain.irregular_slope(rows, cols, tile)
    model, data = build(terrain, {"theta": theta, "direction": direction, "spread": spread}, jax.random.PRNGKey(3))
    azimuths = []
    for r in range(rows):
        for c in range(cols):
            centre = slope_point(theta, direction, (r - (rows - 1) / 2) * tile, (c - (cols - 1) / 2) * tile)
            dist, geom, normal = ray(model, data, [centre[0], centre[1], TOP])
            assert geom == model.geom(f"terrain/tile{r}_{c}").id
            assert TOP - dist == pytest.approx(plane_z(theta, direction, centre[0], centre[1]), abs=1e-9)
            zaxis = data.geom_xmat[geom].reshape(3, 3)[:, 2]
            np.testing.assert_allclose(normal, zaxis, atol=1e-9)
            assert math.acos(normal[2]) == pytest.approx(theta, abs=1e-9)
            azimuths.append(math.atan2(-normal[1], -normal[0]))
    offsets = np.angle(np.exp(1j * (np.array(azimuths) - direction)))
    assert np.all(np.abs(offsets) <= spread + 1e-9)
    assert np.ptp(offsets) > 0.3 * spread  # the tiles really point in different directions


def test_irregular_slope_without_spread_is_the_slope():
    theta, direction = 0.25, -0.4
    model, data = build(sim_terrain.irregular_slope(2, 2, 0.5), {"theta": theta, "direction": direction})
    for u, v in [(0.1, 0.2), (-0.3, 0.35), (0.4, -0.4)]:  # anywhere on the 1 m x 1 m grid, edges included
        x, y, z = slope_point(theta, direction, u, v)
        assert hit_z(model, data, x, y) == pytest.approx(z, abs=1e-9)


def test_steps_left_and_right():
    n, depth, start, h_left, h_right = 3, 0.4, 0.7, 0.45, 0.15
    terrain = sim_terrain.steps(n_terraces=n, depth=depth, half_width=1.0)
    model, data = build(terrain, {"height_left": h_left, "height_right": h_right, "start": start})
    for y, h in [(0.5, h_left), (-0.5, h_right)]:
        assert hit_z(model, data, start - 1.0, y) == pytest.approx(0.0, abs=1e-12)  # floor in front
        for k in range(n):
            x = start + (k + 0.5) * depth
            assert hit_z(model, data, x, y) == pytest.approx(h * (k + 1) / n, abs=1e-12)
        assert hit_z(model, data, start + n * depth + 3.0, y) == pytest.approx(h, abs=1e-12)  # long last terrace


def test_blocks_tops_and_yaw():
    terrain = sim_terrain.blocks(2)
    values = {"block0_x": 1.0, "block0_y": 0.5, "block0_height": 0.3, "block0_yaw": 0.0,
              "block1_x": -1.0, "block1_y": -1.0, "block1_height": 0.8, "block1_yaw": math.pi / 4}
    model, data = build(terrain, values)
    assert hit_z(model, data, 1.0, 0.5) == pytest.approx(0.3, abs=1e-12)
    assert hit_z(model, data, -1.0, -1.0) == pytest.approx(0.8, abs=1e-12)
    assert hit_z(model, data, 3.0, 3.0) == pytest.approx(0.0, abs=1e-12)  # floor
    # 0.3 m along x from the centre: outside the unrotated 0.25 half-size block, inside the 45 deg one
    assert hit_z(model, data, 1.3, 0.5) == pytest.approx(0.0, abs=1e-12)
    assert hit_z(model, data, -0.7, -1.0) == pytest.approx(0.8, abs=1e-12)


def test_frames_on_slope_beams_and_plane():
    theta, direction, spacing, h = 0.3, 0.5, 1.2, 0.2
    nx, ny = 3, 4
    terrain = sim_terrain.frames_on_slope(nx, ny, beam_width=0.2)
    model, data = build(terrain, {"theta": theta, "direction": direction, "spacing": spacing, "beam_height": h})
    us = (np.arange(ny) - (ny - 1) / 2) * spacing  # across beams sit at these uphill coordinates
    vs = (np.arange(nx) - (nx - 1) / 2) * spacing  # along beams at these across coordinates
    lift = h / math.cos(theta)  # vertical offset of a plane moved by h along its normal
    for u in us:
        for v in vs:
            p = slope_point(theta, direction, u, v)
            assert hit_z(model, data, p[0], p[1]) == pytest.approx(plane_z(theta, direction, *p[:2]) + lift, abs=1e-9)
    for u in us[:-1] + spacing / 2:
        for v in vs[:-1] + spacing / 2:
            p = slope_point(theta, direction, u, v)  # between beams: the slope itself
            assert hit_z(model, data, p[0], p[1]) == pytest.approx(plane_z(theta, direction, *p[:2]), abs=1e-9)
            p = slope_point(theta, direction, u, vs[0])  # on an along beam, between two crossings
            assert hit_z(model, data, p[0], p[1]) == pytest.approx(plane_z(theta, direction, *p[:2]) + lift, abs=1e-9)


def test_footholds_follow_centres_and_normals():
    centres = np.array([[0.0, 0.0, 0.1], [0.5, 0.2, 0.3], [-0.4, 0.3, 0.0]])
    normals = np.array([[0.0, 0.0, 2.0], [0.3, -0.2, 1.0], [-0.6, 0.0, 0.8]])
    terrain = sim_terrain.footholds(3)
    model, data = build(terrain, {"centres": centres, "normals": normals})
    for i in range(3):
        n = normals[i] / np.linalg.norm(normals[i])
        dist, geom, normal = ray(model, data, centres[i] + 0.5 * n, -n)
        assert geom == model.geom(f"terrain/pad{i}").id
        assert dist == pytest.approx(0.5, abs=1e-9)
        np.testing.assert_allclose(normal, n, atol=1e-9)
        site = model.site(f"terrain/pad{i}/touch").id  # touch site centred on the top face
        np.testing.assert_allclose(data.site_xpos[site], centres[i], atol=1e-12)
    assert terrain.touch_sensor_names() == ("terrain/pad0/touch", "terrain/pad1/touch", "terrain/pad2/touch")
    assert [model.sensor(s).type[0] for s in terrain.touch_sensor_names()] == [mujoco.mjtSensor.mjSENS_TOUCH] * 3


def test_add_to_uses_defaults_and_filters_collisions():
    terrain = sim_terrain.steps()
    spec = mujoco.MjSpec()
    terrain.add_to(spec, prefix="ground", friction=(0.7, 0.01, 0.001))
    model = spec.compile()
    pos, quat = terrain.place()
    ids = sim_terrain.mocap_ids(model, terrain, "ground")
    np.testing.assert_array_equal(ids, np.arange(len(terrain.pieces)))
    for i, name in enumerate(terrain.body_names("ground")):
        body, geom = model.body(name), model.geom(name)
        np.testing.assert_allclose(body.pos, pos[i], atol=1e-12)
        np.testing.assert_allclose(body.quat, quat[i], atol=1e-12)
        assert (geom.contype[0], geom.conaffinity[0], geom.condim[0]) == (
            sim_terrain.TERRAIN_CONTYPE,
            sim_terrain.TERRAIN_CONAFFINITY,
            3,
        )
        np.testing.assert_allclose(geom.friction, [0.7, 0.01, 0.001])
        np.testing.assert_allclose(geom.size, terrain.pieces[i].half_size)
    assert sim_terrain.TERRAIN_CONTYPE & sim_terrain.TERRAIN_CONAFFINITY == 0  # pieces never collide with each other
    assert (
        sim_terrain.ROBOT_CONTYPE & sim_terrain.TERRAIN_CONAFFINITY
        and sim_terrain.TERRAIN_CONTYPE & sim_terrain.ROBOT_CONAFFINITY
    )
    assert not terrain.fragile_mask.any() and sim_terrain.footholds(2).fragile_mask.all()
    assert terrain.touch_sensor_names() == ()


# ----------------------------------------------------------------------- per simulation
def test_batch_simulations_get_their_own_slope():
    terrain = sim_terrain.slope()
    spec = mujoco.MjSpec()
    terrain.add_to(spec)
    model = spec.compile()
    thetas = np.array([-0.2, 0.1, 0.4])
    direction = 0.3
    pos, quat = jax.vmap(lambda th: terrain.place({"theta": th, "direction": direction}))(jnp.asarray(thetas))
    ids = sim_terrain.mocap_ids(model, terrain)
    batch = mujoco.batch.Batch(model, nsim=3, nthread=1)
    mocap_pos, mocap_quat = batch.bind("mocap_pos"), batch.bind("mocap_quat")
    mocap_pos[:, ids] = np.asarray(pos)
    mocap_quat[:, ids] = np.asarray(quat)
    xy = np.array([[1.0, 0.0], [0.5, -1.2], [-2.0, 1.0]])
    origins = np.column_stack([xy, np.full(len(xy), TOP)])
    dist, geom = batch.ray(origins, DOWN)
    assert dist.shape == (3, 3) and np.all(geom == model.geom("terrain/ground").id)
    expected = np.array([[plane_z(th, direction, x, y) for x, y in xy] for th in thetas])
    np.testing.assert_allclose(TOP - dist, expected, atol=1e-9)


# ----------------------------------------------------------------------------- purity
def test_place_vmap_equals_loop():
    terrain = sim_terrain.irregular_slope(2, 3, 0.3)
    thetas = jnp.array([0.0, 0.2, -0.4, 0.7])
    keys = jax.random.split(jax.random.PRNGKey(0), 4)
    place = jax.jit(jax.vmap(lambda th, k: terrain.place({"theta": th, "spread": 0.5}, k)))
    pos, quat = place(thetas, keys)
    assert pos.shape == (4, 6, 3) and quat.shape == (4, 6, 4)
    for i in range(4):
        p, q = terrain.place({"theta": float(thetas[i]), "spread": 0.5}, keys[i])
        np.testing.assert_allclose(pos[i], p, atol=1e-12)
        np.testing.assert_allclose(quat[i], q, atol=1e-12)
    np.testing.assert_allclose(jnp.linalg.norm(quat, axis=-1), 1.0, atol=1e-12)


def _slope_height(theta, x=0.8, y=-0.4, direction=0.3):
    """Height of the placed slope box's top face above (x, y), from the box pose."""
    terrain = sim_terrain.slope()
    pos, quat = terrain.place({"theta": theta, "direction": direction})
    n = sim_terrain.quat_z_axis(quat[0])
    top = pos[0] + terrain.pieces[0].half_size[2] * n
    return top[2] - (n[0] * (x - top[0]) + n[1] * (y - top[1])) / n[2]


def test_gradients_of_heights():
    theta = jnp.asarray(0.3)
    assert _slope_height(theta) == pytest.approx(plane_z(0.3, 0.3, 0.8, -0.4), abs=1e-12)
    check_grads(_slope_height, (theta,), order=1, modes=("fwd", "rev"))
    expected = (0.8 * math.cos(0.3) - 0.4 * math.sin(0.3)) / math.cos(0.3) ** 2
    assert float(jax.grad(_slope_height)(theta)) == pytest.approx(expected, rel=1e-9)

    terrain = sim_terrain.steps(n_terraces=4)
    hz = terrain.pieces[1].half_size[2]

    def third_left_terrace_top(h):
        pos, _ = terrain.place({"height_left": h})
        return pos[3, 2] + hz  # pieces: floor, left0..left3, right0..

    check_grads(third_left_terrace_top, (jnp.asarray(0.3),), order=1, modes=("fwd", "rev"))
    assert float(jax.grad(third_left_terrace_top)(jnp.asarray(0.3))) == pytest.approx(3 / 4)


# ------------------------------------------------------------------------------ input
def test_bad_inputs_raise_spec_error():
    terrain = sim_terrain.slope()
    with pytest.raises(SpecError, match="thetta"):
        terrain.check({"thetta": 0.1})
    with pytest.raises(SpecError, match="thetta"):
        terrain.place({"thetta": 0.1})
    with pytest.raises(SpecError, match=r"theta: 2 rad is outside \(-1.5708, 1.5708\)"):
        terrain.check({"theta": 2.0})
    with pytest.raises(SpecError, match="block0_height"):
        sim_terrain.blocks(1).check({"block0_height": -0.1})
    with pytest.raises(SpecError, match="centres"):
        sim_terrain.footholds(2).check({"centres": np.zeros((3, 3))})
    assert terrain.check({"theta": np.float64(0.2)}) == {"theta": 0.2, "direction": 0.0}
    checked = sim_terrain.footholds(2).check({})
    np.testing.assert_allclose(checked["normals"], [[0, 0, 1], [0, 0, 1]])


# ------------------------------------------------------------------------------ fragility
def test_collapse_is_latched_and_drop_follows_normal():
    collapsed = jnp.array([False, True, False])
    out = sim_terrain.collapse_update(collapsed, jnp.array([5.0, 0.0, 1.0]), jnp.array([4.0, 4.0, 4.0]))
    np.testing.assert_array_equal(out, [True, True, False])
    normals = jnp.array([[0.0, 0.0, 1.0], [0.6, 0.0, 0.8], [0.0, 0.0, 1.0]])
    pos, quat = sim_terrain.pad_poses(jnp.zeros((3, 3)), normals, 0.02)
    dropped = sim_terrain.drop_away(pos, quat, out, drop=0.3)
    np.testing.assert_allclose(dropped, pos - 0.3 * normals * np.array([1.0, 1.0, 0.0])[:, None], atol=1e-12)


def _pad_and_ball(mass=0.5, radius=0.02):
    terrain = sim_terrain.footholds(1)
    spec = mujoco.MjSpec()
    terrain.add_to(spec)
    ball = spec.worldbody.add_body(name="ball", pos=[0.0, 0.0, radius])
    ball.add_freejoint()
    ball.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[radius, 0, 0], mass=mass, contype=sim_terrain.ROBOT_CONTYPE,
                  conaffinity=sim_terrain.ROBOT_CONAFFINITY)
    return terrain, spec.compile()


@pytest.mark.parametrize("factor", [0.5, 1.5])
def test_fragile_pad_collapses_under_load(factor):
    mass = 0.5
    terrain, model = _pad_and_ball(mass)
    data = mujoco.MjData(model)
    mg = mass * -model.opt.gravity[2]
    ids = sim_terrain.mocap_ids(model, terrain)
    pos0, quat0 = terrain.place()
    r_break = jnp.full((1,), factor * mg)
    sensor = model.sensor(terrain.touch_sensor_names()[0]).adr[0]

    @jax.jit
    def step(collapsed, touch):
        collapsed = sim_terrain.collapse_update(collapsed, touch, r_break)
        return collapsed, sim_terrain.drop_away(pos0, quat0, collapsed)

    collapsed = jnp.zeros((1,), bool)
    touches = []
    for _ in range(300):
        mujoco.mj_step(model, data)
        touch = data.sensordata[sensor: sensor + 1].copy()
        touches.append(touch[0])
        collapsed, pos = step(collapsed, jnp.asarray(touch))
        data.mocap_pos[ids] = np.asarray(pos)
    ball_bottom = data.qpos[2] - 0.02
    if factor < 1:
        assert bool(collapsed[0])
        assert ball_bottom < -0.1  # fell below the pad's original top (z = 0)
    else:
        assert not bool(collapsed[0])
        assert ball_bottom == pytest.approx(0.0, abs=2e-3)
        assert touches[-1] == pytest.approx(mg, rel=0.05)  # at rest the pad carries the ball's weight


# ------------------------------------------------------------------------------ combine
def test_combine_concatenates_and_shares_params():
    parts = (sim_terrain.slope(), sim_terrain.irregular_slope(2, 2), sim_terrain.footholds(2), sim_terrain.steps())
    terrain = sim_terrain.combine(*parts)
    assert len(terrain.pieces) == sum(len(p.pieces) for p in parts)
    assert terrain.body_names()[0] == "terrain/slope0/ground"
    assert terrain.touch_sensor_names() == ("terrain/footholds2/pad0/touch", "terrain/footholds2/pad1/touch")
    names = [p.name for p in terrain.params]
    assert names.count("theta") == 1 and "height_left" in names and "spread" in names
    values = {"theta": 0.2, "spread": 0.4, "height_left": 0.1, "centres": np.ones((2, 3))}
    key = jax.random.PRNGKey(7)
    pos, quat = terrain.place(values, key)
    for i, part in enumerate(parts):
        own = {k: v for k, v in values.items() if k in part.input_names()}
        p, q = part.place(own, key)
        lo = sum(len(t.pieces) for t in parts[:i])
        np.testing.assert_allclose(pos[lo: lo + len(part.pieces)], p, atol=1e-12)
        np.testing.assert_allclose(quat[lo: lo + len(part.pieces)], q, atol=1e-12)
    model, _ = build(terrain, values, key)  # unique names: compiles
    assert model.nmocap == len(terrain.pieces) and model.nsensor == 2


def test_combine_name_clash_raises():
    with pytest.raises(ValueError, match="block0_height"):
        sim_terrain.combine(sim_terrain.blocks(1), sim_terrain.blocks(1, half_size=(0.2, 0.2, 0.02)))
    with pytest.raises(ValueError, match="centres"):
        sim_terrain.combine(sim_terrain.footholds(1), sim_terrain.footholds(2))
    sim_terrain.combine(sim_terrain.flat(), sim_terrain.flat())  # identical params are shared
