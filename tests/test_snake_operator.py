"""The teleoperator model of T² Snake-3's operations (`operator`): pure state-machine
behaviour, checked step by step against what the module docstring promises."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxloco.robots.snake import control, kinsim, operator

DT = 0.02
SCRIPT = kinsim.Target(jnp.array([0.3, 0.0, 0.4, 0.0, 0.0, 0.0, 1.9]),
                  jnp.array([[0.0, 0.0, -0.2, 0.0, 0.0, 0.0, 0.0], [-0.1, 0.05, 0.0, 0.0, 0.0, 0.3, 0.0]]),
                  jnp.array([1.0, 4.0]), jnp.array([2.0, 3.0]))
SEEN0 = jnp.array([0.31, 0.0, 0.38, 0.0, 0.05, 0.0])  # the robot sags: seen != the controller's w0


def run(seen_of, ratios, gain=0.0, limit=0.1, enter=2.0, exit_=0.8, min_switch=1.0):
    """Drive the operator for len(ratios) periods; seen_of(command) -> the seen pose of
    the next period (a toy plant). Returns the commands, stacked."""
    state = operator.initial_state(SEEN0)
    seen = SEEN0
    out = []
    for k, ratio in enumerate(ratios):
        state, cmd = operator.step(state, SCRIPT, jnp.asarray(k * DT), seen, jnp.asarray(ratio), DT, gain, limit, enter,
                             exit_, min_switch)
        out.append(cmd)
        seen = seen_of(cmd)
    return jax.tree.map(lambda *x: np.stack(x), *out)


def test_without_correction_or_switching_the_operator_plays_the_script_exactly():
    cmds = run(lambda c: SEEN0, np.zeros(400))
    t = np.arange(400) * DT
    for k in (0, 60, 150, 260, 399):
        wd, wd_dot = SCRIPT.at(jnp.asarray(t[k]))
        np.testing.assert_array_equal(cmds.wd[k], wd)
        np.testing.assert_array_equal(cmds.wd_dot[k], wd_dot)
        # the intended pose: where the point was seen at t = 0 plus the script's change
        np.testing.assert_allclose(cmds.intent[k], SEEN0 + (wd - SCRIPT.w0)[:6], atol=1e-12)
    assert not cmds.switching.any()


def test_the_correction_drives_a_sagging_point_onto_the_intended_position():
    """A toy plant whose point sits 3 cm below and 1 cm behind the controller's target:
    the operator's integral correction removes the error (gain 2 /s: time constant
    0.5 s; the script ends at 7 s, 5 s before the last step), and the offset is what
    the plant lacks."""
    sag = jnp.array([0.01, 0.0, 0.03, 0.0, 0.0, 0.0])
    shift = SEEN0 - SCRIPT.w0[:6]  # the seen start minus the controller's

    def plant(cmd):
        return cmd.wd[:6] + shift - sag

    cmds = run(plant, np.zeros(600), gain=2.0)
    error = cmds.intent[:, :3] - (cmds.wd[:, :3] + shift[:3] - sag[:3])
    assert np.abs(error[-1]).max() < 1e-6 < np.abs(error[100]).max()
    np.testing.assert_allclose(cmds.wd[-1, :3] - SCRIPT.at(jnp.asarray(599 * DT))[0][:3], sag[:3], atol=1e-6)
    # w_d_dot carries the correction's rate: integrating it gives w_d
    np.testing.assert_allclose(cmds.wd[0] + DT * np.cumsum(cmds.wd_dot[1:], 0)[-1], cmds.wd[-1], atol=2e-3)


def test_the_correction_is_bounded_per_axis():
    cmds = run(lambda c: SEEN0 + jnp.array([0.0, 0.0, -1.0, 0, 0, 0]), np.zeros(300), gain=5.0, limit=0.05)
    offset = cmds.wd[:, :3] - np.stack([SCRIPT.at(jnp.asarray(k * DT))[0][:3] for k in range(300)])
    assert offset[-1, 2] == pytest.approx(0.05) and np.abs(offset).max() <= 0.05 + 1e-12


def test_a_joint_at_its_limit_pauses_the_script_and_commands_switching_until_it_is_free():
    """ratio 0.5, then a stall (1.0) from 1.5 s, freed (0.6) at 2.2 s: switching from the
    stall for at least min_switch = 1 s (to 2.5 s) even though the joint is free before;
    the target stands still meanwhile and the script resumes where it stopped."""
    t = np.arange(250) * DT
    ratio = np.where(t < 1.5, 0.5, np.where(t < 2.2, 1.0, 0.6))
    cmds = run(lambda c: SEEN0, ratio, enter=0.97, exit_=0.8, min_switch=1.0)
    on = cmds.switching
    np.testing.assert_array_equal(on, (t >= 1.5 - 1e-9) & (t < 2.5 - 1e-9))
    assert np.ptp(cmds.wd[on], axis=0).max() < 1e-12 and np.abs(cmds.wd_dot[on]).max() == 0.0
    paused = on.sum() * DT
    k = 240
    np.testing.assert_allclose(cmds.wd[k], SCRIPT.at(jnp.asarray(t[k] - paused))[0], atol=1e-12)


def test_the_operator_watches_the_base_yaw_joints_only():
    phi = jnp.zeros(12).at[1].set(control.PHI_LIMITS[1])  # psi_1 of the head part at its limit
    assert float(operator.base_limit_ratio(phi)) == 0.0
    phi = phi.at[7].set(-0.9 * control.PHI_LIMITS[7])  # theta_5
    assert float(operator.base_limit_ratio(phi)) == pytest.approx(0.9)
