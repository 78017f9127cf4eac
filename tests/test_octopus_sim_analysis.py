"""The `octopus.step_climb` sweep analysis (simulated OCTOPUS with the CLM controller,
native MuJoCo): registered, its parameters validated through the sweep spec, a tiny
sweep end to end with finite metrics and a summary, and resume after an interruption."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from compile_count import run_counting

from jaxloco import analysis
from jaxloco.errors import SpecError, SweepInterrupted
from jaxloco.robots.octopus import clm, scenarios, sim_analysis
from jaxloco.sweep import run as run_sweep
from jaxloco.sweep import spec_from_dict

NAME = "octopus.step_climb"


def test_registered_with_the_clm_gains():
    a = analysis.get(NAME)
    assert a is sim_analysis.STEP_CLIMB and NAME in analysis.names()
    assert a.executor == "host"
    defaults = a.defaults()
    for gain in ("T0", "flip_delta_a", "delta_e", "delta_f", "clm_speed"):
        assert defaults[gain] == clm.PARAM_DEFAULTS[gain]
        a.param(gain).check(defaults[gain])  # the default is inside the range
    # every sweepable parameter is a scenario parameter (params_batch accepts it)
    extra = {"distance_jitter", "yaw_jitter", "mu_jitter"}
    assert {p.name for p in a.params if p.sweepable} - extra <= set(scenarios.PARAM_DEFAULTS)
    assert a.statuses == ("ok", "failed", "diverged", "tipped")


def _doc(**changes):
    doc = {"sweep": {"analysis": NAME}, "fixed": {"horizon": 2.0}, "params": {"height": [0.2, 0.4]}}
    for section, values in changes.items():
        doc.setdefault(section, {}).update(values)
    return doc


@pytest.mark.parametrize("changes, message", [
    ({"params": {"T1": [1.0]}}, "params.T1: unknown parameter 'T1' for analysis 'octopus.step_climb'"),
    ({"params": {"height": [0.2, 0.7]}}, "params.height[1]: 0.7 m is outside [0, 0.6]"),
    ({"params": {"delta_e": [0.0]}}, "params.delta_e[0]: 0 rad/period is outside [0.0005, 0.05]"),
    ({"fixed": {"kind": "step3"}}, "fixed.kind: 'step3' is not one of 'step1', 'step2_front', 'step2_side'"),
    ({"fixed": {"controller": "pid"}}, "fixed.controller: 'pid' is not one of 'clm', 'ccm'"),
    ({"fixed": {"backend": "gpu"}}, "fixed.backend: 'gpu' is not one of 'native', 'mjx', 'auto'"),
    ({"params": {"kind": ["step1"]}}, "params.kind: 'kind' cannot be swept (it changes the compiled program)"),
    ({"params": {"nthread": [1, 2]}}, "params.nthread: 'nthread' cannot be swept"),
])
def test_spec_errors_are_one_line(changes, message):
    with pytest.raises(SpecError) as info:
        spec_from_dict(_doc(**changes))
    text = str(info.value)
    assert text.startswith("<dict>: " + message), text
    assert "\n" not in text


def test_valid_spec_expands():
    spec = spec_from_dict(_doc(params={"delta_f": [0.01, 0.02]}, sweep={"seeds": [0, 1]}))
    assert spec.analysis is sim_analysis.STEP_CLIMB


def test_jitter_is_per_seed_and_bounded():
    """The perturbed trials' draws (`seed_jitter`, shared with the leg-grope analysis):
    pure per key, in [-1, 1)."""
    from jaxloco.sim.scenario import seed_jitter

    keys = np.array([[0, 0], [0, 1], [0, 0]], np.uint32)
    u = seed_jitter(keys, 3)
    assert u.shape == (3, 3) and (np.abs(u) <= 1.0).all()
    np.testing.assert_array_equal(u[0], u[2])
    assert not np.allclose(u[0], u[1])


def _spec(tmp_path):
    return {
        "sweep": {"analysis": NAME, "name": "t", "chunk_size": 2, "output": str(tmp_path / "out"),
                  "formats": ["parquet"]},
        "fixed": {"horizon": 2.0, "nthread": 1},
        "params": {"height": [0.2, 0.4], "delta_e": [0.006, 0.01]},
    }


def test_tiny_sweep_runs_and_resumes(tmp_path):
    full, compiles = run_counting(run_sweep, _spec(tmp_path), progress=False, output=tmp_path / "full")
    compiles.assert_compiled_once()  # two chunks of two simulations, the controller compiled once
    t = full.table
    assert t.num_rows == 4
    col = {n: t.column(n).to_numpy(zero_copy_only=False) for n in t.column_names}
    # 2 s on the floor before the step: not over it, standing stable, nothing diverged
    assert (col["status"] == "failed").all()
    assert not col["success"].any() and not col["tipped"].any()
    for name in ("min_margin", "max_pitch", "max_abs_roll", "final_x", "final_z", "shortfall"):
        assert np.isfinite(col[name]).all(), name
    assert (col["min_margin"] > 0.0).all() and (col["shortfall"] > 0.3).all()
    assert np.isnan(col["climb_time"]).all() and np.isnan(col["t_diverged"]).all()
    assert (col["final_phase"] == clm.PHASE_NAMES.index("walk")).all()
    assert full.summary is not None and full.summary_error is None
    blocks = [row[0] for row in full.summary.rows]
    assert blocks.count("height") == 2 and blocks.count("delta_e") == 2
    assert full.summary.title == "OCTOPUS CLM getting over a step (step1, native MuJoCo)"

    def stop(index, n):
        raise KeyboardInterrupt

    with pytest.raises(SweepInterrupted):
        run_sweep(_spec(tmp_path), progress=False, on_chunk=stop)
    resumed = run_sweep(_spec(tmp_path), progress=False, resume=True)
    assert resumed.chunks_reused == 1 and resumed.chunks_computed == 1
    for name in ("max_abs_roll", "min_margin", "final_x", "status", "height", "delta_e"):
        np.testing.assert_array_equal(resumed.table.column(name).to_numpy(zero_copy_only=False),
                                      full.table.column(name).to_numpy(zero_copy_only=False))


def test_a_diverged_run_has_no_shortfall():
    """A run whose simulation diverged reports no shortfall (nan): its COG flies off or
    falls through the floor, so how near it came to the success line means nothing (in a
    192-climb search the diverged runs read 0 m short). Its success is False, its status
    "diverged"; a run that did not diverge keeps its shortfall."""
    result = SimpleNamespace(
        metrics={"success": np.array([1.0, 0.0]), "tipped": np.array([0.0, 0.0]),
                 "shortfall": np.array([0.0, 0.42]), "min_margin": np.array([0.1, 0.2])},
        records={"phase": np.zeros((2, 3))}, diverged=np.array([True, False]),
        t_diverged=np.array([12.0, np.nan]), status=["ok", "failed"])
    out = sim_analysis.metrics({}, result)
    assert np.isnan(out["shortfall"][0]) and out["shortfall"][1] == 0.42
    assert list(out["success"]) == [False, False]
    assert [sim_analysis.STATUSES[k] for k in out["status"]] == ["diverged", "failed"]
