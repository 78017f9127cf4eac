"""Versions and the JAX environment, for result tables and `jaxloco info`.

`versions()` and `static_environment()` are cheap (package metadata only, nothing
imported). `jax_environment()` (and `environment()`, both parts) imports JAX and, quietly,
`mujoco.mjx` to check that it loads.
"""

from __future__ import annotations

import contextlib
import io
import logging
import os
import sys
import warnings
from importlib import metadata
from pathlib import Path

import jaxloco
from jaxloco import runtime

PACKAGES = ("jax", "jaxlib", "mujoco", "mujoco-mjx")
LABEL_WIDTH = len("compilation cache now")  # the longest label: `jaxloco info` prints in two parts


def package_version(name: str) -> str:
    """The installed version of a distribution, or "not installed"."""
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return "not installed"


def versions() -> dict[str, str]:
    """jaxloco and its main dependencies (from package metadata; imports nothing)."""
    return {"jaxloco": jaxloco.__version__, **{name: package_version(name) for name in PACKAGES}}


@contextlib.contextmanager
def _silenced():
    """Swallow prints, warnings and log records, at the Python and the file-descriptor level."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved: list[tuple[int, int]] = []
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        for fd in (1, 2):
            try:
                saved.append((fd, os.dup(fd)))
                os.dup2(devnull, fd)
            except OSError:
                pass
        os.close(devnull)
    except OSError:
        pass
    previous = logging.root.manager.disable
    logging.disable(logging.CRITICAL)
    try:
        with (
            warnings.catch_warnings(),
            contextlib.redirect_stdout(io.StringIO()),
            contextlib.redirect_stderr(io.StringIO()),
        ):
            warnings.simplefilter("ignore")
            yield
    finally:
        logging.disable(previous)
        for fd, copy in saved:
            os.dup2(copy, fd)
            os.close(copy)


def mjx_status() -> str:
    """ "ok" when `mujoco.mjx` imports, else the reason (its import noise is silenced)."""
    try:
        with _silenced():
            import mujoco.mjx  # noqa: F401
    except Exception as exc:  # any failure to import is what we report
        return f"import failed: {type(exc).__name__}: {exc}"
    return "ok"


def environment() -> list[tuple[str, str]]:
    """(label, value) lines for `jaxloco info`: `static_environment()` then `jax_environment()`."""
    return static_environment() + jax_environment()


def static_environment() -> list[tuple[str, str]]:
    """The lines that need no JAX (versions, python, the compilation cache directory): cheap."""
    rows = [(name, version) for name, version in versions().items()]
    rows.append(("python", sys.version.split()[0]))
    numba = package_version("numba")
    rows.append(("qp kernel backend", "off: pip install 'jaxloco[kernel]'" if numba == "not installed"
                 else f"on (numba {numba}): qp.solve_batch(backend='kernel')"))
    cache = runtime.default_cache_dir()
    source = f" (from ${runtime.ENV_CACHE_DIR})" if os.environ.get(runtime.ENV_CACHE_DIR) else ""
    bound = _cache_bound()
    rows.append(("compilation cache", f"{cache}{source}, {_cache_state(cache, bound)}"))
    programs = runtime.program_cache_dir(cache)
    if programs is None:
        rows.append(("program cache", f"off (${runtime.ENV_PROGRAM_CACHE})"))
    else:
        rows.append(("program cache", f"{programs} (traced simulations), {_cache_state(programs, bound)}"))
    return rows


def _cache_bound() -> str:
    """'at most N MB' from `$JAXLOCO_CACHE_MAX_MB` (or its default), 'no bound', or what
    is wrong with the variable."""
    try:
        max_bytes = runtime.cache_max_bytes()
    except ValueError as err:
        return f"bound: {err}"
    return "no bound" if max_bytes is None else f"at most {max_bytes / 2**20:.0f} MB"


def _cache_state(path: Path, bound: str) -> str:
    if not path.is_dir():
        return f"not created yet ({bound})"
    return f"{runtime.directory_bytes(path) / 2**20:.0f} MB ({bound})"


def jax_environment() -> list[tuple[str, str]]:
    """The lines that import JAX (and, quietly, `mujoco.mjx`): backend, devices, float64."""
    import jax

    runtime.use_cpu_cores()  # report the devices a sweep will shard over
    rows = [("mujoco.mjx import", mjx_status())]
    rows.append(("jax backend", jax.default_backend()))
    rows.append(("jax devices", ", ".join(str(d) for d in jax.devices())))
    # Read the flags directly: `jax.config.read` refuses the compilation-cache flag.
    x64 = bool(jax.config.jax_enable_x64)
    rows.append(("float64 now", "on" if x64 else "off (sweeps switch it on for analyses with x64=True)"))
    current = jax.config.jax_compilation_cache_dir
    if current and Path(current) != runtime.default_cache_dir():
        rows.append(("compilation cache now", str(current)))
    return rows
