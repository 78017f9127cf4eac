"""Traced programs kept on disk, so that a simulation's first call in a new process skips
JAX's tracing and lowering.

JAX's persistent compilation cache (`runtime.configure`) skips XLA's compile, but not
the tracing and lowering that produce its key: for an MJX rollout (controller, terrain,
`mjx.step`, records, metrics) that is 6-9 s of Python on every new process, most of a
cached first call. Here the lowered program is kept as a serialized `jax.export.Exported`
beside the compilation cache (`<cache dir>-programs/`), keyed by what it was traced
from; a later process deserializes it (milliseconds) and runs it through `jax.jit`,
whose compile the persistent cache then serves. The program is the same StableHLO, so
its results are the same as the traced one's, bit for bit.

The key (`program_key`) is a SHA-256 of:
  * the scenario by value (`cloudpickle`: its model, arrays and settings, and the code
    of the closures it holds), together with the source of the `jaxloco` modules it can
    run (functions defined at module level are pickled by reference, so their code comes
    in through the source): every module outside `jaxloco/robots/<robot>/`, and the
    packages of the robots the pickle names (`source_digest`). No robot package imports
    another (`tests/test_code_structure.py`), so an edit to one robot's code leaves the
    other robots' programs cached; a pickle that names a module importing robot code
    from outside the robots (`ROBOT_IMPORTERS`: the render package, the registry) counts
    every robot;
  * the input leaves' shapes, dtypes, shardings and tree structure, the extra settings
    of the caller (block size), the platform, every JAX flag (`jax.config.values`:
    float64, matmul precision, PRNG, ...), and the versions of Python, jax, jaxlib,
    mujoco, mujoco-mjx and the other packages in `VERSIONED`.
A scenario that references code outside `jaxloco`, the standard library and the
versioned packages above (a user's own controller in a script, say) gets no key and is
traced every time: an edit there would not change the key. Pickling or exporting
failures (an effect such as a host callback) also fall back to tracing.

The files are pickles (the program and its output tree): like JAX's compilation cache,
the directory must be writable by no one you would not let run code as you. Like that
cache, it is kept below `runtime.cache_max_bytes()` (`$JAXLOCO_CACHE_MAX_MB`): after each
write the least recently used programs go first (`runtime.prune_cache`; a load touches
its file).

On while the persistent compilation cache is on (`jax_compilation_cache_dir`), in
`<that dir>-programs`; `$JAXLOCO_PROGRAM_CACHE` names another directory, or with 0 turns
it off. Used by the MJX backend (`jaxloco.sim.mjx.run`: the whole rollout) and the native
one (`jaxloco.sim.native`: the initial states, the controller's init, the per-period
tick and the metrics), and by the tune runner (`jaxloco.tune.runner.jitted_value_and_grad`:
an objective's loss and gradient, the loss closure keyed by value), so that an MJX
objective's differentiated rollout is not traced again either, and by the sweeps
(`jaxloco.sweep.chunks.jitted_batch`: a JAX analysis' batch function, keyed by value,
which holds the analysis' code and the sweep's fixed values).
"""

from __future__ import annotations

import functools
import hashlib
import importlib.metadata
import io
import os
import pickle
import sys
import types
from pathlib import Path
from typing import Any, Callable

import jax

from jaxloco import runtime

ENV_SWITCH = runtime.ENV_PROGRAM_CACHE
# packages whose code a keyed scenario may reference by name (besides jaxloco, whose
# source is hashed, and the standard library): their versions are in the key
VERSIONED = ("jax", "jaxlib", "mujoco", "mujoco-mjx", "numpy", "ml_dtypes", "optax", "chex", "opt_einsum", "scipy",
             "cloudpickle")
TRUSTED_ROOTS = frozenset({"jaxloco"} | {name.split("-", 1)[0] for name in VERSIONED})


def cache_dir() -> Path | None:
    """Where traced programs are kept now, or None (off): `runtime.program_cache_dir` of
    JAX's compilation cache directory."""
    return runtime.program_cache_dir(jax.config.jax_compilation_cache_dir)


# modules outside jaxloco/robots that import robot code: a pickle naming one counts every robot
ROBOT_IMPORTERS = (b"jaxloco.render", b"jaxloco.registry")


@functools.cache
def robot_packages(root: Path) -> tuple[str, ...]:
    """The robot packages under `root`/robots (directories with an __init__.py), sorted."""
    return tuple(sorted(d.name for d in (root / "robots").iterdir() if (d / "__init__.py").is_file()))


def robots_named(blob: bytes, robots: tuple[str, ...]) -> frozenset[str]:
    """The robots whose package `blob` (a pickle) names, or all of them when it names a
    module in `ROBOT_IMPORTERS`."""
    if any(name in blob for name in ROBOT_IMPORTERS):
        return frozenset(robots)
    return frozenset(r for r in robots if f"jaxloco.robots.{r}".encode() in blob)


@functools.cache
def source_digest(root: Path, robots: frozenset[str]) -> str:
    """SHA-256 over the path and bytes of every .py file of the package at `root` except
    those of the robot packages (`root`/robots/<robot>/) not in `robots`."""
    skip = {root / "robots" / r for r in robot_packages(root)} - {root / "robots" / r for r in robots}
    h = hashlib.sha256()
    for f in sorted(root.rglob("*.py")):
        if any(d in f.parents for d in skip):
            continue
        h.update(str(f.relative_to(root)).encode())
        h.update(f.read_bytes())
    return h.hexdigest()


_ROOT = Path(__file__).resolve().parents[1]


@functools.cache
def _versions() -> str:
    found = []
    for name in VERSIONED:
        try:
            found.append(f"{name}={importlib.metadata.version(name)}")
        except importlib.metadata.PackageNotFoundError:
            found.append(f"{name}=-")
    return f"python={sys.version_info[:3]};" + ";".join(found)


class _UntrustedCode(Exception):
    """The scenario references code whose edits the key would not see."""


def _trusted(module: str | None) -> bool:
    root = (module or "").split(".", 1)[0]
    return root in TRUSTED_ROOTS or root in sys.stdlib_module_names or root == "builtins"


def _scenario_bytes(scenario: Any) -> bytes:
    """The scenario pickled by value (cloudpickle); raises `_UntrustedCode` when a function
    or class it references comes from outside `TRUSTED_ROOTS` and the standard library."""
    import cloudpickle

    class Pickler(cloudpickle.Pickler):
        def reducer_override(self, obj):
            if isinstance(obj, (types.FunctionType, type)) and not _trusted(getattr(obj, "__module__", None)):
                raise _UntrustedCode(f"{getattr(obj, '__module__', None)}.{getattr(obj, '__qualname__', obj)}")
            return super().reducer_override(obj)

    buf = io.BytesIO()
    Pickler(buf, protocol=pickle.HIGHEST_PROTOCOL).dump(scenario)
    return buf.getvalue()


def program_key(scenario: Any, args: tuple, extra: str = "") -> str | None:
    """The key of the program traced from `scenario` for the inputs `args` (their
    leaves' shapes, dtypes and shardings, and their tree structure) and the caller's
    `extra` settings, or None when the cache is off or the scenario cannot be keyed
    safely."""
    if cache_dir() is None:
        return None
    leaves, tree = jax.tree_util.tree_flatten(args)
    try:
        blob = _scenario_bytes(scenario)
    except Exception:  # untrusted code, or something cloudpickle cannot pickle
        return None
    h = hashlib.sha256()
    flags = repr(sorted((k, repr(v)) for k, v in jax.config.values.items()))  # x64, matmul precision, PRNG, ...
    source = source_digest(_ROOT, robots_named(blob, robot_packages(_ROOT)))
    for part in (blob, source.encode(), _versions().encode(), str(tree).encode(),
                 jax.default_backend().encode(), extra.encode(), flags.encode()):
        h.update(hashlib.sha256(part).digest())
    for leaf in leaves:
        aval = jax.typeof(leaf)
        h.update(f"{aval.shape}{aval.dtype}{aval.weak_type}{getattr(leaf, 'sharding', None)}".encode())
    return h.hexdigest()


def _load(path: Path) -> tuple[Any, Any] | None:
    """(Exported, output tree) from `path`, or None if missing or unreadable. A loaded
    file's modification time is set to now: `runtime.prune_cache` removes the least
    recently used first."""
    from jax import export

    try:
        saved = pickle.loads(path.read_bytes())
        loaded = export.deserialize(bytearray(saved["exported"])), saved["out_tree"]
    except Exception:  # missing, truncated, or from an incompatible version: trace again
        return None
    try:
        os.utime(path)
    except OSError:  # a read-only cache still serves
        pass
    return loaded


def _save(path: Path, exported: Any, out_tree: Any) -> None:
    """Write atomically (a temporary file renamed), so a reader never sees half a file."""
    blob = pickle.dumps({"exported": exported.serialize(), "out_tree": out_tree})
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(f".{os.getpid()}{runtime.TMP_SUFFIX}")
    tmp.write_bytes(blob)
    os.replace(tmp, path)


def load_or_export(make_fn: Callable[[], Callable], key: str, args: tuple) -> Callable[..., Any]:
    """A function equal to `jax.jit(make_fn())` for inputs shaped like `args` (as keyed
    by `program_key`): the program loaded from the cache when it holds `key` (`make_fn`
    is then not called), else traced and lowered once (`jax.export`), kept there and run.
    An unexportable program (an effect such as a host callback, an unpicklable output
    tree) gives `jax.jit(make_fn())`; a cache that cannot be written only costs the next
    process a trace."""
    from jax import export

    root = cache_dir()
    path = root / f"{key}{runtime.PROGRAM_SUFFIX}" if root is not None else None
    loaded = _load(path) if path is not None else None
    leaves, tree = jax.tree_util.tree_flatten(args)
    if loaded is None:
        fn = make_fn()
        out_box = {}

        def flat(*xs):
            out_leaves, out_box["tree"] = jax.tree_util.tree_flatten(fn(*jax.tree_util.tree_unflatten(tree, xs)))
            return out_leaves

        flat.__name__ = flat.__qualname__ = getattr(fn, "__name__", "flat")  # JAX's logs and events name it so
        try:
            loaded = export.export(jax.jit(flat))(*leaves), out_box["tree"]
        except Exception:  # not exportable: trace as usual
            return jax.jit(fn)
        if path is not None:
            try:
                _save(path, *loaded)
                runtime.prune_cache(root, runtime.cache_max_bytes(), suffix=runtime.PROGRAM_SUFFIX,
                                    tmp_suffix=runtime.TMP_SUFFIX)
            except Exception:  # read-only or full disk, an output tree pickle cannot hold
                pass
    exported, out_tree = loaded
    call = jax.jit(exported.call)

    def run(*xs):
        return jax.tree_util.tree_unflatten(out_tree, call(*committed(jax.tree_util.tree_leaves(xs))))

    return run


def committed(leaves: list) -> list:
    """`leaves` with every uncommitted one (a NumPy array, a Python number, a JAX array
    not yet placed) committed to the one device the committed leaves share (JAX's
    default device when none is committed); unchanged when the committed leaves span
    several devices (a sharded batch places its inputs itself) or when any is traced
    (the program is then part of an outer one, which places its own inputs).

    Why: `jax.jit` lowers committed and uncommitted arguments to different programs, so
    one cached program called first with fresh arrays and later with outputs of another
    program (a tuning step: the gradients, then the updated values) compiled twice;
    for an MJX rollout that is 30-40 s each on 2 cores."""
    if any(isinstance(x, jax.core.Tracer) for x in leaves):
        return leaves
    devices = {d for x in leaves if isinstance(x, jax.Array) and x.committed for d in x.sharding.device_set}
    if len(devices) > 1:
        return leaves
    target = next(iter(devices)) if devices else None
    out = []
    for x in leaves:
        if not (isinstance(x, jax.Array) and x.committed):
            # device_put, not jnp.asarray: the same array type, and no one-op program
            # compiled per shape and dtype (~20 ms each in a new process)
            x = x if isinstance(x, jax.Array) else jax.device_put(x)
            x = jax.device_put(x, target if target is not None else next(iter(x.sharding.device_set)))
        out.append(x)
    return out


class CachedJit:
    """`jax.jit(make_fn())` whose programs come from the program cache: for each call
    signature (the arguments' tree, shapes, dtypes and shardings) one key, and the
    program loaded or exported once (`load_or_export`); a scenario that cannot be keyed
    gets the plain jit. Calling it reads the signature each time (fine for functions
    called a few times per run: a rollout's inits and metrics, a tuning step); a caller
    that calls it in a loop with one signature takes `resolve(*args)` once instead."""

    def __init__(self, scenario: Any, label: str, make_fn: Callable[[], Callable]):
        self._scenario, self._label, self._make_fn = scenario, label, make_fn
        self._by_signature: dict[Any, Callable] = {}
        self._plain: Callable | None = None

    def resolve(self, *args) -> Callable[..., Any]:
        """The function for arguments shaped like `args` (loaded, exported or the plain
        jit), to call with arguments of that signature."""
        leaves, tree = jax.tree_util.tree_flatten(args)
        signature = (tree, tuple((jax.typeof(x), str(getattr(x, "sharding", None))) for x in leaves))
        fn = self._by_signature.get(signature)
        if fn is None:
            key = program_key(self._scenario, args, self._label)
            if key is None:
                if self._plain is None:
                    self._plain = jax.jit(self._make_fn())
                fn = self._plain
            else:
                fn = load_or_export(self._make_fn, key, args)
            self._by_signature[signature] = fn
        return fn

    def __call__(self, *args):
        return self.resolve(*args)(*args)

    def lower(self, *args) -> Any:
        """`jax.jit(make_fn()).lower(*args)`: the program traced afresh, to inspect it."""
        return jax.jit(self._make_fn()).lower(*args)
