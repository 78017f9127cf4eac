"""The leg-grope walk in simulation: force sensing, a collapsing foothold, and the
`leggrope.fragile_walk` sweep (resume after an interruption)."""

from __future__ import annotations

import numpy as np
import pytest

from jaxloco.robots.leggrope import control, scenarios
from jaxloco.robots.leggrope.params import G, default_params
from jaxloco.sim.rollout import rollout
from jaxloco.sweep import run as run_sweep
from jaxloco.sweep.errors import SweepInterrupted

THETA = float(np.pi / 12)


@pytest.fixture(scope="module")
def walk():
    """Two 9 s walks on the pi/12 slope: sound footholds, and L2's first target weak
    (L2 gropes first, so its foothold collapses during the first grope)."""
    sc = scenarios.make_scenario(horizon_s=9.0, record_every=5)
    p = scenarios.params_batch(2, theta=THETA, weak_leg=np.array([-1, 1]))
    return sc, rollout(sc, p, seeds=[0, 0])


def test_toe_force_sensors_carry_the_weight(walk):
    _, r = walk
    mg = float(default_params().total_mass) * G
    # at 0.5 s the robot stands on four legs: normal forces sum to M g cos(theta)
    i = int(np.searchsorted(r.times, 0.5))
    total = r.records["normal_force"][0, i].sum()
    assert abs(total - mg * np.cos(THETA)) < 0.05 * mg
    assert (r.records["normal_force"][0, i] > 0).all()


def test_first_grope_probes_the_foothold(walk):
    _, r = walk
    assert r.status[0] != "diverged"
    assert r.metrics["completed_gropes"][0] >= 1
    assert r.metrics["collapses_met"][0] == 0


def test_collapsing_foothold_is_survived_on_three_legs(walk):
    _, r = walk
    assert r.metrics["collapses_met"][1] >= 1
    assert r.records["collapsed"][1].max() >= 1
    assert not r.metrics["fell"][1]
    assert r.metrics["max_attitude_change"][1] < np.radians(10)
    # after the collapse the robot gropes its fallback foothold
    phases = r.records["phase"][1]
    first = int(np.argmax(r.records["collapsed"][1] >= 1))
    assert (phases[first:] == control.A).any()


def _spec(tmp_path):
    return {
        "sweep": {"analysis": "leggrope.fragile_walk", "name": "t", "chunk_size": 2, "output": str(tmp_path / "out"),
                  "formats": ["parquet"]},
        "fixed": {"horizon": 1.0, "nthread": 1},
        "params": {"mu": [0.45, 0.8], "theta": [0.0, 0.1]},
    }


def test_interrupted_simulation_sweep_resumes(tmp_path):
    full = run_sweep(_spec(tmp_path), progress=False, output=tmp_path / "full")

    def stop(index, n):
        raise KeyboardInterrupt

    with pytest.raises(SweepInterrupted):
        run_sweep(_spec(tmp_path), progress=False, on_chunk=stop)
    resumed = run_sweep(_spec(tmp_path), progress=False, resume=True)
    assert resumed.chunks_reused == 1 and resumed.chunks_computed == 1
    for name in ("max_abs_roll", "max_attitude_change", "status", "mu", "theta"):
        np.testing.assert_array_equal(resumed.table.column(name).to_numpy(zero_copy_only=False),
                                      full.table.column(name).to_numpy(zero_copy_only=False))
