"""`titan.walk`: planned walks on exact and surveyed maps executed in
MuJoCo, as a sweep analysis. One batch of short walks on the Sec. 7 grid (0.2 m frames
on 2.0 m), planned on the exact map and on a survey with 5 mm noise."""

from __future__ import annotations

import numpy as np
import pytest

from jaxloco.analysis import get
from jaxloco.errors import SpecError
from jaxloco.robots.titan import params, sim_analysis, walk

N_CYCLES = 2


@pytest.fixture(scope="module")
def rows():
    analysis = get("titan.walk")
    fixed = {**analysis.defaults(), "n_cycles": N_CYCLES, "nthread": 2}
    batch = analysis.batch_fn(fixed)
    swept = {"map": np.array(["exact", "survey"]), "start_jitter": np.array([0.0, 0.3])}
    keys = np.array([[0, 1], [0, 2]], np.uint32)
    return batch(swept, keys)


def test_grid_field_beams_match_the_planning_map():
    # an even count of beams each way centred on the origin: centre lines at
    # +-spacing/2, +-3 spacing/2, ... as walk.sim_map's, covering the walk's map
    for spacing in (1.5, 2.0, 3.0):
        field = sim_analysis.grid_field(spacing)
        assert field.n_along % 2 == 0 and field.n_along == field.n_across
        assert 0.5 * (field.n_along - 1) * spacing >= sim_analysis.GRID_HALF
    assert sim_analysis.grid_shape(N_CYCLES) == walk.SIM_SHAPE
    assert sim_analysis.grid_shape(12)[0] * float(params.CELL) > 12 + 2 * sim_analysis.ROBOT_REACH


def test_planned_walks_hold_up_in_mujoco(rows):
    # both maps: every cycle planned, the walk executed without a fall, no foot on a
    # frame, the NE margin kept at S_NE^c (no allowance), about the
    # planned distance
    assert list(rows["status"]) == [0, 0], rows
    assert rows["success"].all() and rows["planned"].all()
    assert not rows["feet_on_frames"].any() and not rows["swing_collision"].any()
    assert (rows["sim_min_nesm"] >= params.S_NE_C).all()
    assert (rows["plan_min_nesm"] >= params.S_NE_C - 1e-9).all()
    assert (np.abs(rows["sim_min_nesm"] - rows["plan_min_nesm"]) < 0.002).all()
    assert (rows["max_touchdown_error"] < 0.05).all()
    assert (rows["distance"] > 0.7 * N_CYCLES).all()


def test_the_long_field_is_surveyed_and_walked_along_x():
    batch = get("titan.walk").batch_fn({**get("titan.walk").defaults(), "n_cycles": 1})
    with pytest.raises(SpecError, match="long field"):
        batch({"field": np.array(["long"]), "map": np.array(["exact"])}, np.zeros((1, 2), np.uint32))
    with pytest.raises(SpecError, match="walked along"):
        batch({"field": np.array(["long"]), "direction": np.array([0.5])}, np.zeros((1, 2), np.uint32))
