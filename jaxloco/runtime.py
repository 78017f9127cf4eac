"""Process-level JAX settings that an application (CLI, tests, notebooks) opts into.

Nothing in the kernels calls this: precision and caching are chosen by the caller,
once, before the first computation. `configure()` is idempotent. `single_thread_lapack()`
is for forward-mode MJX gradients on CPU (the robots' `mjx_tuning` objectives call it).
"""

from __future__ import annotations

import functools
import os
from dataclasses import dataclass
from pathlib import Path

ENV_CACHE_DIR = "JAXLOCO_CACHE_DIR"


def default_cache_dir() -> Path:
    """Where JAX's persistent compilation cache lives (outside any repository).

    `$JAXLOCO_CACHE_DIR`, else `$XDG_CACHE_HOME/jaxloco/jax`, else `~/.cache/jaxloco/jax`.
    """
    env = os.environ.get(ENV_CACHE_DIR)
    if env:
        return Path(env).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg).expanduser() if xdg else Path.home() / ".cache"
    return base / "jaxloco" / "jax"


ENV_PROGRAM_CACHE = "JAXLOCO_PROGRAM_CACHE"
PROGRAM_CACHE_SUFFIX = "-programs"


def program_cache_dir(compilation_cache: str | Path | None) -> Path | None:
    """Where traced programs are kept (`jaxloco.sim.programs`), given JAX's compilation
    cache directory (None: off): `$JAXLOCO_PROGRAM_CACHE` if it names a directory ("0",
    "off", "false" or "no": off), else `<compilation cache>-programs` beside it."""
    env = os.environ.get(ENV_PROGRAM_CACHE, "").strip()
    if env.lower() in ("0", "false", "no", "off"):
        return None
    if env and env.lower() not in ("1", "true", "yes", "on"):
        return Path(env).expanduser()
    if not compilation_cache:
        return None
    path = Path(compilation_cache)
    return path.with_name(path.name + PROGRAM_CACHE_SUFFIX)


@dataclass(frozen=True)
class RuntimeSettings:
    x64: bool
    cache_dir: Path | None


def configure(
    *, x64: bool = True, cache_dir: str | Path | None | bool = True, cpu_devices: int | None = None
) -> RuntimeSettings:
    """Set float64 on/off, the persistent compilation cache and the number of host CPU
    devices.

    cache_dir: True -> `default_cache_dir()`; False/None -> leave the cache off;
    a path -> use it. Compiled programs of any compile time are cached.
    cpu_devices: how many JAX CPU devices to expose (default: `$JAXLOCO_CPU_DEVICES` or
    the number of cores), so that a batch sharded over them runs on every core. It only
    takes effect before JAX's backend starts (the first computation); later it is left.
    """
    import jax

    jax.config.update("jax_enable_x64", bool(x64))
    use_cpu_cores(cpu_devices)
    path: Path | None = None
    if cache_dir is True:
        path = default_cache_dir()
    elif cache_dir:
        path = Path(cache_dir).expanduser()
    if path is not None:
        path.mkdir(parents=True, exist_ok=True)
        jax.config.update("jax_compilation_cache_dir", str(path))
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
        jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    return RuntimeSettings(x64=bool(x64), cache_dir=path)


def use_cpu_cores(n: int | None = None) -> None:
    """Expose `n` JAX CPU devices (default `$JAXLOCO_CPU_DEVICES` or the core count) so a
    batch sharded over them uses every core. No effect once JAX's backend has started."""
    import jax

    n = n or int(os.environ.get("JAXLOCO_CPU_DEVICES", 0)) or (os.cpu_count() or 1)
    try:
        jax.config.update("jax_num_cpu_devices", int(n))
    except RuntimeError:  # backend already initialized: keep what it has
        pass


def current_settings() -> RuntimeSettings:
    """What JAX is set to now (float64 flag, compilation cache directory or None)."""
    import jax

    cache = jax.config.jax_compilation_cache_dir
    return RuntimeSettings(x64=bool(jax.config.jax_enable_x64), cache_dir=Path(cache) if cache else None)


@functools.cache
def single_thread_lapack() -> bool:
    """Run the LAPACK calls of JAX on CPU (scipy's OpenBLAS) on one thread, unless
    OPENBLAS_NUM_THREADS is set; True if it did. MJX's tangent dynamics call small
    Cholesky and triangular solves every physics step, and OpenBLAS's worker threads
    spin-wait for a core: on 2 busy cores a forward-mode rollout ran 2x (load 3) to
    ~50x (load 8) slower with them. Process-wide; without scipy's OpenBLAS, nothing."""
    import ctypes
    import glob
    import os

    if "OPENBLAS_NUM_THREADS" in os.environ:
        return False
    try:
        import scipy.linalg.cython_lapack  # loads the library that JAX calls
    except ImportError:
        return False
    import scipy

    for path in sorted(glob.glob(os.path.join(os.path.dirname(scipy.__file__) + ".libs", "libscipy_openblas*"))):
        try:
            lib = ctypes.CDLL(path)
            lib.scipy_openblas_set_num_threads(ctypes.c_int(1))
            return True
        except (OSError, AttributeError):
            continue
    return False
