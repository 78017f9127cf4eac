"""OCTOPUS support set of the stability margin: touch sensors on every wheel and roller;
the loaded or seated ones count, each at its contact point with the terrain (the point
of the terrain boxes nearest to its centre), checked against MuJoCo's own contacts on
flat ground and on a step edge; a roller hovering within a few mm is no support."""

from types import SimpleNamespace

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from scipy.spatial import ConvexHull

from jaxloco import stability
from jaxloco.robots.octopus import ccm, clm, scenarios
from jaxloco.robots.octopus import kinematics as kin
from jaxloco.robots.octopus import model as octo_model
from jaxloco.robots.octopus import params as octopus_params
from jaxloco.sim import terrain
from jaxloco.sim.data import FIELDS, SimData
from jaxloco.sim.rollout import rollout
from jaxloco.sim.scenario import Controller

WEIGHT = octopus_params.TOTAL_MASS * octopus_params.G
N_SITES = len(scenarios.CONTACT_SITES)
N_SUPPORT = len(scenarios.SUPPORT_BODIES)
ARMS = scenarios.ROLLERS


def _hold(arms, flips) -> Controller:
    """Tracks stopped, flippers (4,) and arms (4, 3) held at fixed targets [rad]."""
    action = np.concatenate([np.zeros(2), np.asarray(flips, float), np.asarray(arms, float).reshape(-1)])

    def step(p, s, obs):
        return s, jnp.asarray(action, obs["quat"].dtype)

    return Controller(lambda p, obs: jnp.zeros(()), step, name="hold")


def _native(kind: str, controller: Controller, seconds: float, lift: float = 0.0, pose: str | None = None,
            **params):
    """One native MjData of scenario `kind` from its initial state (pose `pose`, the robot
    raised by `lift` [m]), `seconds` of physics with the initial ctrl held; returns the
    model, the MjData and the scenario's record of that state."""
    sc = scenarios.make_scenario(kind, controller, horizon_s=0.1, record_every=5, initial_pose=pose)
    m = sc.model
    p = {k: jnp.asarray(v[0]) for k, v in scenarios.params_batch(1, **params).items()}
    init = sc.initial_state(p, jax.random.PRNGKey(0))
    d = mujoco.MjData(m)
    d.qpos[:], d.ctrl[:] = np.asarray(init.qpos), np.asarray(init.ctrl)
    d.mocap_pos[:], d.mocap_quat[:] = np.asarray(init.mocap_pos), np.asarray(init.mocap_quat)
    d.qpos[2] += lift
    mujoco.mj_step(m, d, nstep=round(seconds / m.opt.timestep))
    mujoco.mj_forward(m, d)
    data = SimData(**{f: jnp.asarray(np.array(getattr(d, f))) for f in FIELDS if f != "site_xmat"},
                   site_xmat=jnp.asarray(d.site_xmat.reshape(-1, 3, 3)))
    rec = sc.record(p, data, sc.observe(data), None, None)
    return m, d, {k: np.asarray(v) for k, v in rec.items()}


def _mujoco_contacts(m, d):
    """MuJoCo's contacts of the wheels and rollers: (index in SUPPORT_BODIES, position (3,),
    normal force [N]) for each, from mj_contactForce."""
    index = {m.body(b).id: i for i, b in enumerate(scenarios.SUPPORT_BODIES)}
    out, f6 = [], np.zeros(6)
    for i in range(d.ncon):
        c = d.contact[i]
        body = [m.geom_bodyid[g] for g in (c.geom1, c.geom2) if m.geom_bodyid[g] in index]
        assert len(body) == 1, "only wheels and rollers touch the terrain"
        mujoco.mj_contactForce(m, d, i, f6)
        out.append((index[body[0]], c.pos.copy(), f6[0]))
    return out


def _hull_margin(q, xy) -> float:
    """Static margin of the 2D point q over the convex hull of xy (scipy: the facets'
    outward unit normals n and offsets b, n . x + b <= 0 inside)."""
    eq = ConvexHull(np.asarray(xy)).equations
    return float(-np.max(eq[:, :2] @ np.asarray(q) + eq[:, 2]))


def _total_load(touch, track_load):
    """Sum of every touch sensor from the records; the segments' track_load count each
    main end wheel twice (main crawler and its flipper), and hold no roller."""
    assert track_load.sum() - touch[:4].sum() + touch[ARMS].sum() == pytest.approx(touch.sum(), rel=1e-5)
    return touch.sum()


def test_touch_sites_line_up_with_contact_sites():
    """One touch sensor per contact site (`CONTACT_SITES` order), on a site around the
    wheel / roller that the contact site sits under: same centre (rollers) or one wheel
    radius above the contact site, TOUCH_MARGIN larger than the sphere, same body. The
    support set is every wheel and roller, in the order of its touch sensors, the
    CONTACT_SITES' wheels first."""
    m = octo_model.load_model()
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_kinematics(m, d)
    assert scenarios.CONTACT_TOUCH == octo_model.touch_names()[:N_SITES]
    assert len(octo_model.touch_names()) == 2 * (octopus_params.MAIN_WHEELS + 2 * octopus_params.FLIPPER_WHEELS) + 4
    assert scenarios.SUPPORT_TOUCH == octo_model.touch_names() and N_SUPPORT == len(scenarios.SUPPORT_TOUCH)
    spheres = {m.body(m.geom_bodyid[g]).name for g in range(m.ngeom)
               if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE and m.geom_contype[g]}
    assert set(scenarios.SUPPORT_BODIES) == spheres and len(spheres) == N_SUPPORT
    for body, name in zip(scenarios.SUPPORT_BODIES, scenarios.SUPPORT_TOUCH, strict=True):
        assert m.body(m.site_bodyid[m.site(name).id]).name == body
    for site, name in zip(scenarios.CONTACT_SITES, scenarios.CONTACT_TOUCH, strict=True):
        sensor = m.sensor(name)
        assert sensor.type[0] == mujoco.mjtSensor.mjSENS_TOUCH and sensor.objid[0] == m.site(name).id
        body = m.site_bodyid[m.site(name).id]
        geoms = [g for g in range(m.ngeom) if m.geom_bodyid[g] == body]
        assert len(geoms) == 1 and m.geom_type[geoms[0]] == mujoco.mjtGeom.mjGEOM_SPHERE
        radius = m.geom_size[geoms[0], 0]
        assert m.site_size[m.site(name).id, 0] == pytest.approx(radius + octo_model.TOUCH_MARGIN)
        offset = d.site(name).xpos - d.site(site).xpos
        expected = [0.0, 0.0, 0.0] if site.startswith("arm") else [0.0, 0.0, radius]
        np.testing.assert_allclose(offset, expected, atol=1e-9)
    # sites carry no mass and never collide: the model is still 100 kg
    assert m.body_subtreemass[m.body("chassis").id] == pytest.approx(octopus_params.TOTAL_MASS, abs=1e-9)


def test_touch_sensors_read_the_contact_forces_on_flat_ground():
    """MuJoCo directly, Table 2 start pose on a floor plane, at rest: each touch sensor
    equals the normal force of its body's contacts (mj_contactForce), and together they
    carry the robot's weight."""
    spec = octo_model.load_spec()
    spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[20, 20, 0.1],
                            contype=terrain.TERRAIN_CONTYPE, conaffinity=terrain.TERRAIN_CONAFFINITY)
    m = spec.compile()
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_step(m, d, nstep=1000)
    mujoco.mj_forward(m, d)
    by_body = np.zeros(m.nbody)
    f6 = np.zeros(6)
    for i in range(d.ncon):
        mujoco.mj_contactForce(m, d, i, f6)
        for g in (d.contact[i].geom1, d.contact[i].geom2):
            by_body[m.geom_bodyid[g]] += f6[0]
    touch = {n: d.sensor(n).data[0] for n in octo_model.touch_names()}
    for name, value in touch.items():
        assert value == pytest.approx(by_body[m.site_bodyid[m.site(name).id]], abs=1e-6)
    assert sum(touch.values()) == pytest.approx(WEIGHT, rel=0.01)
    assert all(touch[f"{a}_touch"] > scenarios.LOAD_MIN for a in octopus_params.ARM_NAMES)


def test_support_set_matches_mujoco_contacts_on_flat_ground():
    """Oracle, standing on flat ground in the CLM start pose (native MjData, 2 s at rest):
    every MuJoCo contact of a wheel or roller lies at the support point of its body
    (within 1 mm: MuJoCo puts it mid-penetration); every body with a contact above
    LOAD_MIN is in the support set; the margin over the set equals the one over the
    convex hull of the set's wheel centres (scipy, exact on flat ground) and agrees with
    the margin over MuJoCo's own contact points that carry more than LOAD_MIN."""
    m, d, rec = _native("flat", _hold(*clm.start_pose()), 2.0, pose="clm")
    contacts = _mujoco_contacts(m, d)
    assert sum(f for _, _, f in contacts) == pytest.approx(WEIGHT, rel=0.01)
    for i, pos, force in contacts:
        np.testing.assert_allclose(rec["contact_points"][i], pos, atol=1e-3)
        assert rec["contact"][i] or force < scenarios.LOAD_MIN, scenarios.SUPPORT_BODIES[i]
    on = rec["contact"]
    assert on[ARMS].all() and on[:4].all() and not on[4:6].any()  # rollers, crawler ends; front tips raised
    cog = rec["cog"]
    ours = float(stability.static_margin(jnp.asarray(cog), jnp.asarray(rec["contact_points"]), jnp.asarray(on)))
    centres = d.xpos[[m.body(b).id for b in np.asarray(scenarios.SUPPORT_BODIES)[on]]]
    assert ours == pytest.approx(_hull_margin(cog[:2], centres[:, :2]), abs=1e-6)
    loaded = np.array([pos for _, pos, f in contacts if f > scenarios.LOAD_MIN])
    assert ours == pytest.approx(_hull_margin(cog[:2], loaded[:, :2]), abs=1e-3)
    assert ours > 0.1


def test_support_point_on_a_step_edge_matches_mujoco():
    """Oracle on a 100 mm step: the robot (CCM pose, front flippers up) dropped with its
    front end wheels just beyond the riser rests on the edge (rear flipper tips on the
    floor); MuJoCo's contacts of the front wheels are at the edge, and so are their
    support points (within 1 mm), where the centre projected to its lowest point
    (centre - radius * z) is more than 10 mm behind; the margins agree."""
    m, d, rec = _native("step1", ccm.make_controller(), 2.0, lift=0.12, height=0.1, distance=0.15)
    contacts = _mujoco_contacts(m, d)
    edge = [(i, pos) for i, pos, f in contacts if f > scenarios.LOAD_MIN and abs(pos[0] - 0.15) < 1e-3]
    assert {scenarios.SUPPORT_BODIES[i] for i, _ in edge} == {"wheel_l6", "wheel_r6"}
    for i, pos, force in contacts:
        np.testing.assert_allclose(rec["contact_points"][i], pos, atol=1e-3)
        assert rec["contact"][i] or force < scenarios.LOAD_MIN
    for i, pos in edge:
        np.testing.assert_allclose(rec["contact_points"][i, [0, 2]], [0.15, 0.1], atol=1e-3)  # the edge
        low = d.xpos[m.body(scenarios.SUPPORT_BODIES[i]).id] - [0.0, 0.0, octopus_params.MAIN_WHEEL_RADIUS]
        assert np.linalg.norm(low - pos) > 0.01
    # the margin over the set agrees with the one over MuJoCo's loaded contacts (the
    # centres' vertical would put the front edge of the polygon about 13 mm behind)
    on = rec["contact"]
    ours = float(stability.static_margin(jnp.asarray(rec["cog"]), jnp.asarray(rec["contact_points"]), jnp.asarray(on)))
    loaded = np.array([pos for _, pos, f in contacts if f > scenarios.LOAD_MIN])
    assert ours == pytest.approx(_hull_margin(rec["cog"][:2], loaded[:, :2]), abs=1e-3)
    centres = d.xpos[[m.body(b).id for b in np.asarray(scenarios.SUPPORT_BODIES)[on]]]
    assert ours > _hull_margin(rec["cog"][:2], centres[:, :2]) + 0.005


@pytest.mark.parametrize("kind, params, centre, radius, point", [
    ("flat", {}, [0.3, 0.1, 0.09], 0.09, [0.3, 0.1, 0.0]),  # on the ground
    ("flat", {}, [0.3, 0.1, 0.1], 0.09, [0.3, 0.1, 0.0]),  # 10 mm above it
    ("step1", {"height": 0.2, "distance": 0.7}, [0.9, 0.25, 0.3], 0.09, [0.9, 0.25, 0.2]),  # on the top
    ("step1", {"height": 0.2, "distance": 0.7}, [0.646, 0.25, 0.272], 0.09, [0.7, 0.25, 0.2]),  # on the edge
    ("step1", {"height": 0.2, "distance": 0.7}, [0.61, -0.25, 0.1], 0.09, [0.7, -0.25, 0.1]),  # on the riser
    # first terraces: left 0.2 m, right 0.1 m high; on the right one, and against the left one's side
    ("step2_side", {"height": 0.4, "side_ratio": 0.5, "distance": 0.7}, [0.8, -0.3, 0.15], 0.05,
     [0.8, -0.3, 0.1]),
    ("step2_side", {"height": 0.4, "side_ratio": 0.5, "distance": 0.7}, [0.8, -0.04, 0.15], 0.05,
     [0.8, 0.0, 0.15]),
    ("step2_front", {"height": 0.4, "distance": 0.7}, [1.46, 0.2, 0.44], 0.05, [1.5, 0.2, 0.4]),  # 2nd edge
    ("block", {"height": 0.5, "distance": 0.7, "block_gap": 0.01}, [0.95, -0.6, 0.55], 0.05,
     [0.95, -0.6, 0.5]),  # on top of the block
])
def test_terrain_contacts_is_the_nearest_terrain_point(kind, params, centre, radius, point):
    _, terrain_ = scenarios.build_model(kind)
    p = {k: jnp.asarray(v[0]) for k, v in scenarios.params_batch(1, **params).items()}
    pts, gap = scenarios.terrain_contacts(terrain_, scenarios.terrain_values(kind, p), jnp.asarray([centre]),
                                          jnp.asarray([radius]))
    np.testing.assert_allclose(pts[0], point, atol=1e-6)
    assert float(gap[0]) == pytest.approx(np.linalg.norm(np.subtract(centre, point)) - radius, abs=1e-6)


@pytest.fixture(scope="module")
def clm_stance_and_hover():
    """Two flat-ground runs of 2 s holding the CLM start pose: rollers on the ground, and
    rollers commanded 10 mm above it (Table 2 EPRAs raised, inverse kinematics); the
    records also hold the roller centres."""
    arms, flips = clm.start_pose()
    raised = octopus_params.TABLE2_INIT.copy()
    raised[:, 2] += 0.01
    hover, reach = kin.inverse_kinematics_all(octopus_params.OctopusParams(), jnp.asarray(raised))
    assert np.all(np.asarray(reach) > 0.0)
    out = []
    for target in (arms, np.asarray(hover)):
        sc = scenarios.make_scenario("flat", _hold(target, flips), horizon_s=2.0, record_every=25,
                                     initial_pose="clm")
        rollers = np.array([sc.model.body(f"{a}_roller").id for a in octopus_params.ARM_NAMES])
        base = sc.record

        def record(p, data, obs, c, e, base=base, rollers=rollers):
            return {**base(p, data, obs, c, e), "rollers": data.xpos[rollers]}

        out.append(rollout(sc.with_(record=record), scenarios.params_batch(1), nthread=2))
    return out


def test_loaded_contacts_standing_in_clm_start_pose(clm_stance_and_hover):
    r = clm_stance_and_hover[0]
    touch, load = r.records["touch"][0, -1], r.records["track_load"][0, -1]
    # oracle: at rest the contacts carry the weight, 100 kg x 9.81 (within 2 %)
    assert _total_load(touch, load) == pytest.approx(WEIGHT, rel=0.02)
    assert touch.shape == (N_SUPPORT,) and load.shape == (2, 3)
    contact = r.records["contact"][0, -1]
    # the four rollers carry load (Table 2 pose: arms on the ground) and count, as do the
    # main crawler wheels and the level rear flippers; the raised front flippers do not
    assert (touch[ARMS] > scenarios.LOAD_MIN).all() and contact[ARMS].all()
    assert contact[:4].all() and contact[6:8].all() and not contact[4:6].any()
    on = {b for b, c in zip(scenarios.SUPPORT_BODIES, contact, strict=True) if c}
    assert {f"wheel_{s}{k + 1}" for s in "lr" for k in range(octopus_params.MAIN_WHEELS)} <= on
    assert not any(b.startswith(("flipper_fl", "flipper_fr")) for b in on)
    # on flat ground every support point is on the ground, under its wheel's centre
    np.testing.assert_allclose(r.records["contact_points"][0, -1, contact, 2], 0.0, atol=1e-3)
    assert r.metrics["min_margin"][0] > 0.1


def test_hovering_roller_is_not_support(clm_stance_and_hover):
    r = clm_stance_and_hover[1]
    touch, load = r.records["touch"][0, -1], r.records["track_load"][0, -1]
    assert _total_load(touch, load) == pytest.approx(WEIGHT, rel=0.02)  # all on the tracks
    gap = r.records["rollers"][0, -1, :, 2] - octopus_params.ROLLER_RADIUS
    # the rollers hover a few mm above the ground ...
    assert ((gap > 0.003) & (gap < 0.02)).all()
    # ... carry nothing, so they are no support
    np.testing.assert_array_equal(touch[ARMS], 0.0)
    contact = r.records["contact"][0, -1]
    assert not contact[ARMS].any()
    assert contact[:4].all()
    assert np.isfinite(r.metrics["min_margin"][0])


def test_contact_needs_load_or_seat():
    """The record of one sample on the 400 mm step (synthetic state): the left rear end
    wheel above the floor, a middle wheel on the step edge (its centre 0.6 radius before
    the riser, its lowest point over the floor 0.4 m below), another against the riser;
    each 5 mm off the terrain counts only when it carries load (its touch sensor), and
    on the terrain (within SEAT_TOL) also unloaded; its support point is where it
    touches (the floor below it, the edge, the riser face)."""
    sc = scenarios.make_scenario("step1", horizon_s=0.1, record_every=5)
    p = {k: v[0] for k, v in scenarios.params_batch(1).items()}
    d, h = float(p["distance"]), float(p["height"])
    y, r = octopus_params.CRAWLER_Y, octopus_params.MAIN_WHEEL_RADIUS
    k_rear, k_edge, k_riser = (scenarios.SUPPORT_BODIES.index(b) for b in ("wheel_l1", "wheel_l3", "wheel_r4"))
    ids = [sc.model.body(scenarios.SUPPORT_BODIES[k]).id for k in (k_rear, k_edge, k_riser)]

    def record(off, touch=0.0):
        xpos = np.full((sc.model.nbody, 3), [-5.0, 0.0, 3.0])  # everything else far up in the air
        xpos[ids[0]] = [d - 0.3, y, r + off]
        xpos[ids[1]] = [d - 0.6 * (r + off), y, h + 0.8 * (r + off)]
        xpos[ids[2]] = [d - r - off, -y, 0.5 * h]
        data = SimpleNamespace(xpos=jnp.asarray(xpos), subtree_com=jnp.zeros((sc.model.nbody, 3)))
        obs = {"quat": jnp.array([1.0, 0, 0, 0]), "flipper_q": jnp.zeros(4), "flipper_tau": jnp.zeros(4),
               "arm_q": jnp.zeros(12), "arm_tau": jnp.zeros(12), "contact_points": jnp.zeros((N_SITES, 3)),
               "touch": jnp.zeros(N_SUPPORT).at[jnp.array([k_rear, k_edge, k_riser])].set(touch),
               "track_load": jnp.zeros((2, 3))}
        rec = sc.record(p, data, obs, None, None)
        pts = np.asarray(rec["contact_points"])[[k_rear, k_edge, k_riser]]
        np.testing.assert_allclose(pts, [[d - 0.3, y, 0.0], [d, y, h], [d, -y, 0.5 * h]], atol=1e-6)
        return set(np.flatnonzero(np.asarray(rec["contact"])).tolist())

    assert record(0.005) == set()  # hovering 5 mm, no load
    assert record(0.005, touch=100.0) == {k_rear, k_edge, k_riser}  # loaded
    # on the surface (within SEAT_TOL), unloaded: touching, a load distribution artefact
    assert record(0.0005) == {k_rear, k_edge, k_riser}


def test_min_margin_finite_in_short_flat_runs():
    """The CLM (arms walking) and the CCM (arms stowed, driving) on flat ground for 2 s:
    enough loaded contacts for a finite, positive margin."""
    for controller in (clm.make_controller(), ccm.make_controller()):
        sc = scenarios.make_scenario("flat", controller, horizon_s=2.0, record_every=10)
        r = rollout(sc, scenarios.params_batch(1), nthread=2)
        assert (r.status != "diverged").all()
        margin = r.metrics["min_margin"][0]
        assert np.isfinite(margin) and margin > 0.03, controller.name
        contact = r.records["contact"][0, 1:]
        assert (contact.sum(-1) >= 3).all()
        assert contact[:, :4].all()  # the crawler end wheels stay on the ground
    # CCM: the stowed arms never count
    assert not contact[:, ARMS].any()
