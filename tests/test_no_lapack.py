"""No JAX analysis emits a LAPACK call on the CPU, which is why a sweep's compiled call
takes the whole chunk (no rows-per-call cap): jaxlib 0.10's batched LAPACK kernels were
seen to deadlock XLA's CPU thread pool at ~1,000 small factorizations per call. Each
JAX analysis' batch function is lowered (not compiled) as a sweep would call it, and its
program is searched for LAPACK custom calls (`jaxloco.linalg` has the small solves)."""

from __future__ import annotations

import pytest

from jaxloco import analysis
from jaxloco.sweep import chunks, spec_from_dict

SMALL = {  # cheap-to-trace settings; every analysis with executor "jax" must appear here
    "leggrope.slope_cycle": ({"n_move": 10, "n_unload": 4, "n_swing": 6, "n_load": 4}, {"theta": [0.1, 0.2]}),
    "octopus.terrain_classification": ({"samples": 8}, {"height": [0.2, 0.3]}),
    "snake.kv": ({"horizon": 0.2, "dt": 0.02}, {"k_eta": [0.1, 0.2]}),
    "titan.stride": ({"n_cycles": 1, "map_nx": 60, "map_ny": 60}, {"l_std": [0.5, 0.6]}),
}


def test_every_jax_analysis_is_listed():
    jax_analyses = {name for name in analysis.names() if analysis.get(name).executor == "jax"}
    builtin = {name for name in jax_analyses if analysis.is_builtin(name)}
    assert builtin == set(SMALL)


@pytest.mark.parametrize("name", sorted(SMALL))
def test_batch_program_has_no_lapack_call(name):
    fixed, params = SMALL[name]
    spec = spec_from_dict({"sweep": {"analysis": name, "name": "lapack", "chunk_size": 2},
                           "fixed": fixed, "params": params})
    prepared = chunks.prepare(spec)
    swept, seed_pos = prepared.grid.rows(0, 2)
    text = prepared.fn.lower(*chunks.call_args(prepared, swept, seed_pos, 2)).as_text().lower()
    assert "lapack" not in text
