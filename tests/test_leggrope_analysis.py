"""`leggrope.slope_cycle` through the sweep engine: statuses, metrics and the summary
(critical inclination per walking direction)."""

import math

import numpy as np
import pyarrow as pa
import pytest
from compile_count import run_counting

from jaxloco import analysis
from jaxloco.robots.leggrope.analysis import SLOPE_CYCLE, summarize
from jaxloco.sweep import SpecError, run, spec_from_dict


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    """theta 0 (flat), 0.3 and 0.46 (> atan 0.45) at one direction, with the optional
    slip-capacity QP, through the real sweep engine (two chunks): (result, lowerings)."""
    out = tmp_path_factory.mktemp("sweep") / "leggrope"
    spec = {
        "sweep": {"analysis": "leggrope.slope_cycle", "name": "t", "chunk_size": 2},
        "fixed": {"psi": 0.4, "capacity": True},
        "params": {"theta": [0.0, 0.3, 0.46, -0.3]},
    }
    return run_counting(run, spec_from_dict(spec), output=out, progress=False)


@pytest.fixture(scope="module")
def small_sweep(small_run):
    return small_run[0].table


def test_a_two_chunk_sweep_compiles_once(small_run):
    small_run[1].assert_compiled_once()


def test_statuses_follow_the_friction_limit(small_sweep):
    t = small_sweep.to_pydict()
    assert t["theta"] == [0.0, 0.3, 0.46, -0.3]
    assert t["status"][:2] == ["ok", "ok"] and t["status"][3] == "ok"
    assert t["status"][2].startswith("failed: slip")
    assert t["slip_free"] == [True, True, False, True]
    assert t["slip_steps"][2] > 0 and t["slip_steps"][0] == 0


def test_metrics_are_consistent(small_sweep):
    t = small_sweep.to_pydict()
    for i in (0, 1, 3):
        # the capacity (best achievable s) is never below the controller's s ...
        assert t["min_capacity"][i] >= t["min_s"][i] - 1e-6
        # ... and the feasible cycles have s >= 0 up to the imposed sliver
        assert t["min_s_norm"][i] >= -1.1e-4
        assert 0.0 < t["max_relaxation"][i] < 0.1
        assert t["min_static_margin"][i] > 0 and t["min_reach"][i] > 0
        assert t["max_move_time"][i] <= 1.5 and t["cycle_time"][i] == pytest.approx(720 * 0.015)
    # feasible: ok with Eq. 19 hard (no relaxation of R_ref at all)
    for i in range(4):
        assert t["feasible"][i] == (t["status"][i] == "ok" and t["max_relaxation"][i] <= 1e-6)
    # beyond atan(mu) no distribution holds the robot: the best margin is negative
    assert t["min_capacity"][2] < 0
    # steeper slopes use more of the friction available
    assert t["max_friction_use"][1] > t["max_friction_use"][0]


def test_forward_crawl_cycle_is_slip_free_on_the_paper_slope(tmp_path):
    """numbering = "mirrored" (the paper's forward crawl along x_R, its A-D footsteps
    `gait.MIRRORED_CYCLE_STANCE`): slip-free on the pi/12 slope straight up, with a few
    per cent of R_ref relaxed (as the literal walk), and no distribution beyond atan mu."""
    spec = {
        "sweep": {"analysis": "leggrope.slope_cycle", "name": "t", "chunk_size": 2},
        "fixed": {"psi": 0.0, "numbering": "mirrored"},
        "params": {"theta": [math.pi / 12, 0.46]},
    }
    t = run(spec_from_dict(spec), output=tmp_path / "m", progress=False).table.to_pydict()
    assert t["status"][0] == "ok" and t["slip_free"][0]
    assert 0.0 < t["max_relaxation"][0] < 0.06 and t["plan_margin"][0] > -2.5e-3
    assert t["status"][1].startswith("failed: slip")
    with pytest.raises(SpecError, match="numbering"):
        run(spec_from_dict({**spec, "fixed": {"numbering": "diagonal"}}), output=tmp_path / "x", progress=False)


def test_spec_errors_name_the_parameter():
    with pytest.raises(SpecError, match="theta"):
        spec_from_dict({"sweep": {"analysis": "leggrope.slope_cycle"}, "params": {"theta": [0.1, 1.7]}})
    with pytest.raises(SpecError, match="n_move"):
        spec_from_dict({"sweep": {"analysis": "leggrope.slope_cycle"}, "params": {"n_move": [50, 60]}})
    with pytest.raises(SpecError, match="stride_len"):
        spec_from_dict({"sweep": {"analysis": "leggrope.slope_cycle"}, "fixed": {"stride_len": 0.1}})


def _table(rows):
    names = ("row", "theta", "psi", "status")
    cols = {n: [r[i] for r in rows] for i, n in enumerate(names)}
    return pa.table(cols)


def test_summary_finds_critical_theta_per_direction():
    rows, i = [], 0
    for psi, crit_pos, crit_neg in ((0.0, 0.4, 0.38), (0.7, 0.36, 0.39)):
        for th in np.round(np.arange(-0.45, 0.451, 0.01), 2):
            ok = (0 <= th <= crit_pos + 1e-9) or (-crit_neg - 1e-9 <= th < 0)
            rows.append((i, float(th), psi, "ok" if ok else "failed: slip (no distribution with s >= 0 at some step)"))
            i += 1
    s = summarize(_table(rows))
    by_psi = {r[0]: r for r in s.rows}
    assert by_psi["+0.000"][2:5] == ("0.400", "0.410", "slip")
    assert by_psi["+0.000"][5:7] == ("0.380", "0.390")
    assert by_psi["+0.700"][2] == "0.360" and by_psi["+0.700"][5] == "0.390"
    assert any("0.40" in n for n in s.notes)


def test_summary_reports_the_hard_rule_and_the_relaxation_used():
    """With `feasible` and `max_relaxation` columns: the critical |theta| with Eq. 19 hard
    (+ / -), and the largest relaxation among the rows inside the critical range."""
    rows, feasible, relax = [], [], []
    for i, th in enumerate(np.round(np.arange(-0.45, 0.451, 0.01), 2)):
        ok = -0.38 - 1e-9 <= th <= 0.4 + 1e-9
        rows.append((i, float(th), 0.0, "ok" if ok else "failed: slip (no distribution with s >= 0 at some step)"))
        feasible.append(bool(-0.1 - 1e-9 <= th <= 0.2 + 1e-9))  # the hard rule holds on a narrower range
        relax.append(0.02 + 0.1 * abs(th) if ok else 0.9)  # the failing rows' values must not count
    table = _table(rows).append_column("feasible", pa.array(feasible)).append_column("max_relaxation",
                                                                                    pa.array(relax))
    s = summarize(table)
    assert s.columns[-2:] == ("hard crit", "relax")
    row = s.rows[0]
    assert row[-2] == "0.200 / 0.100"
    assert row[-1] == f"{0.02 + 0.1 * 0.4:.3f}"  # the largest inside [-0.38, 0.40]
    assert summarize(_table(rows)).columns[-1] == "why -"  # older tables: no extra columns


def test_registered_and_documented():
    a = analysis.get("leggrope.slope_cycle")
    assert a is SLOPE_CYCLE and a.x64
    assert {p.name for p in a.params} >= {"theta", "psi", "mu", "r_ref_factor", "a_max", "v_max"}
    assert all(p.doc for p in a.params) and all(m.doc for m in a.metrics)
    assert a.param("theta").hi == pytest.approx(math.pi / 2)
