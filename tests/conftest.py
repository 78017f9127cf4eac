"""Test session setup: float64 available (float32 is tested with explicit dtypes) and
JAX's persistent compilation cache outside the repository, so later runs compile less.

Each test module's compiled programs are dropped from JAX's in-memory caches when the
module ends (they stay in the persistent cache): one process runs the whole suite, and
holding every executable of ~600 tests made a later cache write abort."""

import jax
import pytest

from jaxloco import runtime

runtime.configure(x64=True, cache_dir=True)


@pytest.fixture(autouse=True, scope="module")
def _drop_compiled_programs():
    yield
    jax.clear_caches()
