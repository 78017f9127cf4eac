"""Test session setup: float64 available (float32 is tested with explicit dtypes) and
JAX's persistent compilation cache outside the repository, so later runs compile less.

The suite runs on pytest-xdist workers (`-n auto --dist loadgroup`, pyproject.toml): a
module is one unit of work (its tests share module fixtures and compile their programs
once, on one worker) unless a test names its own `xdist_group` (the notebooks, each run in
its own kernel); units with `slow` tests are handed out first so that the workers finish
together. `-n auto` means one worker per core, at most MAX_WORKERS (each holds its own JAX
and its compiled programs). Each module's compiled programs are dropped from JAX's
in-memory caches when the module ends (they stay in the persistent cache): holding every
executable of ~700 tests in one process made a later cache write abort.

MuJoCo's warnings (an unstable simulation, ...) go to the session's temporary directory,
not to MUJOCO_LOG.TXT in the working directory (the repository)."""

import os

import jax
import mujoco
import pytest

from jaxloco import runtime

runtime.configure(x64=True, cache_dir=True)

MAX_WORKERS = 4


def pytest_xdist_auto_num_workers(config):
    """`-n auto`: one worker per core, at most MAX_WORKERS."""
    return max(1, min(os.cpu_count() or 1, MAX_WORKERS))


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """Every test without an `xdist_group` mark joins its module's group (one unit of work
    for --dist loadgroup); units holding `slow` tests come first, in collection order."""
    for item in items:
        if item.get_closest_marker("xdist_group") is None:
            item.add_marker(pytest.mark.xdist_group(item.nodeid.split("::", 1)[0]))
    slow_units = {_unit(item) for item in items if item.get_closest_marker("slow") is not None}
    items.sort(key=lambda item: _unit(item) not in slow_units)  # stable: collection order otherwise


def _unit(item) -> str:
    marker = item.get_closest_marker("xdist_group")
    return marker.kwargs.get("name") or (marker.args[0] if marker.args else "")


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
