"""Process-level JAX settings that an application (CLI, tests, notebooks) opts into.

Nothing in the kernels calls this: precision and caching are chosen by the caller,
once, before the first computation. `configure()` is idempotent. `single_thread_lapack()`
is for forward-mode MJX gradients on CPU (the robots' `mjx_tuning` objectives call it).
"""

from __future__ import annotations

import functools
import importlib.metadata
import os
import re
import time
from dataclasses import dataclass
from pathlib import Path

from jaxloco.errors import SpecError

ENV_CACHE_DIR = "JAXLOCO_CACHE_DIR"
ENV_CACHE_MAX = "JAXLOCO_CACHE_MAX_MB"
# default (ours): each cache directory (compiled programs, traced programs) is kept below
# this many MB, the least recently used entries removed first; the suite's cache is
# ~250 MB + ~80 MB, a sweep adds one or two programs of 0.5-5 MB
DEFAULT_CACHE_MAX_MB = 4096


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


def cache_max_bytes() -> int | None:
    """The size bound [bytes] of each cache directory (JAX's compilation cache, the
    program cache): `$JAXLOCO_CACHE_MAX_MB` megabytes (-1: unbounded, None), default
    `DEFAULT_CACHE_MAX_MB`. A value that is not a positive number or -1 is a SpecError."""
    raw = os.environ.get(ENV_CACHE_MAX, "").strip()
    if not raw:
        return DEFAULT_CACHE_MAX_MB * 2**20
    try:
        mb = float(raw)
    except ValueError:
        mb = float("nan")
    if mb == -1:
        return None
    if not mb > 0 or mb == float("inf"):
        raise SpecError(f"${ENV_CACHE_MAX}: expected a size in MB (> 0, or -1 for no bound), got {raw!r}")
    return int(mb * 2**20)


def directory_bytes(path: Path) -> int:
    """Total size [bytes] of the files under `path` (0 if it does not exist)."""
    total = 0
    for f in path.rglob("*") if path.is_dir() else ():
        try:
            total += f.stat().st_size if f.is_file() else 0
        except OSError:  # removed meanwhile by another process
            pass
    return total


STALE_TMP_S = 3600.0  # [s] a temporary file this old is a crashed writer's, not a live one's
JAX_CACHE_SUFFIX = "-cache"  # the entries of JAX's compilation cache
PROGRAM_SUFFIX = ".bin"  # the entries of the program cache (`jaxloco.sim.programs`)
TMP_SUFFIX = ".tmp"  # its files being written


def prune_cache(root: Path, max_bytes: int | None, *, suffix: str, tmp_suffix: str | None = None,
                now: float | None = None) -> list[Path]:
    """Remove the oldest entries (files named `*{suffix}`; nothing else in `root` is
    touched) of a cache directory by modification time (JAX's compilation cache writes
    an entry once; the program cache touches a file it loads, so there it is the least
    recently used) until they take at most `max_bytes` (None: no bound), and the
    `*{tmp_suffix}` files older than `STALE_TMP_S` (writers that died). Returns the
    removed paths. Safe beside other processes: a file removed meanwhile is skipped, and
    a reader whose entry is gone compiles or traces it again."""
    now = time.time() if now is None else now
    entries, removed = [], []
    for f in root.iterdir() if root.is_dir() else ():
        is_tmp = tmp_suffix is not None and f.name.endswith(tmp_suffix)
        if not (is_tmp or f.name.endswith(suffix)):
            continue
        try:
            st = f.stat()
        except OSError:
            continue
        if not f.is_file():
            continue
        if is_tmp:
            if now - st.st_mtime > STALE_TMP_S and _unlink(f):
                removed.append(f)
        else:
            entries.append((st.st_mtime, f.name, st.st_size, f))
    if max_bytes is None:
        return removed
    total = sum(e[2] for e in entries)
    for _, _, size, f in sorted(entries):
        if total <= max_bytes:
            break
        if _unlink(f):
            removed.append(f)
        total -= size
    return removed


def _unlink(path: Path) -> bool:
    try:
        path.unlink()
        return True
    except OSError:  # gone already, or not ours to remove
        return False


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


def xla_has_legacy_cpu_emitters(jaxlib_version: str | None = None) -> bool:
    """Whether jaxlib's XLA (the installed one, or `jaxlib_version`) still has its legacy
    LLVM IR emitters, which `FAST_XLA_CPU_FLAGS` selects: jaxlib < 0.11. jaxlib 0.11's XLA
    dropped the flag and aborts the process on it ("Unknown flag in XLA_FLAGS"), so it is
    only set where it exists. Reads the package metadata: imports no JAX."""
    if jaxlib_version is None:
        try:
            jaxlib_version = importlib.metadata.version("jaxlib")
        except importlib.metadata.PackageNotFoundError:
            return False
    numbers = [int(p) for p in re.findall(r"\d+", jaxlib_version)[:2]]
    return len(numbers) == 2 and tuple(numbers) < (0, 11)


# XLA's CPU compiler through its legacy LLVM IR emitters instead of its newer fusion
# emitters (default (ours), where jaxlib has them: `xla_has_legacy_cpu_emitters`): the
# same fused HLO, emitted by the older code path, compiles faster and runs as fast or
# faster. Measured on 2 cores, 6 Dec 2026 (jaxlib 0.10.2): the README's main job
# (`jaxloco sweep leggrope_slope`) 29.3 -> 26.6 s with an empty compilation cache and
# 8.7 -> 8.0 s warm, the same table to 3e-14; `qp.solve_batch` on 5,760 contact QPs
# 8-12 % more QPs/s (float64 and float32); compiling an MJX forward-mode rollout 13 %
# faster, TITAN's gait module 27 % (tests/conftest.py). A CPU flag: other backends ignore
# it. With jaxlib 0.11 (Python >= 3.12) none is set.
FAST_XLA_CPU_FLAGS = ("--xla_cpu_use_fusion_emitters=false",) if xla_has_legacy_cpu_emitters() else ()


def with_xla_flags(current: str, flags: tuple[str, ...]) -> str:
    """`current` (an XLA_FLAGS value) with each of `flags` appended unless it names that flag already."""
    named = {f.split("=", 1)[0] for f in current.split()}
    return " ".join([current.strip(), *(f for f in flags if f.split("=", 1)[0] not in named)]).strip()


def configure(
    *, x64: bool = True, cache_dir: str | Path | None | bool = True, cpu_devices: int | None = None,
    xla_cpu_flags: tuple[str, ...] = FAST_XLA_CPU_FLAGS,
) -> RuntimeSettings:
    """Set float64 on/off, the persistent compilation cache, the number of host CPU
    devices and XLA's CPU compiler flags.

    cache_dir: True -> `default_cache_dir()`; False/None -> leave the cache off;
    a path -> use it. Compiled programs of any compile time are cached, and the oldest
    entries are removed (`prune_cache`) until the directory is within `cache_max_bytes()`.
    (JAX's own bound, `jax_compilation_cache_max_size`, is not used: it fails on every
    write into a cache that was filled without it, as every existing one was.)
    cpu_devices: how many JAX CPU devices to expose (default: `$JAXLOCO_CPU_DEVICES` or
    the number of cores), so that a batch sharded over them runs on every core. It only
    takes effect before JAX's backend starts (the first computation); later it is left.
    xla_cpu_flags: added to $XLA_FLAGS (a flag already named there wins) if JAX's backend
    has not started yet (XLA reads them when it starts): default `FAST_XLA_CPU_FLAGS`;
    () keeps XLA's own defaults.
    """
    import jax

    max_bytes = cache_max_bytes()  # a bad $JAXLOCO_CACHE_MAX_MB fails before anything changes
    jax.config.update("jax_enable_x64", bool(x64))
    if xla_cpu_flags and not backend_started():
        os.environ["XLA_FLAGS"] = with_xla_flags(os.environ.get("XLA_FLAGS", ""), tuple(xla_cpu_flags))
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
        prune_cache(path, max_bytes, suffix=JAX_CACHE_SUFFIX)
    return RuntimeSettings(x64=bool(x64), cache_dir=path)


def backend_started() -> bool:
    """Whether JAX's backend has started (its first computation ran). Asked through the
    public config: once the backend runs, `jax_num_cpu_devices` cannot change."""
    import jax

    current = jax.config.jax_num_cpu_devices
    try:
        jax.config.update("jax_num_cpu_devices", current + 2)
    except RuntimeError:
        return True
    jax.config.update("jax_num_cpu_devices", current)
    return False


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
