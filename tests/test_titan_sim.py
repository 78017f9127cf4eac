"""TITAN XI in MuJoCo: standing, one gait cycle of the footstep executor on flat ground,
the tethers holding the robot on the 30 deg slope (Sec. 8.4), and the same cycle without
re-referencing the foot targets (`control.anchor_to_feet`) and without the servos' load
feedforward (`control.load_feedforward`). One batch of six simulations compiled once
(native backend); the executor's pure helpers checked against closed forms."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxloco.robots.titan import control, kinematics, params, scenarios
from jaxloco.sim.rollout import rollout

THETA = float(params.SLOPE_ANGLE)
WALK, HOLD, TETHER, NO_TETHER, NO_ANCHOR, NO_LOAD_FF = range(6)


@pytest.fixture(scope="module")
def runs():
    walk = scenarios.demo_crawl_plan(1)
    hold = scenarios.hold_plan(walk.n_steps)
    slope = hold.to_world(THETA)
    sc = scenarios.make_scenario(walk.n_steps)
    p = scenarios.params_batch(
        [walk, hold, slope, slope, walk, walk],
        theta=np.array([0.0, 0.0, THETA, THETA, 0.0, 0.0]),
        tether=np.array([1.0, 1.0, 1.0, 0.0, 1.0, 1.0]),
        # below tan(30 deg) = 0.58 on the slope: the robot slides unless the tethers hold it
        mu=np.array([0.6, 0.6, 0.5, 0.5, 0.6, 0.6]),
        anchor_feet=np.array([1.0, 1.0, 1.0, 1.0, 0.0, 1.0]),
        load_feedforward=np.array([1.0, 1.0, 1.0, 1.0, 1.0, 0.0]),
    )
    return sc, rollout(sc, p, nthread=2)


def test_plan_format(runs):
    plan = scenarios.demo_crawl_plan(2)
    assert (
        plan.feet.shape == (12, 4, 3)
        and plan.body.shape == (12, 3)
        and plan.swing.shape == (12,)
    )
    assert list(plan.swing[:6]) == [2, 0, -1, 3, 1, -1]  # LR, LF, shift, RR, RF, shift
    assert plan.cycle_end.sum() == 2
    # every cycle moves the COG by the stroke 2 L_std and back onto the path (y = -W/2)
    ends = plan.body[plan.cycle_end]
    assert np.allclose(np.diff(np.r_[plan.body0[0], ends[:, 0]]), 2 * params.L_STD)
    assert np.allclose(ends[:, 1], plan.path_origin[1])


def test_robot_stands_still_on_flat_ground(runs):
    _, r = runs
    assert r.status[HOLD] == "ok"
    z = r.records["body_pos"][HOLD, :, 2]
    assert z[0] - z.min() < 0.03  # [m] sinks less than 3 cm over 20 s
    assert r.metrics["foot_slip"][HOLD] < 0.01
    touch = r.records["touch"][HOLD, -1]
    assert abs(touch.sum() / (7000 * params.G) - 1.0) < 0.02  # the feet carry the weight


def test_one_gait_cycle_on_flat_ground(runs):
    _, r = runs
    m = r.row(WALK)
    assert m["completed"] and not m["fell"] and r.status[WALK] != "diverged"
    assert 0.8 < m["final_progress"] < 1.1  # [m] one stride (2 L_std = 1.0 m)
    # [m] three-leg support during swings (planned ~0.07; the feet creep, see the report)
    assert m["min_nesm_swing"] > 0.0
    assert m["min_nesm"] > 0.0
    assert m["max_path_deviation"] < 0.05  # the COG back on the path at the cycle end
    assert not m["swing_collision"] and not m["forbidden_landing"]
    assert m["max_tilt"] < 0.05
    # the swing legs really lift: foot up to ~swing_height above the ground
    feet_z = r.records["feet"][WALK, :, :, 2]
    assert feet_z.max() > 0.5


def test_tethers_hold_the_robot_on_the_30_degree_slope(runs):
    _, r = runs
    on, off = r.records["body_pos"][TETHER], r.records["body_pos"][NO_TETHER]
    assert r.status[TETHER] == "ok" and r.metrics["foot_slip"][TETHER] < 0.02
    assert np.linalg.norm(on[-1] - on[0]) < 0.02
    # without the tethers the robot slides down (mu 0.5 < tan 30 deg)
    assert np.linalg.norm(off[-1] - off[0]) > 0.5 or r.metrics["fell"][NO_TETHER]
    # and the tethers take the slope-parallel load off the feet: normal loads sum to
    # M g cos(theta)
    touch = r.records["touch"][TETHER, -1]
    assert abs(touch.sum() / (7000 * params.G * np.cos(THETA)) - 1.0) < 0.03


def test_foot_targets_stay_on_the_feet(runs):
    """Re-referencing the targets of the feet in contact at each step
    (`control.anchor_to_feet`) keeps the commanded feet within 5 mm of the real ones; without
    it the slip and sag of every step stay in the targets (1-2 cm after one cycle, 0.2 m
    and a foot on a frame after ~8 cycles of the Sec. 8.3 field). Every foot carries load."""
    _, r = runs
    off = np.linalg.norm(r.records["feet_target"][:, -1] - r.records["feet"][:, -1], axis=-1)
    assert off[WALK].max() < 0.005 and off[NO_ANCHOR].min() > 0.01
    load = r.records["touch"][WALK, -1] / (7000 * params.G)
    assert load.min() > 0.10 and abs(load.sum() - 1.0) < 0.02


def test_load_feedforward_takes_out_the_servo_sag(runs):
    """Pre-deflecting the servos by the static foot loads keeps the body within 3 mm of its
    target height through a cycle and the feet within 1 cm of their footholds; the
    compliant servos alone let it sag ~1 cm and the body tip towards each lifted leg."""
    _, r = runs
    on, off = r.row(WALK), r.row(NO_LOAD_FF)
    assert on["max_sag"] < 0.003 < 0.006 < off["max_sag"]
    assert on["max_touchdown_error"] < 0.01 and on["max_tilt"] < off["max_tilt"]


def test_load_shares_are_the_statics_of_the_support():
    up = jnp.array([0.0, 0.0, 1.0])
    feet = jnp.array([[2.0, 2.0, 0.0], [2.0, -2.0, 0.0], [-2.0, 2.0, 0.0], [-2.0, -2.0, 0.0]])
    # four feet, COG over their centroid: equal shares
    w4 = control.load_shares(jnp.array([0.0, 0.0, 1.5]), feet, jnp.ones(4, bool), up)
    np.testing.assert_allclose(w4, 0.25, atol=1e-12)
    # three feet: the barycentric coordinates of the COG's projection (closed form), no
    # moment about the COG, nothing on the lifted foot
    cog = jnp.array([0.3, -0.4, 1.5])
    w3 = control.load_shares(cog, feet, jnp.arange(4) != 0, up)
    a, b, c = np.asarray(feet[1, :2]), np.asarray(feet[2, :2]), np.asarray(feet[3, :2])
    T = np.column_stack([a - c, b - c])
    l1, l2 = np.linalg.solve(T, np.asarray(cog[:2]) - c)
    np.testing.assert_allclose(w3, [0.0, l1, l2, 1.0 - l1 - l2], atol=1e-12)
    np.testing.assert_allclose(np.asarray(w3) @ np.asarray(feet[:, :2] - cog[:2]), 0.0, atol=1e-12)


def test_support_shift_follows_the_feet_slip_in_the_plane():
    support_shift = jax.jit(control.support_shift, static_argnums=1)  # one program, not one per operation
    walk = scenarios.demo_crawl_plan(1)
    p = {k: jnp.asarray(v[0]) for k, v in scenarios.params_batch([walk]).items()}
    n_steps = walk.n_steps
    slip = jnp.array([0.02, -0.01, 0.0])
    planned = p["plan_feet"][3] + kinematics.FOOT_RADIUS * jnp.array([0.0, 0.0, 1.0])
    now = control.StepTargets(jnp.asarray(3), jnp.asarray(int(walk.swing[3])), planned, p["plan_body"][3],
                              jnp.asarray(False), jnp.asarray(0.5))
    swing_off = jnp.zeros((4, 3)).at[int(walk.swing[3])].set(jnp.array([0.3, 0.0, 0.4]))
    # every supporting foot slid by `slip` in the plane: the COG target moves with them, exactly
    feet = planned + slip + swing_off
    shift = support_shift(p, n_steps, now, {"feet": feet})
    np.testing.assert_allclose(shift, slip, atol=1e-6)
    # the feet also rose 5 mm: the shift stays in the plane, and the COG, now lower against the
    # tipping axes, needs a slightly different shift to keep each edge's energy margin
    risen = support_shift(p, n_steps, now, {"feet": feet + jnp.array([0.0, 0.0, 0.005])})
    assert float(risen[2]) == 0.0
    assert 1e-5 < float(jnp.linalg.norm(risen - slip)) < 2e-3
    assert float(jnp.linalg.norm(support_shift({**p, "support_relative": 0.0}, n_steps, now,
                                                       {"feet": feet}))) == 0.0
