"""`octopus.paper` (jaxloco/robots/octopus/paper_analysis.py): the paper's experiments as
one sweep with a string `task` column. A tiny sweep (2 s runs) checks that rows of mixed
tasks run on their own terrain and controller and land in grid order, that the
perturbations come from the seeds, and that the summary puts the paper's numbers beside
ours; the bundled spec is the paper's 5 tasks x 20 runs on the paper's method."""

from __future__ import annotations

import numpy as np
import pyarrow as pa
import pytest
from compile_count import run_counting

from jaxloco import specs
from jaxloco.robots.octopus import paper_analysis
from jaxloco.sweep import load_spec, run


def test_bundled_spec_is_the_papers_five_tasks_times_20_on_the_papers_method():
    spec = load_spec(specs.path("octopus_paper"))
    assert spec.analysis is paper_analysis.PAPER_EXPERIMENTS
    assert tuple(spec.swept["task"]) == paper_analysis.TASK_NAMES and len(spec.seeds) == 20
    assert spec.n_rows == 100
    # the paper's method: Eqs. 28-29, never CRAWL, no operator; the paper's perturbations
    assert spec.fixed["climb_paper"] == 1.0 and spec.fixed["crawl_max_h"] == 0.0
    assert spec.fixed["operator_gain"] == 0.0
    assert (spec.fixed["distance_jitter"], spec.fixed["yaw_jitter"], spec.fixed["mu_jitter"]) == (0.1, 0.05, 0.2)
    assert set(paper_analysis.PAPER) == set(paper_analysis.TASK_NAMES)


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """Two tasks x two seeds in chunks of 3 and 1 rows: (result, lowerings)."""
    out = tmp_path_factory.mktemp("paper")
    doc = {"sweep": {"analysis": "octopus.paper", "name": "tiny", "chunk_size": 3, "seeds": [0, 1],
                     "output": str(out), "formats": ["parquet"]},
           "fixed": {"horizon": 1.0}, "params": {"task": ["block", "step1_ccm"]}}
    return run_counting(run, doc, progress=False)


@pytest.fixture(scope="module")
def tiny(tiny_run):
    return tiny_run[0]


def test_a_two_chunk_sweep_compiles_once(tiny_run):
    tiny_run[1].assert_compiled_once()  # chunk 2 runs step1_ccm again, compiled in chunk 1


def test_mixed_tasks_run_on_their_own_terrain_and_controller(tiny):
    t = tiny.table
    tasks = t.column("task").to_pylist()
    assert tasks == ["block", "block", "step1_ccm", "step1_ccm"]  # grid order, seeds inner
    assert t.column("seed").to_pylist() == [0, 1, 0, 1]
    phase = np.asarray(t.column("final_phase"))
    # CLM on the block walks (phase 0 = walk); CCM approaches (its phase 0 = approach):
    # both are controller phases, never -1
    assert (phase >= 0).all()
    margin = np.asarray(t.column("min_margin"))
    assert np.isfinite(margin).all()
    # the seeds perturb the start: the two block runs differ
    assert not np.isclose(np.asarray(t.column("final_x"))[0], np.asarray(t.column("final_x"))[1])


def test_summary_puts_the_papers_numbers_beside_ours(tiny):
    s = tiny.summary
    assert [r[0] for r in s.rows] == ["step1_ccm", "block"]  # TASK_NAMES order
    ccm = dict(zip(s.columns, s.rows[0]))
    assert ccm["success / paper"] == "0/2 / 0%"
    assert ccm["max |roll| / paper"].endswith("/ 0.14")
    # how the failures end, and how near the COG came to the success line
    short = np.asarray(tiny.table.column("shortfall"))[2:]
    assert ccm["failures"] == f"2 stuck; {short.mean():.2f} ({short.min():.2f}) m short"
    assert (short > 0.5).all()  # 1 s of driving from 0.6-0.8 m before the riser, the line 0.3 m beyond it
    assert "Eqs. 28-29" in s.title


def _table(tasks, success, climb_paper=1.0):
    """A stand-in sweep table of `tasks` rows with the columns `summarize` reads."""
    n = len(tasks)
    return pa.table({"task": tasks, "status": ["ok" if s else "failed" for s in success], "success": success,
                     "climb_time": [10.0 if s else np.nan for s in success], "max_pitch": [0.5] * n,
                     "max_abs_roll": [0.1] * n, "min_margin": [0.05] * n,
                     "shortfall": [0.0 if s else 0.6 for s in success],
                     "climb_paper": [climb_paper] * n, "crawl_max_h": [0.0] * n})


def test_summary_points_to_why_when_the_papers_climb_gets_over_nothing():
    assert paper_analysis.CLIMB_TASKS == ("step1_clm", "step2_front", "step2_side")
    tasks = ["step1_clm", "step2_front", "block", "step1_ccm"]

    def pointed(success, climb_paper=1.0):
        notes = paper_analysis.summarize(_table(tasks, success, climb_paper)).notes
        return any("octopus_low_steps" in n and "It does not climb yet" in n for n in notes)

    assert pointed([False, False, True, False])  # the block and the CCM do not count
    assert not pointed([False, True, True, False])  # one climb got over
    assert not pointed([False, False, True, False], climb_paper=0.0)  # our level lift: not the paper's climb
    assert not paper_analysis.summarize(_table(["block"], [False])).notes[1:]  # no climbing task run


def test_task_values_and_perturbations():
    assert paper_analysis.task_values("step2_side") == {"kind": "step2_side", "controller": "clm", "height": 0.4,
                                            "side_ratio": 0.5}
    p = paper_analysis.perturbations(50, seed=3)
    assert (p["distance"] >= 0.6).all() and (p["distance"] <= 0.8).all() and np.ptp(p["mu"]) > 0.2
