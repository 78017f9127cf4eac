"""Test session setup: float64 available (float32 is tested with explicit dtypes) and
JAX's persistent compilation cache outside the repository, so later runs compile less.

Each test module's compiled programs are dropped from JAX's in-memory caches when the
module ends (they stay in the persistent cache): one process runs the whole suite, and
holding every executable of ~600 tests made a later cache write abort.

MuJoCo's warnings (an unstable simulation, ...) go to the session's temporary directory,
not to MUJOCO_LOG.TXT in the working directory (the repository)."""

import jax
import mujoco
import pytest

from jaxloco import runtime

runtime.configure(x64=True, cache_dir=True)


@pytest.fixture(autouse=True, scope="module")
def _drop_compiled_programs():
    yield
    jax.clear_caches()


@pytest.fixture(autouse=True, scope="session")
def _mujoco_log_outside_the_repository(tmp_path_factory):
    """MuJoCo's log file (MUJOCO_LOG.TXT, by default in the working directory) in a
    temporary directory for the session."""
    config = mujoco.MjLogConfig.get()
    saved = config.logfile
    config.logfile = str(tmp_path_factory.mktemp("mujoco") / "MUJOCO_LOG.TXT")
    config.set()
    yield
    config.logfile = saved
    config.set()
