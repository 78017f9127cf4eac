"""A sweep compiles each analysis' programs for its first chunk and reuses them for the
next chunk of the same shape (no tracing or lowering after chunk 0). The analyses whose
own test modules already run a two-chunk sweep check it there (leggrope.slope_cycle,
leggrope.fragile_walk, octopus.terrain_classification, octopus.step_climb,
octopus.paper, snake.operations); the others run here on tiny settings: two rows, one per chunk. Every
one of these sweeps' tables is also pinned (`tables.check_table`, via `run_counting`)."""

from __future__ import annotations

import pytest
from compile_count import run_counting

from jaxloco import analysis
from jaxloco.sweep import run

# checked in their own test modules (see the docstring)
ELSEWHERE = {"leggrope.slope_cycle", "leggrope.fragile_walk", "octopus.terrain_classification",
             "octopus.step_climb", "octopus.paper", "snake.operations"}

TINY = {
    "titan.stride": ({"n_cycles": 1, "map_nx": 60, "map_ny": 60}, {"l_std": [0.5, 0.6]}),
    "titan.walk": ({"n_cycles": 1, "nthread": 1}, {"direction": [0.0, 0.1]}),
    "snake.kv": ({"horizon": 0.2, "dt": 0.02}, {"k_eta": [0.1, 0.2]}),
    "snake.reach": ({"horizon": 0.3, "ramp": 0.1, "settle": 0.1, "nthread": 1}, {"gain_k": [1.0, 0.9]}),
    "snake.table3": ({"ramp": 0.5, "settle": 0.1, "nthread": 1}, {"target": ["z", "beta"]}),
    # first a posture no other test computes: `contact.head_posture` is cached per posture, so a posture another test
    # module ran first in this process (test_snake_mjx's "ii") would leave its programs to the second chunk
    "snake.contact": ({"ramp": 0.5, "hold": 0.1, "settle": 0.1, "nthread": 1}, {"posture": ["iv", "v"]}),
}


@pytest.mark.parametrize("name", sorted(TINY))
def test_the_second_chunk_compiles_nothing(name, tmp_path):
    fixed, params = TINY[name]
    spec = {"sweep": {"analysis": name, "name": "once", "chunk_size": 1, "formats": ["parquet"]},
            "fixed": fixed, "params": params}
    result, compiles = run_counting(run, spec, output=tmp_path / "out", progress=False)
    assert result.table.num_rows == 2
    compiles.assert_compiled_once()


def test_every_analysis_has_a_compile_once_check():
    assert ELSEWHERE.isdisjoint(TINY)
    assert set(TINY) | ELSEWHERE == set(analysis.ANALYSES.builtin), "add the new analysis to TINY (or to ELSEWHERE)"
