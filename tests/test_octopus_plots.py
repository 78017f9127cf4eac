"""OCTOPUS time-trace plots (the paper's Figs. 12-20): the trace extraction from recorded
signals and the figures, on synthetic records (no simulation)."""

import matplotlib

matplotlib.use("Agg")

import numpy as np
import pytest

from jaxloco.plots import spans
from jaxloco.robots.octopus import clm, plots, scenarios

N_SUPPORT = len(scenarios.SUPPORT_BODIES)


def _records(n=40):
    """One run's records: standing level on four wheels, the RF roller lifted onto a 0.5 m
    obstacle from sample 10 to 19, the phases WALK (0-14), PREPARE (15-24), CLIMB (25-)."""
    t = np.arange(n)
    contact = np.zeros((n, N_SUPPORT), bool)
    contact[:, :4] = True  # the main crawler end wheels
    contact[:, 8:12] = True  # the rollers
    pts = np.zeros((n, N_SUPPORT, 3))
    pts[:, :4, :2] = [[0.16, 0.25], [-0.16, 0.25], [0.16, -0.25], [-0.16, -0.25]]
    pts[10:20, 9, 2] = 0.5  # RF on the obstacle top
    arm_q = np.zeros((n, 12))
    arm_q[:, 4] = 0.01 * t  # RF boom
    arm_tau = np.zeros((n, 12))
    arm_tau[10, 5] = 90.0  # RF elbow torque jump
    phase = np.where(t < 15, clm.WALK, np.where(t < 25, clm.PREPARE, clm.CLIMB))
    rpy = np.zeros((n, 3))
    rpy[:, 1] = -0.002 * t  # nose up
    return {"rpy": rpy[None], "contact": contact[None], "cog": np.zeros((1, n, 3)) + [0, 0, 0.27],
            "contact_points": pts[None], "phase": phase[None], "arm_q": arm_q[None], "arm_tau": arm_tau[None]}, 0.5 * t


def test_rollers_are_where_the_scenario_puts_them():
    rollers = [b for b in scenarios.SUPPORT_BODIES if b.endswith("_roller")]
    assert [scenarios.SUPPORT_BODIES.index(b) for b in rollers] == [8, 9, 10, 11]
    assert plots.CLM_PHASES == clm.PHASE_NAMES
    assert plots.OBSTACLE_MIN == scenarios.OBSTACLE_MIN


def test_climb_trace_signals():
    records, times = _records()
    tr = plots.climb_trace(records, 0, times)
    assert tr["arm_q"].shape == (40, 4, 3) and tr["arm_tau"].shape == (40, 4, 3)
    np.testing.assert_allclose(tr["arm_q"][:, 1, 1], 0.01 * np.arange(40))  # RF boom
    assert tr["arm_tau"][10, 1, 2] == 90.0
    np.testing.assert_allclose(tr["pitch"], 0.002 * np.arange(40))
    assert tr["roller_on"].shape == (40, 4) and np.all(tr["roller_z"][10:20, 1] == 0.5)
    assert np.all(np.isfinite(tr["margin"]))  # four wheels and four rollers in contact


def test_phase_spans():
    t = np.arange(6) * 0.5
    assert spans(t, np.array([0, 0, 1, 1, 1, 2])) == [(0.0, 1.0, 0), (1.0, 2.5, 1), (2.5, 3.0, 2)]


def test_figures():
    records, times = _records()
    tr = plots.climb_trace(records, 0, times)
    fig = plots.plot_arm_joints(tr, arms=(1, 3), title="RF and RR")
    axes = fig.get_axes()
    assert len(axes) == 6
    labels = {t.get_text() for t in axes[0].texts}
    assert {"A-C", "D", "E"} <= labels  # the paper's phases over WALK, PREPARE, CLIMB
    fig = plots.plot_attitude_traces({"run": tr}, paper={"run": {"max_pitch": 0.59, "max_abs_roll": 0.25}})
    a1, a2 = fig.get_axes()
    assert [ln.get_ydata()[0] for ln in a2.get_lines()[1:]] == [0.25, -0.25]  # the paper's |roll| at +-
    fig = plots.plot_climb_traces({"run": tr}, paper={"run": {"max_pitch": 0.6, "min_margin": 0.15}})
    a1, a2 = fig.get_axes()
    assert a1.get_lines()[1].get_ydata()[0] == 0.6 and a2.get_lines()[1].get_ydata()[0] == 0.15
    fig = plots.plot_arm_on_obstacle(tr, arm=1)
    a1, a2 = fig.get_axes()
    (span,) = [p for p in a1.patches]  # the roller on the obstacle top, samples 10-19
    assert span.get_x() == pytest.approx(5.0) and span.get_x() + span.get_width() == pytest.approx(10.0)
    assert max(a2.get_lines()[0].get_ydata()) == 90.0


def test_climb_geometry_figure_marks_each_mount_pitch():
    from jaxloco.robots.octopus import kinematics, params

    fig = plots.plot_climb_geometry(0.4, rear_flippers=(0.0, -0.83), stall=None)
    a1, a2 = fig.get_axes()
    dots = [ln for ln in a1.get_lines() if ln.get_marker() == "o"]
    assert [float(d.get_xdata()[0]) for d in dots] == pytest.approx(
        [float(kinematics.mount_pitch_on_rear_tips(0.4, a)) for a in (0.0, -0.83)])
    assert all(float(d.get_ydata()[0]) == pytest.approx(0.4 + params.MAIN_WHEEL_RADIUS) for d in dots)
    least = a2.get_lines()[0].get_ydata()
    assert np.nanmin(least) == pytest.approx(0.6166, abs=1e-3) and np.isnan(least[0])  # none at -85 deg
    assert not a1.patches and not a2.patches  # stall=None: no band
    assert a2.get_lines()[1].get_ydata() == pytest.approx(
        np.asarray(kinematics.tipping_pitch_on_rear_tips(a2.get_lines()[1].get_xdata())))
    assert len(a2.collections) == 1  # the window where the robot mounts without slipping or tipping


def test_cog_lead_figure_draws_the_bound_per_cog_height():
    from jaxloco.robots.octopus import kinematics

    xs = (0.1, 0.3, 0.5)
    fig = plots.plot_cog_lead(0.4, cog_heights=(0.183, 0.0), cog_x=xs)
    (ax,) = fig.get_axes()
    lines = ax.get_lines()[:2]
    base = kinematics.CrawlerProfile()
    for line, cz in zip(lines, (0.183, 0.0)):
        assert list(line.get_xdata()) == pytest.approx(xs)
        expected = [float(kinematics.cog_lead_over_edge_on_rear_tips(0.4, base._replace(cog_x=x, cog_z=cz))[0])
                    for x in xs]
        assert list(line.get_ydata()) == pytest.approx(expected)
    # at our COG height the COG passes the edge only beyond 0.45 m; at the axles' height from about 0.31 m
    assert lines[0].get_ydata()[1] < 0 < lines[0].get_ydata()[2]
    assert lines[1].get_ydata()[0] < 0 < lines[1].get_ydata()[2]
