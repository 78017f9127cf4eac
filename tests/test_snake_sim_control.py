"""T² Snake-3's task-space controller in MuJoCo (`sim_control`): the paper's relative
position accuracy experiment (Sec. V-A) with feedforward and feedback control, and the
joint-limit experiment (Sec. V-B) with mode switching in the closed loop."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from jaxloco.robots.snake import experiments, params, sim_control


@pytest.fixture(scope="module")
def accuracy():
    return {fb: sim_control.run_accuracy(feedback=fb) for fb in (False, True)}


def test_accuracy_feedback_converges_feedforward_keeps_the_servo_error(accuracy):
    """Feedback of the simulated head pose drives every Table III displacement to its
    target (Fig. 7(b): the measured w_h converges despite the servos' steady error),
    within 5 % (measured: at most 2.1 %); the paper's feedforward control keeps the
    head part's sag, which depends on the posture: lowering the head by 0.1 m sags it
    further (measured 3.9 % error there with model.py's head servos, 20 % with KP = 30;
    the paper had 1.5 %), x and roll stay within
    3 % as in the paper. Cross terms of the feedback runs stay within 1 cm / 0.02 rad."""
    ff, fb = accuracy[False], accuracy[True]
    for out in (ff, fb):
        assert all(s == "ok" for s in out["result"].status)
    assert np.all(fb["error"] < 5.0)
    assert ff["error"][0] < 3.0 and ff["error"][3] < 3.0  # dx, dalpha
    assert ff["error"][2] > 3 * fb["error"][2]  # dz: the sag is only removed by feedback
    off = fb["displacement"] - np.diag(experiments.ACCURACY_DELTAS)
    assert np.abs(off[:, :3]).max() < 0.01 and np.abs(off[:, 3:]).max() < 0.02
    # no skidding to speak of while holding the mode (the paper's 34 % came from slip)
    assert ff["max_slip"].max() < 0.05


def test_joint_limit_avoidance_in_mujoco():
    """Figs. 8-10, 8 s: the cost V decreases, the commanded modes follow the schedule
    (sigma = 1 for t < 2 s, then 2, 3, ... every Delta T = 1 s), the measured wheel
    contacts follow the commanded modes, the robot does not fall and the head (the
    controlled point, as in the paper's Fig. 9) stays within 0.1 m / 0.3 rad of where it
    was (paper: about 30 mm / 0.1 rad)."""
    res, recs = sim_control.run_joint_limit(n=1, horizon=8.0)
    assert res.status[0] == "ok"
    t, V, sigma = recs["t"][0], recs["V"][0], recs["sigma"][0]
    assert V[-1] < 0.8 * V[0]
    # the schedule, away from the switching instants (a record holds the command of the
    # control period before it)
    k = np.floor(t - experiments.SWITCH_AT).astype(int)
    expected = np.where(t < experiments.SWITCH_AT, 1, 2 + np.mod(k, 5))
    clear = np.abs(t - np.round(t)) > 0.03
    assert np.array_equal(sigma[clear], expected[clear])
    assert set(np.unique(sigma)) == {1, 2, 3, 4, 5, 6}
    contact = np.asarray(res.records["contact"][0])
    commanded = np.asarray(res.records["grounded_cmd"][0])
    assert np.mean(np.all(contact == commanded, axis=-1)[10:]) > 0.9
    assert np.abs(recs["error"][0][:, :3]).max() < 0.1
    assert np.linalg.norm(recs["error"][0][:, 3:6], axis=-1).max() < 0.3
    assert float(res.metrics["max_tilt"][0]) < 0.3
    # the base straightens: its mean |yaw angle| falls from 1.1 rad (the last joint,
    # theta_7, leaves its limit at about 21 s)
    base = np.abs(recs["phi"][0][:, params.N_H :]).mean(-1)
    assert base[-1] < base[0] - 0.15
    m = experiments.limit_metrics({k: jnp.asarray(v[0]) for k, v in recs.items() if k != "slip"})
    assert float(m["min_margin"]) > 0.02


def test_predictive_selection_in_mujoco_holds_one_candidate_mode_per_slot():
    """The MuJoCo controller with `predictive.Prediction`: after the fixing state (2 s) the
    first Delta T = 1 s slot holds one of the modes 2..6, chosen by the look-ahead; the
    robot stays up and the head within 0.1 m."""
    from jaxloco.robots.snake import predictive

    res, recs = sim_control.run_joint_limit(
        n=1, horizon=3.2, settle=0.5, prediction=predictive.Prediction(horizon_s=0.1)
    )
    assert res.status[0] == "ok"
    t, sigma = recs["t"][0], recs["sigma"][0]
    assert np.all(sigma[t < experiments.SWITCH_AT - 0.03] == 1)
    slot = (t > experiments.SWITCH_AT + 0.03) & (t < experiments.SWITCH_AT + 0.97)  # the first Delta T slot
    assert np.unique(sigma[slot]).size == 1 and sigma[slot][0] in predictive.CANDIDATES
    assert np.abs(recs["error"][0][:, :3]).max() < 0.1
