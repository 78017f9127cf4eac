"""Test session setup: float64 available (float32 is tested with explicit dtypes) and
JAX's persistent compilation cache outside the repository, so later runs compile less.

The suite runs on pytest-xdist workers (`-n auto --dist loadscope`, pyproject.toml): a
module is one unit of work (its tests share module fixtures and compile their programs
once, on one worker), a test class one of its own (the notebooks: one class each, each
run in its own kernel); units with `slow` tests are handed out first so that the workers
finish together. `-n auto` means one worker per core, at most MAX_WORKERS (each holds its own JAX
and its compiled programs). Each module's compiled programs are dropped from JAX's
in-memory caches when the module ends (they stay in the persistent cache): holding every
executable of ~700 tests in one process made a later cache write abort.

MuJoCo's warnings (an unstable simulation, ...) go to the session's temporary directory,
not to MUJOCO_LOG.TXT in the working directory (the repository)."""

import os

# LLVM's backend optimisations off for the suite's programs (and for the notebook kernels,
# which inherit the environment): XLA's graph passes still run, so the programs compute
# the same, and compiling them (most of a run with an empty cache) takes about a fifth
# less. Users' runs keep the full optimisation; the cache keeps the two apart.
_FAST_COMPILE = os.environ.setdefault("JAX_DISABLE_MOST_OPTIMIZATIONS", "1").lower() not in ("0", "false", "")

# XLA's legacy LLVM IR emitters (`runtime.FAST_XLA_CPU_FLAGS`, which `runtime.configure`
# also sets for users' runs), here in the environment before JAX starts, so that the
# notebook kernels and the suite's subprocesses inherit them. A flag already in
# $XLA_FLAGS wins.
from jaxloco.runtime import FAST_XLA_CPU_FLAGS, with_xla_flags  # noqa: E402  (imports no JAX)

if _FAST_COMPILE:
    os.environ["XLA_FLAGS"] = with_xla_flags(os.environ.get("XLA_FLAGS", ""), FAST_XLA_CPU_FLAGS)

import jax  # noqa: E402
import mujoco  # noqa: E402
import pytest  # noqa: E402

from jaxloco import runtime  # noqa: E402

runtime.configure(x64=True, cache_dir=True)
jax.config.update("jax_disable_most_optimizations", _FAST_COMPILE)  # also if a plugin imported JAX first

MAX_WORKERS = 4


def pytest_xdist_auto_num_workers(config):
    """`-n auto`: one worker per core, at most MAX_WORKERS."""
    return max(1, min(os.cpu_count() or 1, MAX_WORKERS))


def pytest_collection_modifyitems(config, items):
    """Units of work (--dist loadscope: a module, or a class) holding `slow` tests first,
    in collection order otherwise (pyproject.toml passes --no-loadscope-reorder)."""
    slow_units = {_unit(item) for item in items if item.get_closest_marker("slow") is not None}
    items.sort(key=lambda item: _unit(item) not in slow_units)  # a stable sort


def _unit(item) -> str:
    """The test's loadscope unit: `path::Class` for a method, `path` for a function."""
    return item.nodeid.rsplit("::", 1)[0] if item.cls is not None else item.nodeid.split("::", 1)[0]


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
