"""The CLM control rules of OCTOPUS (`clm_rules`) against their closed forms, a kinematic
arm transfer to the Table 2 targets, batching and gradients."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads

from jaxloco.robots.octopus import clm_rules, kinematics
from jaxloco.robots.octopus.params import TABLE2_INIT, TABLE2_TARGET, default_params

T0, DA, A0, DB = 5.0, 0.01, np.radians(85.0), 0.02


@pytest.mark.parametrize(
    ("a_prev", "t_prev", "a_expected", "case"),
    [
        (0.3, 2.0, 0.3, clm_rules.FLIPPER_HOLD),  # Case 1: vibration
        (0.3, -2.0, 0.3, clm_rules.FLIPPER_HOLD),
        (0.3, -40.0, 0.3 + DA, clm_rules.FLIPPER_FOLLOW),  # Case 2: an obstacle pushes the tip up
        (0.3, 40.0, 0.3 - DA, clm_rules.FLIPPER_FOLLOW),  # a pit: the flipper turns down
        (A0 + 0.01, -40.0, A0 + 0.01 - DB, clm_rules.FLIPPER_LIMIT),  # Case 3 wins over Case 2
        (A0 + 0.01, 0.0, A0 + 0.01 - DB, clm_rules.FLIPPER_LIMIT),
    ],
)
def test_flipper_rule_cases(a_prev, t_prev, a_expected, case):
    a, c = clm_rules.flipper_rule(jnp.float64(a_prev), jnp.float64(t_prev), T0, DA, A0, DB)
    assert float(a) == pytest.approx(a_expected, abs=1e-12)
    assert int(c) == case


def test_flipper_rule_vmap_equals_loop_and_grad():
    rng = np.random.default_rng(0)
    a = jnp.asarray(rng.uniform(-1.0, 1.6, 50))
    t = jnp.asarray(rng.uniform(-30, 30, 50))
    batched = jax.vmap(lambda x, y: clm_rules.flipper_rule(x, y, T0, DA, A0, DB))(a, t)
    for i in range(50):
        one = clm_rules.flipper_rule(a[i], t[i], T0, DA, A0, DB)
        assert float(one[0]) == float(batched[0][i]) and int(one[1]) == int(batched[1][i])
    # away from the switching surfaces the command moves one-for-one with A'
    check_grads(lambda x: clm_rules.flipper_rule(x, jnp.float64(-40.0), T0, DA, A0, DB)[0], (jnp.float64(0.3),),
                order=1, modes=("fwd", "rev"))


def test_arm_stop_cases():
    target = jnp.array([0.618, 0.399, -0.433])
    dc, dd = 0.05, 0.03
    cases = {
        clm_rules.STOP_REACHED: target + jnp.array([0.01, 0.0, 0.01]),
        clm_rules.STOP_BLOCKED: target + jnp.array([-0.2, 0.0, 0.3]),  # |dx| > dC wins
        clm_rules.STOP_ON_OBSTACLE: target + jnp.array([0.0, 0.0, 0.1]),
        clm_rules.STOP_IN_PIT: target + jnp.array([0.02, 0.0, -0.1]),
    }
    pts = jnp.stack(list(cases.values()))
    assert list(np.asarray(clm_rules.arm_stop_case(pts, target, dc, dd))) == list(cases)


def test_collision_is_a_torque_rise():
    prev = jnp.array([[10.0, -50.0, 20.0], [10.0, -50.0, 20.0]])
    now = jnp.array([[12.0, -55.0, 21.0], [10.0, -95.0, 20.0]])
    assert list(np.asarray(clm_rules.collision(now, prev, 20.0))) == [False, True]


def _pitch(p):
    """{R} -> world rotation of a robot pitched by p (> 0 nose up), no roll or yaw."""
    c, s = np.cos(p), np.sin(p)
    return np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])


@pytest.mark.parametrize(("robot_pitch", "terrain_pitch"), [(0.0, 0.0), (0.1, 0.3), (0.4, 0.15), (-0.2, 0.1)])
def test_predicted_contacts_stay_fixed_on_the_ground(robot_pitch, terrain_pitch):
    """Closed form: the body moves L along a terrain inclined by T_P while pitched by
    R_P; a ground-fixed contact, seen from {R}, is where predict_contacts puts it."""
    rng = np.random.default_rng(1)
    world = rng.uniform(-1, 1, (4, 3))
    base = np.array([0.3, 0.0, 0.5])
    step = 0.0126  # 63 mm/s over 0.2 s
    R = _pitch(robot_pitch)
    before = (world - base) @ R
    moved = base + step * np.array([np.cos(terrain_pitch), 0.0, np.sin(terrain_pitch)])
    after = (world - moved) @ R
    got = clm_rules.predict_contacts(jnp.asarray(before), jnp.float64(step), jnp.float64(terrain_pitch),
                              jnp.float64(robot_pitch))
    np.testing.assert_allclose(got, after, atol=1e-12)
    check_grads(lambda tp: clm_rules.predict_contacts(jnp.asarray(before), jnp.float64(step), tp,
                                                      jnp.float64(robot_pitch)),
                (jnp.float64(terrain_pitch),), order=2)


@pytest.mark.parametrize("arm", [0, 1, 2, 3])
def test_kinematic_arm_transfer_reaches_its_table2_target(arm):
    """A perfectly tracking arm run through Eqs. 19-21 from its Table 2 start to its
    Table 2 target on flat ground (contact when the EPRA reaches the ground plane):
    lift, swing, over the target (100 mm up), lower and stop within 10 mm of it."""
    params = default_params()
    q, _ = kinematics.inverse_kinematics(params, arm, jnp.asarray(TABLE2_INIT[arm]))
    q_target, reach = kinematics.inverse_kinematics(params, arm, jnp.asarray(TABLE2_TARGET[arm]))
    above = jnp.asarray(TABLE2_TARGET[arm]) + jnp.array([0, 0, 0.1])
    q_above, reach_above = kinematics.inverse_kinematics(params, arm, above)
    assert float(reach) > 0 and float(reach_above) > 0
    ground = TABLE2_TARGET[arm][2]
    step = jax.jit(lambda q, ph, c: clm_rules.transfer_step(q, ph, c, q_target, q_above, -0.9, 0.2, 0.03, 0.02))
    phase = jnp.int32(clm_rules.LIFT)
    seen, highest = [], -np.inf
    for _ in range(400):
        tip = kinematics.arm_tip(params, arm, q)
        highest = max(highest, float(tip[2]))
        contact = tip[2] <= ground
        q, phase = step(q, phase, contact)
        if not seen or seen[-1] != int(phase):
            seen.append(int(phase))
        if int(phase) == clm_rules.PLACED:
            break
    assert seen == [clm_rules.LIFT, clm_rules.SWING, clm_rules.OVER, clm_rules.LOWER, clm_rules.PLACED]
    tip = np.asarray(kinematics.arm_tip(params, arm, q))
    assert highest > ground + 0.15  # the EPRA was carried well clear of the ground
    assert np.linalg.norm(tip - TABLE2_TARGET[arm]) < 0.01


@pytest.mark.parametrize(
    ("h", "s", "boom", "flip", "boom_next", "flip_next", "on_top"),
    [
        (0.3, 0.1, 0.2, -0.1, 0.25, -0.12, False),  # H < H_EST: keep pushing the body up
        (0.5, 0.1, 0.2, -0.1, 0.25, -0.12, False),  # on top but not far enough in (S < L)
        (0.5, 0.4, 0.2, -0.1, 0.15, -0.08, True),  # release
        (0.5, 0.4, -0.1, 0.1, -0.1, 0.1, True),  # released: hold
    ],
)
def test_climb_rule(h, s, boom, flip, boom_next, flip_next, on_top):
    b, f, top = clm_rules.climb_rule(jnp.float64(boom), jnp.float64(flip), h, 0.4, s, 0.3, 0.05, 0.02)
    assert float(b) == pytest.approx(boom_next) and float(f) == pytest.approx(flip_next)
    assert bool(top) is on_top
