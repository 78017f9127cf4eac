"""The OCTOPUS compound locomotion mode (CLM) controller (`clm`) in the step scenarios: the
start pose, the support arms holding their ground contacts while the crawlers drive,
step detection (fires on a step, not on flat ground), a climb of a low step through
every phase, and the controller's pieces as pure functions. The rules themselves are
tested in test_octopus_clm_rules.py."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxloco.robots.octopus import clm, params, scenarios
from jaxloco.robots.octopus import clm_rules as cr
from jaxloco.robots.octopus import kinematics as kin
from jaxloco.robots.octopus import model as octo_model
from jaxloco.sim.rollout import rollout

TIP_SITES = tuple(f"{a}_tip" for a in params.ARM_NAMES)


def _scenario(kind: str, horizon_s: float, record_every: int = 5):
    """A CLM scenario that also records the controller state and the rollers (world)."""
    sc = scenarios.make_scenario(kind, clm.make_controller(), horizon_s=horizon_s, record_every=record_every)
    base = sc.record
    tips = np.array([sc.model.site(n).id for n in TIP_SITES])

    def record(p, data, obs, c, e):
        r = base(p, data, obs, c, e)
        r.update(arm_phase=c.arms.arm_phase, active=c.arms.active, confirmed=c.confirmed, h_est=c.h_est,
                 on_step=c.arms.on_step, rollers=data.site_xpos[tips])
        return r

    return sc.with_(record=record)


def test_clm_params_merge_and_start_pose():
    for k in clm.PARAM_DEFAULTS:
        assert k in scenarios.PARAM_DEFAULTS
    batch = scenarios.params_batch(2, clm_speed=0.02, T0=np.array([10.0, 20.0]))
    assert batch["clm_speed"].shape == (2,) and float(batch["T0"][1]) == 20.0
    assert float(batch["speed"][0]) == pytest.approx(params.CRAWLER_MAX_SPEED)  # CCM keys unchanged
    with pytest.raises(KeyError):
        scenarios.params_batch(1, not_a_gain=1.0)
    arms, flips = clm.start_pose()
    np.testing.assert_allclose(arms, octo_model.home_arm_angles())
    tips = np.asarray(kin.arm_tips(params.default_params(), jnp.asarray(arms)))
    np.testing.assert_allclose(tips, params.TABLE2_INIT, atol=1e-5)
    assert flips[0] == flips[1] == clm.PARAM_DEFAULTS["front_start"] and flips[2] == flips[3] == 0.0
    with pytest.raises(ValueError):
        scenarios.make_scenario("flat", initial_pose="walking")


def test_controller_is_pure_jax_with_fixed_shapes():
    """init/step trace under jit and vmap (no Python branches on traced values) and the
    action has the actuator layout (2 crawlers, 4 flippers, 12 arm joints)."""
    ctrl = clm.make_controller()
    p = {k: jnp.asarray(v) for k, v in scenarios.PARAM_DEFAULTS.items()}
    q = jnp.asarray(clm.start_pose()[0].reshape(-1))
    obs = {"time": jnp.zeros(()), "quat": jnp.array([1.0, 0.0, 0.0, 0.0]), "flipper_q": jnp.array([0.5, 0.5, 0, 0]),
           "flipper_tau": jnp.zeros(4), "arm_q": q, "arm_tau": jnp.zeros(12), "track_speed": jnp.zeros(2),
           "contact_points": jnp.zeros((len(scenarios.CONTACT_SITES), 3))}
    s = ctrl.init(p, obs)
    batch = jax.tree_util.tree_map(lambda x: jnp.stack([x, x]), (p, s, obs))
    s2, actions = jax.jit(jax.vmap(ctrl.step))(*batch)
    assert actions.shape == (2, len(params.ACTUATOR_NAMES))
    assert jax.tree_util.tree_structure(s2) == jax.tree_util.tree_structure(s)
    for a, b in zip(jax.tree_util.tree_leaves(s), jax.tree_util.tree_leaves(s2)):
        assert b.shape == (2, *a.shape) and a.dtype == b.dtype
    # standing on flat ground, all arms in support: the first transfer (RR, CRAWL_ORDER)
    # starts after the gait pause and the arms hold the Table 2 pose
    np.testing.assert_allclose(actions[0, 6:], q, atol=1e-6)


def test_tips_move_along_the_world_vertical():
    """The climbing rule moves the EPRAs of the pushing arms straight down in the level
    frame {C}, whatever the attitude (Eq. 28 in task space), and leaves the others."""
    prm = params.default_params()
    q = jnp.asarray(octo_model.home_arm_angles())
    move = jnp.array([True, False, True, True])
    for a_p, a_r in ((0.0, 0.0), (0.3, -0.1)):
        q2 = clm._tips_moved(q, move, jnp.asarray(-0.01), jnp.asarray(a_p), jnp.asarray(a_r))
        d = kin.to_level_frame(kin.arm_tips(prm, q2) - kin.arm_tips(prm, q), a_p, a_r)
        np.testing.assert_allclose(np.asarray(d)[move], [[0.0, 0.0, -0.01]] * 3, atol=1e-9)
        np.testing.assert_allclose(q2[1], q[1])


def test_support_arms_hold_their_ground_contacts_while_driving():
    """On flat ground the arms walk in the crawl gait (one transfer at a time, at least
    three arms in support) and a support arm's roller stays within a few cm of its
    ground point while the crawlers carry the body on (Eqs. 22-27 + inverse kinematics);
    the robot drives straight and no step is detected."""
    sc = _scenario("flat", horizon_s=24.0)
    r = rollout(sc, scenarios.params_batch(1), nthread=2)
    assert r.status[0] != "diverged"
    R = {k: v[0] for k, v in r.records.items()}
    support = R["arm_phase"] == cr.PLACED
    assert support.sum(axis=1).min() >= 3
    assert (R["active"] >= 0).any()
    moved = R["pos"][-1, 0] - R["pos"][0, 0]
    assert moved > 0.4
    # every support interval: the roller's horizontal drift on the ground
    worst = 0.0
    for arm in range(4):
        runs = np.flatnonzero(np.diff(np.concatenate([[0], support[:, arm].astype(int), [0]])))
        for a, b in zip(runs[::2], runs[1::2]):
            a += 2  # the roller settles after touch-down
            if b - a > 10:
                xy = R["rollers"][a:b, arm, :2]
                worst = max(worst, float(np.max(np.linalg.norm(xy - xy[0], axis=1))))
    assert worst < 0.04
    assert abs(R["rpy"][-1, 2]) < 0.05 and r.metrics["max_abs_roll"][0] < 0.05
    assert not R["confirmed"].any() and not R["on_step"].any()
    assert set(R["phase"].tolist()) == {clm.WALK}


def test_clm_climbs_a_low_step_through_every_phase():
    """200 mm step, our level lift (climb_paper = 0, a named option), the arms climbing
    (crawl_max_h = 0, the default): a front arm stops on the step
    top (arm stop case: obstacle on the target), the other front arm follows, H_EST is
    confirmed, the crawlers stop, the rear arms are placed, the arms lift the body level,
    the flippers pull it onto the top, the release lowers it and it drives on (WALK,
    PREPARE, CLIMB, RELEASE, DONE)."""
    height = 0.2
    sc = _scenario("step1", horizon_s=84.0, record_every=10)
    r = rollout(sc, scenarios.params_batch(1, height=height, climb_paper=0.0, crawl_max_h=0.0), nthread=2)
    row = r.row(0)
    assert row["status"] == "ok" and row["success"], row
    R = {k: v[0] for k, v in r.records.items()}
    assert set(R["phase"].tolist()) == {clm.WALK, clm.PREPARE, clm.CLIMB, clm.RELEASE, clm.DONE}
    h_est = R["h_est"][-1]
    assert h_est == pytest.approx(height, abs=0.05)
    # the step is confirmed before PREPARE; no detection before the front arms reach it
    first_prepare = np.argmax(R["phase"] == clm.PREPARE)
    assert R["confirmed"][first_prepare] and not R["confirmed"][0]
    assert row["max_pitch"] < 0.3 and row["max_abs_roll"] < 0.1
    assert row["min_margin"] > 0.0
    assert row["final_z"] > height + 0.2


def test_clm_crawls_up_a_two_terrace_staircase():
    """Two 200 mm terraces from the front, CRAWL on (crawl_max_h = 0.25 m, a named option of
    ours; H_EST <= crawl_max_h): the arms grope the first
    riser, the step is confirmed, and the robot climbs it in CRAWL with the arms carried;
    blocked again by the second riser right after (DONE, stalled) it climbs that one in
    CRAWL too, and ends on the top. The arms are in the carrying pose (booms up) while
    crawling, and the robot never tips."""
    sc = _scenario("step2_front", horizon_s=90.0, record_every=10)
    r = rollout(sc, scenarios.params_batch(1, height=0.4, crawl_max_h=0.25), nthread=2)
    row = r.row(0)
    assert row["status"] == "ok" and row["success"], row
    R = {k: v[0] for k, v in r.records.items()}
    ph = R["phase"]
    assert clm.PREPARE not in ph and clm.CLIMB not in ph  # no arm climb
    assert R["h_est"][np.argmax(ph == clm.CRAWL)] == pytest.approx(0.2, abs=0.05)
    # two CRAWL climbs, the second straight from DONE (no groping in between)
    entries = np.flatnonzero((ph[1:] == clm.CRAWL) & (ph[:-1] != clm.CRAWL)) + 1
    assert ph[0] == clm.WALK and len(entries) == 2 and ph[entries[1] - 1] == clm.DONE
    assert row["max_pitch"] < 0.5 and row["max_abs_roll"] < 0.1
    assert row["final_z"] > 0.4 + 0.2


def test_clm_walks_past_a_block_beside_its_right_side():
    """Rough ground (paper, Figs. 19-20): a 500 mm block 10 mm beside the right crawler.
    A right arm's transfer collides with the block (the torque reaches collision_torque),
    the arm stops there, rides the block top in support (PLACED, roller above 0.5 m), and
    later returns to the floor (`arm_over_obstacle`); the left arms stay on the floor, no
    step is confirmed, and the robot walks on past the block in WALK without tipping, its
    right crawler on the floor: |roll| < 0.1 rad (until 7 Dec 2026 the riding arm, its boom
    at its limit, chased its contact with the elbow, pressed the roller down and held the
    right crawler off the floor: 0.21 rad). 80 s: since the arms also stop on a collision
    while the pressed joint moves (7 Dec 2026), the right arms stop on the block's top
    and near face more often, and the robot passes the block at about 67 s (49 s before)."""
    sc = _scenario("block", horizon_s=80.0, record_every=10)
    r = rollout(sc, scenarios.params_batch(1, height=0.5), nthread=2)
    row = r.row(0)
    assert row["status"] == "ok" and row["success"] and row["arm_over_obstacle"], row
    R = {k: v[0] for k, v in r.records.items()}
    assert set(R["phase"].tolist()) == {clm.WALK} and not R["confirmed"].any()
    right = np.array([not left for left in clm.LEFT])
    z = R["rollers"][..., 2]
    riding = (R["arm_phase"] == cr.PLACED) & (z > 0.5)
    assert riding[:, right].any() and not riding[:, ~right].any()
    first = np.argmax(riding[:, right].any(axis=1))
    assert (z[first:, right] < params.ROLLER_RADIUS + 0.02).any()  # back on the floor afterwards
    assert z[:, ~right][(R["arm_phase"] == cr.PLACED)[:, ~right]].max() < 0.2
    assert row["max_abs_roll"] < 0.1, row["max_abs_roll"]


def test_prepare_approach_squares_up_on_a_high_step():
    """PREPARE on a high step (H_EST > approach_min_h), front flippers up at A0: both
    crawlers drive towards the riser; the side whose raised front flipper is pressed back
    by the riser (torque beyond approach_tau for approach_touch_s) stops while the other
    drives on (square-up); no rear arm transfer starts before both sides are blocked. On a
    low step the approach is skipped (crawlers stopped)."""
    ctrl = clm.make_controller()
    step = jax.jit(ctrl.step)
    p = {k: jnp.asarray(v) for k, v in scenarios.PARAM_DEFAULTS.items()}
    a0 = float(p["A0"])
    q = jnp.asarray(clm.start_pose()[0].reshape(-1))
    obs = {"time": jnp.zeros(()), "quat": jnp.array([1.0, 0.0, 0.0, 0.0]),
           "flipper_q": jnp.array([a0, a0, 0.0, 0.0]), "flipper_tau": jnp.zeros(4), "arm_q": q,
           "arm_tau": jnp.zeros(12), "track_speed": jnp.full(2, float(p["clm_speed"])),
           "contact_points": jnp.zeros((len(scenarios.CONTACT_SITES), 3))}
    s0 = ctrl.init(p, obs)
    s0 = s0._replace(phase=jnp.asarray(clm.PREPARE, jnp.int32), confirmed=jnp.asarray(True),
                     flip=jnp.array([a0, a0, 0.0, 0.0]), h_est=jnp.asarray(0.4),
                     arms=s0.arms._replace(pause=jnp.asarray(1.0)))
    s, a = step(p, s0, obs)
    np.testing.assert_allclose(a[:2], [p["clm_speed"]] * 2)  # both crawlers drive
    pressed = {**obs, "flipper_tau": jnp.array([0.0, -2.0 * float(p["approach_tau"]), 0.0, 0.0])}
    n = int(np.ceil(float(p["approach_touch_s"]) / clm.CONTROL_DT)) + 2
    for _ in range(n):
        s, a = step(p, s, pressed)
    np.testing.assert_allclose(a[:2], [p["clm_speed"], 0.0])  # the right side is at the riser
    assert bool(s.approach.blocked[1]) and not bool(s.approach.blocked[0]) and not bool(s.approach.squared)
    assert int(s.arms.active) == -1  # no transfer yet
    both = {**obs, "flipper_tau": jnp.array([-2.0, -2.0, 0.0, 0.0]) * float(p["approach_tau"])}
    for _ in range(n):
        s, a = step(p, s, both)
    assert bool(s.approach.squared) and int(s.phase) == clm.PREPARE
    np.testing.assert_allclose(a[:2], [0.0, 0.0])
    # a low step: no approach
    s, a = step(p, s0._replace(h_est=jnp.asarray(0.2)), obs)
    assert bool(s.approach.squared)
    np.testing.assert_allclose(a[:2], [0.0, 0.0])


def _obs_at(yaw: float, pitch: float = 0.2, roll: float = -0.03):
    """An observation with the body at (roll, pitch, yaw) (z-up Z-Y-X, radians), arms in
    the start pose, a torque on the front flippers and the tracks rolling."""
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_quat()
    q = jnp.asarray(clm.start_pose()[0].reshape(-1))
    return {"time": jnp.asarray(3.0), "quat": jnp.array([w, x, y, z]), "flipper_q": jnp.array([0.5, 0.6, 0.0, 0.0]),
            "flipper_tau": jnp.array([20.0, -3.0, 1.0, 0.0]), "arm_q": q + 0.01, "arm_tau": jnp.arange(12.0),
            "track_speed": jnp.array([0.03, 0.028]), "contact_points": jnp.zeros((len(scenarios.CONTACT_SITES), 3))}


@pytest.mark.parametrize("phase", [clm.WALK, clm.PREPARE, clm.CLIMB, clm.RELEASE, clm.DONE])
@pytest.mark.parametrize("paper", [0.0, 1.0])
def test_clm_never_reads_the_yaw(phase, paper):
    """The real OCTOPUS cannot measure its yaw (paper, "Recognition of COG position"): the
    CLM's state and actions are the same whatever the IMU heading, in every phase, with
    either climb."""
    ctrl = clm.make_controller()
    p = {k: jnp.asarray(v) for k, v in scenarios.PARAM_DEFAULTS.items()}
    p["climb_paper"] = jnp.asarray(paper)
    step = jax.jit(ctrl.step)
    outs = []
    for yaw in (0.0, 0.4, -2.5):
        obs = _obs_at(yaw)
        s = ctrl.init(p, obs)
        s = s._replace(phase=jnp.asarray(phase, jnp.int32), confirmed=jnp.asarray(phase != clm.WALK))
        for _ in range(3):
            s, action = step(p, s, obs)
        outs.append((s, action))
    for s, action in outs[1:]:
        np.testing.assert_allclose(action, outs[0][1], atol=1e-9)
        for a, b in zip(jax.tree_util.tree_leaves(s), jax.tree_util.tree_leaves(outs[0][0])):
            np.testing.assert_allclose(a, b, atol=1e-9)


def test_operator_is_separate_and_off_by_default():
    """The operator layer (`operator.with_operator`) leaves the CLM's actions alone at
    operator_gain = 0; with a gain it speeds up the left track when the robot has turned
    left (yaw > 0) while driving straight, and never touches turning or stopped tracks."""
    from jaxloco.robots.octopus import operator

    tracks = jnp.array([0.03, 0.03])
    np.testing.assert_allclose(operator.steer(tracks, jnp.asarray(0.2), 0.0), tracks)
    left, right = np.asarray(operator.steer(tracks, jnp.asarray(0.2), 0.05))
    assert left == pytest.approx(0.04) and right == pytest.approx(0.02)
    assert np.asarray(operator.steer(tracks, jnp.asarray(5.0), 1.0)).tolist() == pytest.approx([0.06, 0.0])
    for fixed in (jnp.array([0.03, 0.0]), jnp.zeros(2)):
        np.testing.assert_allclose(operator.steer(fixed, jnp.asarray(0.2), 0.05), fixed)
    ctrl = clm.make_controller()
    op = operator.with_operator(ctrl)
    init, step, op_step = jax.jit(ctrl.init), jax.jit(ctrl.step), jax.jit(op.step)  # one program each
    p = {k: jnp.asarray(v) for k, v in scenarios.PARAM_DEFAULTS.items()}
    obs = _obs_at(0.3)
    s = init(p, obs)
    np.testing.assert_allclose(op_step(p, s, obs)[1], step(p, s, obs)[1])
    for yaw in (0.3, -0.3):
        obs = _obs_at(yaw, pitch=0.0, roll=0.0)
        s = init(p, obs)
        a = np.asarray(op_step({**p, "operator_gain": jnp.asarray(0.1)}, s, obs)[1])
        b = np.asarray(step(p, s, obs)[1])
        if b[0] == b[1] > 0:  # driving straight: steered against the yaw
            assert np.sign(a[0] - a[1]) == np.sign(yaw)
        np.testing.assert_allclose(a[2:], b[2:])


def test_paper_climb_and_release_rules_are_eqs_28_29():
    """`paper_climb_step` (Eqs. 28-29, first branches): every boom command + Delta_E, the
    front flippers measured angle - Delta_F (A' = the encoder), the rear ones held, yielding
    by Delta_A against a torque beyond T0; nothing moves once on top. `paper_release_step`
    (second branches): booms back up by Delta_E to the start pose's angle, flippers up by
    Delta_F to 0, and done only when every one is back."""
    p = {k: jnp.asarray(v) for k, v in scenarios.PARAM_DEFAULTS.items()}
    de, df, da = float(p["delta_e"]), float(p["delta_f"]), float(p["flip_delta_a"])
    q = jnp.asarray(clm.start_pose()[0])
    flip_cmd = jnp.array([1.4, 1.4, 0.0, 0.0])
    flip_q = jnp.array([1.3, 1.35, 0.01, -0.01])
    tau = jnp.array([0.0, -2.0 * float(p["T0"]), 0.0, 0.0])
    q2, f2 = clm.paper_climb_step(p, q, flip_cmd, flip_q, tau, jnp.asarray(False))
    np.testing.assert_allclose(q2[:, 1], q[:, 1] + de)
    np.testing.assert_allclose(q2[:, [0, 2]], q[:, [0, 2]])
    np.testing.assert_allclose(f2, [1.3 - df, 1.35 - df + da, 0.0, 0.0], atol=1e-12)
    f3 = clm.paper_climb_step({**p, "climb_rear_flippers": jnp.asarray(1.0), "flip_encoder": jnp.asarray(0.0),
                               "climb_yield": jnp.asarray(0.0)}, q, flip_cmd, flip_q, tau, jnp.asarray(False))[1]
    np.testing.assert_allclose(f3, flip_cmd - df)
    q4, f4 = clm.paper_climb_step(p, q, flip_cmd, flip_q, tau, jnp.asarray(True))
    np.testing.assert_allclose(q4, q)
    np.testing.assert_allclose(f4, flip_cmd)
    # release from a lifted pose
    lifted = q.at[:, 1].add(jnp.array([0.5, 0.5 * de, 0.0, 0.2]))
    flips = jnp.array([-0.3, -0.5 * df, 0.2, 0.0])
    q5, f5, back = clm.paper_release_step(p, lifted, flips)
    np.testing.assert_allclose(q5[:, 1], q[:, 1] + jnp.array([0.5 - de, 0.0, 0.0, 0.2 - de]), atol=1e-12)
    np.testing.assert_allclose(f5, [-0.3 + df, 0.0, 0.2, 0.0], atol=1e-12)
    assert not bool(back)
    assert bool(clm.paper_release_step(p, q, jnp.array([0.0, 0.1, 0.0, 0.0]))[2])


def test_the_common_axis_reading_turns_the_front_booms_down_and_the_rear_ones_up():
    """`climb_common_axis` = 1: Eq. 28's +Delta_E on the authors' common boom axis (their
    transfer lifts the rear booms to +0.6 rad and the front ones to -0.6) lowers the front
    EPRAs and raises the rear ones in {R} (forward kinematics); the release turns each
    boom back to the start pose's angle from the side it climbed, and is done only there."""
    p = {k: jnp.asarray(v) for k, v in scenarios.PARAM_DEFAULTS.items()}
    p = {**p, "climb_common_axis": jnp.asarray(1.0)}
    de = float(p["delta_e"])
    q = jnp.asarray(clm.start_pose()[0])
    flips = jnp.array([1.4, 1.4, 0.0, 0.0])
    q2, _ = clm.paper_climb_step(p, q, flips, flips, jnp.zeros(4), jnp.asarray(False))
    np.testing.assert_allclose(q2[:, 1] - q[:, 1], [de, de, -de, -de])
    kp = params.default_params()
    dz = np.asarray(kin.arm_tips(kp, q2)[:, 2] - kin.arm_tips(kp, q)[:, 2])
    assert np.all(dz[:2] < 0) and np.all(dz[2:] > 0), dz
    climbed = q.at[:, 1].add(jnp.array([0.3, 0.5 * de, -0.3, -0.5 * de]))
    q3, _, back = clm.paper_release_step(p, climbed, jnp.zeros(4))
    np.testing.assert_allclose(q3[:, 1], q[:, 1] + jnp.array([0.3 - de, 0.0, -0.3 + de, 0.0]), atol=1e-12)
    assert not bool(back)
    # a rear boom turned *down* (below the start in the authors' frame) is not theirs to release
    down = q.at[3, 1].add(0.2)
    q4, _, back = clm.paper_release_step(p, down, jnp.zeros(4))
    np.testing.assert_allclose(q4, down)
    assert bool(back)


def test_clm_stops_at_a_pit_and_picks_new_targets():
    """Arm stop Case 3 (paper, "Arm stop"): on a 0.4 m platform whose far edge is 0.8 m
    ahead, with no ground beyond it ("pit"), a front arm's target falls in the pit; the
    arm lifts again for a target pit_backoff nearer the body ("a new target point will
    be selected"), lands on the platform short of the edge, and the crawlers stop (the
    paper leaves the way down to the operator). The robot stays on the platform."""
    height, edge = 0.4, 0.8
    sc = scenarios.make_scenario("pit", clm.make_controller(), horizon_s=40.0, record_every=10)
    base = sc.record
    tips = np.array([sc.model.site(n).id for n in TIP_SITES])

    def record(p, data, obs, c, e):
        r = base(p, data, obs, c, e)
        r.update(pit=c.pit, backoff=c.arms.backoff, arm_phase=c.arms.arm_phase, rollers=data.site_xpos[tips])
        return r

    r = rollout(sc.with_(record=record), scenarios.params_batch(1, height=height, distance=edge), nthread=2)
    row = r.row(0)
    assert row["status"] == "ok" and row["success"] and not row["tipped"], row
    R = {k: v[0] for k, v in r.records.items()}
    assert R["pit"][-1] and not R["pit"][0]
    front = np.asarray(clm.FRONT)
    assert (R["backoff"][-1][front] > 0).all() and (R["backoff"][-1][~front] == 0).all()
    # the front rollers end in support on the platform top, short of the edge
    placed = R["arm_phase"][-1] == cr.PLACED
    ends = R["rollers"][-1][front & placed]
    assert (
        len(ends) >= 1
        and np.allclose(ends[:, 2], height + params.ROLLER_RADIUS, atol=0.02)
        and (ends[:, 0] < edge).all()
    )
    # stopped: the COG moves less than 2 cm in the last 10 s, and stays short of the edge
    cog = R["cog"]
    assert abs(cog[-1, 0] - cog[-50, 0]) < 0.02 and cog[-1, 0] < edge - 0.3
