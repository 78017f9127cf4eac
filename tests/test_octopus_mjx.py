"""`octopus.step_climb` and `octopus.paper` on MJX (`backend = "mjx"`): the same model as on
native MuJoCo (MJX has everything it uses), so a tiny sweep on each backend over the
same rows, the first seconds of the CLM step climb (the walk towards the 400 mm step:
crawlers driving, support arms holding their rollers on the ground, the RR arm's first
transfer), agree within `TOL` (the table in docs/simulation.md). The MJX sweep compiles
its rollout once, for its first chunk, and `octopus.paper`'s CLM row runs on that
compiled program too: one MJX compile in this module (1-2 minutes of its time cold).

Oracle: MuJoCo's C code (the native backend) on the same rows."""

from __future__ import annotations

import numpy as np
import pytest
from compile_count import LOWERING_EVENT, LoweringsPerChunk, compile_events

from jaxloco.robots.octopus import clm
from jaxloco.sweep import run

HORIZON = 1.0  # [s] simulated per row
SPEEDS = [0.03, 0.063]  # [m/s] clm_speed of the two rows (the default and the crawlers' top speed)
# |native - mjx| allowed per metric (measured at most: docs/simulation.md, "OCTOPUS")
TOL = {"final_x": 1e-3, "final_z": 1e-4, "max_pitch": 1e-3, "max_abs_roll": 1e-3, "min_margin": 1e-3}
EXACT = ("success", "tipped", "arm_over_obstacle", "final_phase", "status")


def _spec(out, backend: str, chunk_size: int) -> dict:
    return {"sweep": {"analysis": "octopus.step_climb", "name": backend, "chunk_size": chunk_size,
                      "output": str(out / backend), "formats": ["parquet"]},
            "fixed": {"horizon": HORIZON, "nthread": 1, "backend": backend},
            "params": {"clm_speed": SPEEDS}}


@pytest.fixture(scope="module")
def sweeps(tmp_path_factory):
    """The two rows on each backend: {"native": result, "mjx": result}, and the MJX
    sweep's lowerings per chunk (one row per chunk)."""
    out = tmp_path_factory.mktemp("octopus_mjx")
    native = run(_spec(out, "native", 2), progress=False)
    with compile_events() as events:
        counter = LoweringsPerChunk(events)
        mjx = run(_spec(out, "mjx", 1), progress=False, on_chunk=counter.on_chunk)
    return {"native": native, "mjx": mjx}, counter


def _columns(result) -> dict[str, np.ndarray]:
    t = result.table
    return {n: t.column(n).to_numpy(zero_copy_only=False) for n in t.column_names}


@pytest.mark.slow  # an MJX compile of the OCTOPUS loop: start it first
def test_a_sweep_runs_on_mjx_end_to_end_and_compiles_once(sweeps):
    results, counter = sweeps
    counter.assert_compiled_once()
    col = _columns(results["mjx"])
    assert list(col["backend"]) == ["mjx", "mjx"]
    assert results["mjx"].summary.title == "OCTOPUS CLM getting over a step (step1, MJX)"
    assert list(col["status"]) == ["failed", "failed"]  # 1 s: still on the floor, walking
    assert (col["final_phase"] == clm.WALK).all()
    assert col["final_x"][1] > 1.5 * col["final_x"][0] > 0.0  # the faster row drove farther


@pytest.mark.slow  # an MJX compile of the OCTOPUS loop: start it first
def test_native_and_mjx_agree_on_the_same_rows(sweeps):
    results, _ = sweeps
    native, mjx = _columns(results["native"]), _columns(results["mjx"])
    assert list(native["backend"]) == ["native", "native"]
    np.testing.assert_array_equal(native["clm_speed"], mjx["clm_speed"])
    for name in EXACT:
        np.testing.assert_array_equal(native[name], mjx[name], err_msg=name)
    assert np.isnan(native["climb_time"]).all() and np.isnan(mjx["climb_time"]).all()
    for name, tol in TOL.items():
        diff = np.abs(native[name] - mjx[name])
        assert (diff <= tol).all(), (name, diff)


@pytest.mark.slow  # an MJX compile of the OCTOPUS loop: start it first
def test_the_paper_analysis_runs_its_clm_row_on_the_compiled_rollout(sweeps, tmp_path):
    """`octopus.paper` simulates a task's rows as `octopus.step_climb` rows: its 400 mm CLM
    row, unperturbed, is the step_climb sweep's first row, run by the same compiled program."""
    results, _ = sweeps
    doc = {"sweep": {"analysis": "octopus.paper", "name": "paper", "chunk_size": 1, "output": str(tmp_path),
                     "formats": ["parquet"]},
           "fixed": {"horizon": HORIZON, "nthread": 1, "backend": "mjx", "distance_jitter": 0.0,
                     "yaw_jitter": 0.0, "mu_jitter": 0.0, "clm_speed": SPEEDS[0]},
           "params": {"task": ["step1_clm"]}}
    with compile_events() as events:
        paper = run(doc, progress=False)
    assert events.count(LOWERING_EVENT) == 0
    col, step = _columns(paper), _columns(results["mjx"])
    assert list(col["backend"]) == ["mjx"]
    for name in ("final_x", "final_z", "max_pitch", "max_abs_roll", "min_margin", "final_phase", "status"):
        np.testing.assert_array_equal(col[name], step[name][:1], err_msg=name)
