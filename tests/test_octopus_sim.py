"""OCTOPUS step scenarios (native backend) and the CCM baseline controller: per-simulation
terrain, driving speed on flat ground, and the crawler-only climbing limit (paper: CCM
fails the 400 mm step)."""

import mujoco
import numpy as np
import pytest

from jaxloco.robots.octopus import ccm, params, scenarios
from jaxloco.sim import terrain as tr
from jaxloco.sim.rollout import rollout


def test_step_height_differs_per_simulation():
    sc = scenarios.make_scenario("step1", horizon_s=0.5, record_every=5)
    heights = np.array([0.15, 0.4])
    r = rollout(sc, scenarios.params_batch(2, height=heights, mu=np.array([0.6, 1.0])), nthread=2)
    assert (r.status != "diverged").all()
    _, terrain = scenarios.build_model("step1")
    rows = tr.mocap_ids(sc.model, terrain)
    mocap = np.asarray(r.final.data.mocap_pos)[:, rows]
    # pieces: floor, left0, right0; the terrace tops rise with the height
    half_z = terrain.pieces[1].half_size[2]
    np.testing.assert_allclose(mocap[:, 1, 2] + half_z, heights, atol=1e-9)
    np.testing.assert_allclose(mocap[:, 2, 2] + half_z, heights, atol=1e-9)
    # records and metrics have their shapes; the robot stands on the floor with its
    # main crawler wheels and rear flippers in contact, stable; touch and the support set:
    # one per wheel and roller
    assert r.records["rpy"].shape == (2, sc.n_records, 3)
    assert r.records["flipper_q"].shape == (2, sc.n_records, 4)
    n = len(scenarios.SUPPORT_BODIES)
    assert r.records["touch"].shape == r.records["contact"].shape == (2, sc.n_records, n)
    assert r.records["contact_points"].shape == (2, sc.n_records, n, 3)
    assert r.records["contact"][:, -1].sum(-1).min() >= 6
    assert (r.metrics["min_margin"] > 0.03).all()
    assert not r.metrics["success"].any()


@pytest.mark.parametrize("kind", scenarios.KINDS)
def test_terrain_reaches_as_far_as_the_longest_run_can_drive(kind):
    """Every terrain carries the robot as far as it can drive within the longest horizon
    (600 s at 63 mm/s, `scenarios.REACH`), ahead and to the sides: MuJoCo's ray cast,
    straight down onto the placed terrain, finds the top where `terrain_height` says.
    (With 5 m step tops a CCM run of 150 s drove off the step it had climbed.)"""
    horizon = params.PARAMETERS["horizon"]
    assert scenarios.REACH > horizon.hi * params.CRAWLER_MAX_SPEED
    m, terrain = scenarios.build_model(kind)
    d = mujoco.MjData(m)
    p = {**scenarios.PARAM_DEFAULTS, "height": 0.3, "distance": 3.0}
    pos, quat = terrain.place(scenarios.terrain_values(kind, p))
    rows = tr.mocap_ids(m, terrain)
    d.mocap_pos[rows], d.mocap_quat[rows] = np.asarray(pos), np.asarray(quat)
    mujoco.mj_forward(m, d)
    far = scenarios.REACH - 0.5
    # pit: the platform the robot starts on ends at `distance`; along it, sideways
    ahead = 2.0 if kind == "pit" else far
    points = [(ahead, 0.0), (ahead, 0.9 * far), (ahead, -0.9 * far), (0.0, 0.9 * far), (0.0, -0.9 * far)]
    for x, y in points:
        geom = np.zeros(1, np.int32)
        dist = mujoco.mj_ray(m, d, np.array([x, y, 2.0]), np.array([0.0, 0.0, -1.0]), None, 1, -1, geom)
        assert dist > 0.0, f"{kind}: no ground under ({x}, {y})"
        want = float(scenarios.terrain_height(kind, p, np.array([x, y])))
        assert 2.0 - dist == pytest.approx(want, abs=1e-6), (kind, x, y)


def test_ccm_drives_at_commanded_speed_on_flat_ground():
    sc = scenarios.make_scenario("flat", horizon_s=4.0, record_every=25)
    speed = 0.05
    r = rollout(sc, scenarios.params_batch(1, speed=speed), nthread=1)
    x, t = r.records["pos"][0, :, 0], r.times
    v = (x[-1] - x[2]) / (t[-1] - t[2])
    assert v == pytest.approx(speed, rel=0.05)
    assert r.metrics["max_abs_roll"][0] < 0.01 and abs(r.metrics["max_pitch"][0]) < 0.01
    # flippers held by the policy: front raised, rear level
    np.testing.assert_allclose(r.records["flipper_q"][0, -1], [1.2, 1.2, 0.0, 0.0], atol=0.03)


def test_ccm_climbs_150mm_and_fails_400mm():
    """The automatic CCM policy climbs a 150 mm step; 400 mm is beyond the flippers even
    when it tries harder (the paper: crawler-only climbing < 250 mm, CCM success 0% on
    400 mm)."""
    sc = scenarios.make_scenario("step1", horizon_s=22.0, record_every=25)
    r = rollout(sc, scenarios.params_batch(2, height=np.array([0.15, 0.4]), distance=0.5), nthread=2)
    assert (r.status != "diverged").all()
    low, high = r.row(0), r.row(1)
    assert low["success"] and low["status"] == "ok"
    assert 0.0 < low["climb_time"] < 22.0 and low["shortfall"] == 0.0
    assert low["final_z"] > 0.15 + 0.2  # the COG on the step
    assert 0.1 < low["max_pitch"] < 0.6 and low["max_abs_roll"] < 0.05
    assert np.isfinite(low["min_margin"])
    # the policy went through its phases: obstacle seen, climbed, levelled
    assert {ccm.LOWER, ccm.PUSH, ccm.LEVEL} <= set(r.records["phase"][0].tolist())
    assert not high["success"] and high["status"] == "failed"
    assert high["final_x"] < 0.5  # stuck at the riser
    # short of the success line (0.3 m beyond the riser at 0.5 m) by what the COG never covered
    line = 0.5 + scenarios.PARAM_DEFAULTS["pass_distance"]
    assert high["shortfall"] == pytest.approx(line - r.records["cog"][1, :, 0].max(), abs=1e-9)
    assert high["shortfall"] > scenarios.PARAM_DEFAULTS["pass_distance"]
    # ... after trying: the flipper tips stayed below the edge, so the front flippers went
    # up to their limit against the riser (RAISE), and the front could not climb its face
    assert ccm.RAISE in r.records["phase"][1].tolist() and ccm.RAISE not in r.records["phase"][0].tolist()
    assert r.records["flipper_q"][1, -1, :2].min() > params.FLIPPER_LIMIT - 0.1
    assert high["max_pitch"] < 0.1
    assert params.CRAWLER_MAX_SPEED == pytest.approx(scenarios.PARAM_DEFAULTS["speed"])
