"""T² Snake-3's operations (Sec. V-D): the operator's script and picking up the pipe."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from jaxloco.robots.snake import kinsim as S
from jaxloco.robots.snake import operations as O


def test_a_script_is_the_sum_of_its_smooth_steps():
    w0 = jnp.arange(7.0)
    delta = jnp.array([[0, 0, -0.2, 0, 0, 0, -1.0], [0, 0, 0.1, 0, 0, 0, 0]], float)
    script = S.Target(w0, delta, jnp.array([1.0, 6.0]), jnp.array([4.0, 2.0]))
    for t in (0.0, 2.5, 5.5, 7.0, 9.0):
        w, w_dot = script.at(jnp.asarray(t))
        one = [S.Target(w0 * 0, delta[k], jnp.array([1.0, 6.0])[k], jnp.array([4.0, 2.0])[k]).at(jnp.asarray(t))
               for k in range(2)]
        np.testing.assert_allclose(w, w0 + one[0][0] + one[1][0], atol=1e-12)
        np.testing.assert_allclose(w_dot, one[0][1] + one[1][1], atol=1e-12)
    np.testing.assert_allclose(script.at(jnp.asarray(9.0))[0], w0 + delta.sum(0), atol=1e-12)
    # the host copy of the tip's part
    np.testing.assert_allclose(O.script_target(np.array([9.0]), np.zeros(6), [(1.0, 4.0, delta[0]), (6.0, 2.0, delta[1])])[0],
                               np.asarray(delta.sum(0))[:6], atol=1e-12)


@pytest.fixture(scope="module")
def pick():
    return O.run_pick(1)


def test_the_gripper_picks_the_pipe_up(pick):
    """Reach down with psi_3 lowered, harden, lift by 0.1 m: the pipe comes up with the
    gripper (its centre rises > 4 cm; measured 5.4); the tip follows the script within
    5 cm under the paper's feedforward control (measured 3.9 cm: the head part sags
    under the lifted pose; the paper's operator corrected such errors by joystick)."""
    res, m = pick
    assert res.status[0] == "ok"
    assert m["pipe_lift"][0] > 0.04
    assert m["max_tip_error"][0] < 0.05
    pipe = np.asarray(res.records["fixture"])[0]
    before = res.times < O.PICK_GRIP_AT
    assert np.abs(pipe[before, 2] - pipe[0, 2]).max() < 0.005  # soft: the pipe stays down until the grip


def test_without_the_grip_the_pipe_stays_on_the_ground():
    res, m = O.run_pick(1, grip_at=1e3)
    assert res.status[0] == "ok" and abs(m["pipe_lift"][0]) < 0.005


def test_the_hardened_gripper_turns_the_valve():
    """Push the soft gripper onto the handwheel, harden, roll the gripper 90 deg: the
    valve turns with it (measured 1.29 of 1.57 rad: the membrane's torsional grip slips a
    little), the tip held within 30 mm (measured 21 mm). Without the grip the gripper,
    pressed 1 cm into the handwheel by its stiff servos, still turns it 0.97 rad: in this
    model the press does most of the work."""
    res, m = O.run_valve(2, grip_at=np.array([O.VALVE_GRIP_AT, 1e3]))
    assert list(res.status) == ["ok", "ok"]
    assert m["roll"][0] == pytest.approx(np.pi / 2, abs=0.05)
    assert 0.6 * np.pi / 2 < m["valve_turn"][0] <= m["roll"][0] + 0.01
    assert m["max_tip_error"][0] < 0.03
    assert m["valve_turn"][1] < m["valve_turn"][0] - 0.1


def test_the_door_stalls_at_a_joint_limit_and_mode_switching_frees_it():
    """Fig. 14: pulling the knob along the door's arc drives theta_4, theta_5 onto their
    limits (the stall); without help the door does not open past 0.6 rad. With the
    operator's pause and the switching state (modes 2..6) both leave their limits while
    the tip stays near the knob, and the pull then opens the door much wider."""
    stalled, m0 = O.run_door(1, horizon=16.0)
    script = O.door_recovery_script()
    res, m = O.run_door(1, switch_at=O.DOOR_SWITCH[0], switch_until=O.DOOR_SWITCH[1], script=script, horizon=24.0)
    assert stalled.status[0] == "ok" and res.status[0] == "ok"
    lim = 0.97 * np.radians(65)
    phi, t = np.asarray(res.records["phi"])[0], res.times
    at_stall = (t > 5.0) & (t < 6.0)
    assert np.all(np.abs(phi[at_stall, 6]) > lim) and np.all(np.abs(phi[at_stall, 7]) > lim)  # theta_4, theta_5
    freed = (t > O.DOOR_SWITCH[1] - 1.0) & (t < O.DOOR_SWITCH[1])
    assert np.all(np.abs(phi[freed, 6:8]) < 0.5 * np.radians(65))
    assert m0["door_max"][0] < 0.6 and m["door_max"][0] > m0["door_max"][0] + 0.3  # measured 0.49, 1.08
